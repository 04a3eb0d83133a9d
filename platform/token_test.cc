#include "platform/token.h"

#include <stdlib.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <vector>

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

TEST(TokenStrengthTest, AtLeast128Bits) {
  EXPECT_TRUE(CheckTokenStrength(std::string(32, 'a'), "--token-file").ok());  // 32 hex digits
  EXPECT_TRUE(CheckTokenStrength("0123456789ABCDEFabcdef0123456789", "x").ok());
  EXPECT_TRUE(CheckTokenStrength("q3V1p9Zx_kT7-mN2bW4yRa", "x").ok());  // 22 base64url characters
  for (const std::string& weak :
       std::vector<std::string>{"x", "s3cret", std::string(31, 'f'), "q3V1p9Zx_kT7-mN2bW4yR"}) {
    Status s = CheckTokenStrength(weak, "--token-file");
    EXPECT_FALSE(s.ok()) << weak;
    EXPECT_EQ(s.field(), "--token-file");
    EXPECT_NE(s.reason().find("openssl rand -hex 32"), std::string::npos) << s.reason();
  }
  // 31 hex digits are refused even though 22 other characters would do: they hold 124 bits.
  EXPECT_NE(CheckTokenStrength(std::string(31, 'f'), "x").reason().find("32 or more hexadecimal"), std::string::npos);
}

TEST(GenerateTokenTest, SixtyFourHexDigitsNeverTheSame) {
  auto a = GenerateToken(), b = GenerateToken();
  ASSERT_TRUE(a.ok() && b.ok());
  EXPECT_EQ(a->size(), 64u);
  EXPECT_EQ(a->find_first_not_of("0123456789abcdef"), std::string::npos);
  EXPECT_NE(*a, *b);
  EXPECT_TRUE(CheckTokenStrength(*a, "x").ok());
}

TEST_F(TokenTest, TheDaemonsFileIsMadeOwnerOnlyAndReused) {
  const std::string path = (dir_ / "data" / "token").string();
  auto made = LoadOrCreateTokenFile(path);
  ASSERT_TRUE(made.ok()) << made.status().ToString();
  EXPECT_TRUE(made->created);
  EXPECT_EQ(made->token.size(), 64u);
  EXPECT_EQ(std::filesystem::status(path).permissions() & std::filesystem::perms::all,
            std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  auto again = LoadOrCreateTokenFile(path);
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(again->created);
  EXPECT_EQ(again->token, made->token);
  // Readable by others: refused, saying how to fix it.
  std::filesystem::permissions(path, std::filesystem::perms::group_read, std::filesystem::perm_options::add);
  auto open = LoadOrCreateTokenFile(path);
  ASSERT_FALSE(open.ok());
  EXPECT_NE(open.status().reason().find("chmod 600"), std::string::npos) << open.status().ToString();
  // A weak token in the file: refused.
  std::filesystem::permissions(path, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write,
                               std::filesystem::perm_options::replace);
  std::ofstream(path) << "short\n";
  EXPECT_FALSE(LoadOrCreateTokenFile(path).ok());
}

// A link planted where the token file goes is not followed (to a file of another user's, or one
// the attacker can read back): refused, saying to remove it.
TEST_F(TokenTest, ALinkInPlaceOfTheTokenFileIsRefused) {
  const std::string real = (dir_ / "elsewhere").string();
  std::ofstream(real) << std::string(64, 'a') << "\n";
  std::filesystem::permissions(real, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write,
                               std::filesystem::perm_options::replace);
  const std::string path = (dir_ / "token").string();
  std::filesystem::create_symlink(real, path);
  auto linked = LoadOrCreateTokenFile(path);
  ASSERT_FALSE(linked.ok());
  EXPECT_NE(linked.status().reason().find("symbolic link"), std::string::npos) << linked.status().ToString();
}

TEST_F(TokenTest, ClientsFindTheDefaultFileOnlyForALoopbackDaemon) {
  const std::string file = TokenFile(std::string(64, 'b'));
  const std::string other = (dir_ / "other").string();
  std::ofstream(other) << std::string(64, 'c');
  // --token-file, then the environment, then the default file (loopback only).
  EXPECT_EQ(*LoadClientToken(other, "127.0.0.1", EnvWithToken, file), std::string(64, 'c'));
  EXPECT_EQ(*LoadClientToken("", "127.0.0.1", EnvWithToken, file), "from-env");
  EXPECT_EQ(*LoadClientToken("", "127.0.0.1", EmptyEnv, file), std::string(64, 'b'));
  EXPECT_EQ(*LoadClientToken("", "localhost", EmptyEnv, file), std::string(64, 'b'));
  EXPECT_EQ(*LoadClientToken("", "[::1]", EmptyEnv, file), std::string(64, 'b'));
  EXPECT_EQ(*LoadClientToken("", "login1.cluster", EmptyEnv, file), "") << "never sent to another machine";
  EXPECT_EQ(*LoadClientToken("", "127.0.0.1", EmptyEnv, (dir_ / "none").string()), "");
}

TEST(IsLoopbackHostTest, Loopback) {
  EXPECT_TRUE(IsLoopbackHost("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackHost("127.1.2.3"));
  EXPECT_TRUE(IsLoopbackHost("::1"));
  EXPECT_TRUE(IsLoopbackHost("[::1]"));
  EXPECT_TRUE(IsLoopbackHost("localhost"));
  EXPECT_FALSE(IsLoopbackHost("0.0.0.0"));
  EXPECT_FALSE(IsLoopbackHost("192.168.1.4"));
  EXPECT_FALSE(IsLoopbackHost("localhost.evil.example"));
}

}  // namespace
}  // namespace sandswim
