#include "core/token.h"

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

std::string TempFile(const std::string& text) {
  std::string path = (std::filesystem::temp_directory_path() / "sandswim-token-test").string();
  std::ofstream(path) << text;
  return path;
}

TEST(TokenTest, FileWinsOverTheEnvironmentAndIsTrimmed) {
  setenv("SANDSWIM_TOKEN", "from-env", 1);
  auto t = LoadToken(TempFile("  s3cret\n"));
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(*t, "s3cret");
  EXPECT_EQ(*LoadToken(""), "from-env");
  unsetenv("SANDSWIM_TOKEN");
  EXPECT_EQ(*LoadToken(""), "");
}

TEST(TokenTest, UnreadableOrEmptyFileIsAnError) {
  EXPECT_EQ(LoadToken("/nonexistent/token").status().field(), "--token-file");
  EXPECT_EQ(LoadToken(TempFile(" \n")).status().field(), "--token-file");
}

}  // namespace
}  // namespace sandswim
