#include "platform/token.h"

#include <stdlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

// A token file in a directory of this test's own (ctest -j runs tests as parallel processes).
class TokenTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (std::filesystem::temp_directory_path() / "sandswim-token-XXXXXX").string();
    ASSERT_NE(mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string TokenFile(const std::string& text) {
    std::string path = (dir_ / "token").string();
    std::ofstream(path) << text;
    return path;
  }
  std::filesystem::path dir_;
};

const char* EnvWithToken(const char* name) {
  return std::strcmp(name, "SANDSWIM_TOKEN") == 0 ? " from-env\n" : nullptr;
}
const char* EmptyEnv(const char*) { return nullptr; }

TEST_F(TokenTest, FileWinsOverTheEnvironmentAndIsTrimmed) {
  auto t = LoadToken(TokenFile("  s3cret\n"), EnvWithToken);
  ASSERT_TRUE(t.ok());
  EXPECT_EQ(*t, "s3cret");
  EXPECT_EQ(*LoadToken("", EnvWithToken), "from-env");
  EXPECT_EQ(*LoadToken("", EmptyEnv), "");
}

TEST_F(TokenTest, UnreadableOrEmptyFileIsAnError) {
  EXPECT_EQ(LoadToken((dir_ / "missing").string(), EmptyEnv).status().field(), "--token-file");
  EXPECT_EQ(LoadToken(TokenFile(" \n"), EmptyEnv).status().field(), "--token-file");
}

}  // namespace
}  // namespace sandswim
