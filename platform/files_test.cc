#include "platform/files.h"

#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

namespace fs = std::filesystem;

mode_t ModeOf(const std::string& path) {
  struct stat st {};
  EXPECT_EQ(lstat(path.c_str(), &st), 0) << path;
  return st.st_mode & 07777;
}

// A data directory an earlier daemon left under umask 022 (0755 directories, 0644 files) is made
// private whole; a link inside is not followed out of it, and a second pass changes nothing.
TEST(RestrictToOwnerTest, TakesGroupAndOthersBitsFromADirectoryAndEverythingUnderIt) {
  char pattern[] = "/tmp/restrict-test-XXXXXX";
  ASSERT_NE(mkdtemp(pattern), nullptr);
  const std::string root = std::string(pattern) + "/data";
  const std::string outside = std::string(pattern) + "/outside";
  fs::create_directories(root + "/beds");
  std::ofstream(root + "/beds/k.restart") << "x";
  std::ofstream(root + "/token") << "t";
  std::ofstream(outside) << "o";
  chmod(root.c_str(), 0755);
  chmod((root + "/beds").c_str(), 0775);
  chmod((root + "/beds/k.restart").c_str(), 0644);
  chmod((root + "/token").c_str(), 0600);
  chmod(outside.c_str(), 0644);
  fs::create_symlink(outside, root + "/link");

  auto changed = RestrictToOwner(root);
  ASSERT_TRUE(changed.ok()) << changed.status().ToString();
  EXPECT_EQ(*changed, 3);
  EXPECT_EQ(ModeOf(root), 0700u);
  EXPECT_EQ(ModeOf(root + "/beds"), 0700u);
  EXPECT_EQ(ModeOf(root + "/beds/k.restart"), 0600u);
  EXPECT_EQ(ModeOf(root + "/token"), 0600u);
  EXPECT_EQ(ModeOf(outside), 0644u) << "a link was followed out of the directory";
  EXPECT_EQ(*RestrictToOwner(root), 0);
  EXPECT_EQ(*RestrictToOwner(root + "/absent"), 0);
  fs::remove_all(pattern);
}

}  // namespace
}  // namespace sandswim
