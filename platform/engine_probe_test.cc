#include "platform/engine_probe.h"

#include <stdlib.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <fstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;

TEST(EngineProbeTest, BannerIsTheFirstLiggghtsLine) {
  EXPECT_EQ(EngineVersionFromBanner("LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by "
                                    "buildd, git commit unknown)\nTotal wall time: 0:00:00\n"),
            "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)");
  EXPECT_EQ(EngineVersionFromBanner("warning: something\r\nLIGGGHTS (Version X)\r\n"), "LIGGGHTS (Version X)");
  EXPECT_FALSE(EngineVersionFromBanner("").has_value());
  EXPECT_FALSE(EngineVersionFromBanner("LAMMPS (3 Mar 2020)\n").has_value());
}

class EngineProbeProcessTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/sandswim-probe-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string Script(const std::string& body) {
    std::string path = dir_ + "/engine";
    std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
    chmod(path.c_str(), 0755);
    return path;
  }
  std::string dir_;
};

TEST_F(EngineProbeProcessTest, ReadsTheBannerOfAFakeEngineAndPassesNoLog) {
  std::string engine = Script(R"sh(echo "LIGGGHTS (Version fake $1 $2)"; cat >/dev/null)sh");
  auto version = ProbeEngineVersion(engine, 5);
  ASSERT_TRUE(version.ok()) << version.status().ToString();
  EXPECT_EQ(*version, "LIGGGHTS (Version fake -log none)");
}

TEST_F(EngineProbeProcessTest, NoBannerOrNoEngineIsUnavailable) {
  auto silent = ProbeEngineVersion(Script("exit 0"), 5);
  EXPECT_EQ(silent.status().code(), StatusCode::kUnavailable);
  auto missing = ProbeEngineVersion(dir_ + "/no-such-engine", 5);
  EXPECT_EQ(missing.status().code(), StatusCode::kUnavailable);
  EXPECT_THAT(missing.status().reason(), HasSubstr("cannot start"));
}

TEST_F(EngineProbeProcessTest, AHangingEngineTimesOut) {
  // The engine sleeps 30 s: a probe that waited for it to exit would take that long, and say
  // nothing of a deadline.
  auto start = std::chrono::steady_clock::now();
  auto hung = ProbeEngineVersion(Script("exec sleep 30"), 0.2);
  double waited = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_EQ(hung.status().code(), StatusCode::kUnavailable);
  EXPECT_THAT(hung.status().reason(), HasSubstr("printed no banner within"));
  EXPECT_LT(waited, 15);
}

TEST_F(EngineProbeProcessTest, ABannerBeforeAHangStillCounts) {
  auto version = ProbeEngineVersion(Script(R"sh(echo "LIGGGHTS (Version hangs)"; exec sleep 30)sh"), 0.5);
  ASSERT_TRUE(version.ok()) << version.status().ToString();
  EXPECT_EQ(*version, "LIGGGHTS (Version hangs)");
}

}  // namespace
}  // namespace sandswim
