#include "cli/analyze.h"

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli/commands.h"

namespace sandswim::cli {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const std::string kRun = std::string(SANDSWIM_SOURCE_DIR) + "/tests/fixtures/runs/vibration-3s";

struct Cli {
  std::ostringstream out, err;
  int Run(std::vector<const char*> args) {
    Environment env;
    env.out = &out;
    env.err = &err;
    env.getenv = [](const char*) -> const char* { return nullptr; };
    args.insert(args.begin(), "sandswim");
    return RunCli(static_cast<int>(args.size()), args.data(), env);
  }
};

class AnalyzeTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    dir_ = fs::temp_directory_path() / ("sandswim-analyze-" + std::to_string(rd()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name, std::ios::binary) << text;
    return (dir_ / name).string();
  }
  fs::path dir_;
};

// A run directory of the service: the deck and the log beside the dump are read, and say so.
TEST_F(AnalyzeTest, RunDirectoryGivesItsInputsAndAConclusiveRate) {
  auto a = AnalyzeDumpFile(kRun + "/so.dump", {});
  ASSERT_TRUE(a.ok()) << a.status().ToString();
  EXPECT_EQ(a->inputs.f, 3.0);
  EXPECT_EQ(a->f_from, "deck " + kRun + "/drive.in");
  EXPECT_EQ(a->surface_from, "log " + kRun + "/log.liggghts");
  EXPECT_EQ(a->floor_from, "deck " + kRun + "/drive.in");
  EXPECT_TRUE(a->result.conclusive);
  EXPECT_THAT(RenderDumpAnalysis(*a), HasSubstr("U_z:      " + DescribeUz(a->result)));
  // Options override what the files say: a frequency, no clearance.
  AnalyzeOptions o;
  o.f = 0;
  o.rule.clearance_m = 0;
  auto b = AnalyzeDumpFile(kRun + "/so.dump", o);
  ASSERT_TRUE(b.ok());
  EXPECT_EQ(b->f_from, "--f");
  EXPECT_EQ(b->result.block_kind, "block");
  EXPECT_EQ(b->result.window_end, "run_end");
}

// A dump of many particles with no deck: the SO is the largest particle (or the one named by --id),
// the frequency must be given, and boundaries not known are said to be unchecked.
TEST_F(AnalyzeTest, AnyDumpCustomWithTheSoAmongOtherParticles) {
  std::string text;
  for (int k = 0; k <= 1500; ++k) {
    const double t = k * 1e-3, z = 0.02 * t + 0.003 * std::sin(2 * 3.14159265358979 * 6 * t);
    text += "ITEM: TIMESTEP\n" + std::to_string(k * 100) + "\nITEM: NUMBER OF ATOMS\n2\n" +
            "ITEM: BOX BOUNDS pp pp ff\n-1 1\n-1 1\n-1 1\nITEM: ATOMS id type x y z radius\n" + "7 1 0.1 0.1 " +
            std::to_string(-0.3 + t) + " 0.01\n" + "9 2 0 0 " + std::to_string(z) + " 0.06\n";
  }
  const std::string dump = Write("all.dump", text);
  Cli no_f;
  EXPECT_EQ(no_f.Run({"analyze", dump.c_str()}), 2);
  EXPECT_THAT(no_f.err.str(), HasSubstr("--f"));

  Cli cli;
  ASSERT_EQ(cli.Run({"analyze", dump.c_str(), "--f", "3", "--json"}), 0) << cli.err.str();
  nlohmann::json j = nlohmann::json::parse(cli.out.str());
  ASSERT_EQ(j.size(), 1u);
  EXPECT_NEAR(j[0]["result"]["uz"].get<double>(), 0.02, 1e-4);
  EXPECT_EQ(j[0]["result"]["uz_blocks"], 3);
  EXPECT_FALSE(j[0]["inputs"].contains("floor"));
  Cli text_out;
  ASSERT_EQ(text_out.Run({"analyze", dump.c_str(), "--f", "3"}), 0);
  EXPECT_THAT(text_out.out.str(), HasSubstr("floor unknown: not checked (--floor Z)"));
  // --id 7 follows the small grain, which moves at 1 m/s.
  Cli grain;
  ASSERT_EQ(grain.Run({"analyze", dump.c_str(), "--f", "3", "--id", "7", "--json"}), 0);
  EXPECT_NEAR(nlohmann::json::parse(grain.out.str())[0]["result"]["uz"].get<double>(), 1.0, 1e-6);
}

// Dumps it cannot read get a clear error naming the file; the others are still analysed (exit 1).
TEST_F(AnalyzeTest, UnreadableDumpsAreNamedAndTheRestAnalysed) {
  const std::string garbage = Write("garbage.dump", "this is not a dump\n");
  const std::string two = Write("two.dump",
                                "ITEM: TIMESTEP\n0\nITEM: NUMBER OF ATOMS\n2\nITEM: BOX BOUNDS pp pp ff\n-1 1\n-1 1\n"
                                "-1 1\nITEM: ATOMS id x y z\n1 0 0 0\n2 0 0 1\n");
  const std::string missing = (dir_ / "nope.dump").string();
  const std::string good = kRun + "/so.dump";
  Cli cli;
  EXPECT_EQ(cli.Run({"analyze", missing.c_str(), garbage.c_str(), two.c_str(), good.c_str(), "--f", "3"}), 1);
  EXPECT_THAT(cli.err.str(), HasSubstr("cannot read " + missing));
  EXPECT_THAT(cli.err.str(), HasSubstr(garbage + ": "));
  EXPECT_THAT(cli.err.str(), HasSubstr("no radius or diameter column"));
  EXPECT_THAT(cli.out.str(), HasSubstr(good));
  Cli bad;
  EXPECT_EQ(bad.Run({"analyze", good.c_str(), "--min-periods", "0"}), 2);
}

// Numbers that would silently mean something else are usage errors naming the option: nan or inf
// (no "default" from a NaN), an atom id < 1, a frequency whose period is shorter than a sample, a
// deck that states no frequency.
TEST_F(AnalyzeTest, OptionsThatCannotBeRightAreRefused) {
  const std::string good = kRun + "/so.dump";
  for (const char* opt : {"--f", "--dt", "--floor", "--surface"}) {
    for (const char* v : {"nan", "inf", "-inf"}) {
      Cli cli;
      EXPECT_EQ(cli.Run({"analyze", good.c_str(), opt, v}), 2) << opt << " " << v;
      EXPECT_THAT(cli.err.str(), HasSubstr(opt)) << opt << " " << v;
      EXPECT_TRUE(cli.out.str().empty());
    }
  }
  Cli id;
  EXPECT_EQ(id.Run({"analyze", good.c_str(), "--id", "-3"}), 2);
  EXPECT_THAT(id.err.str(), HasSubstr("--id"));
  Cli huge;
  EXPECT_EQ(huge.Run({"analyze", good.c_str(), "--f", "1e300"}), 2);
  EXPECT_THAT(huge.err.str(), HasSubstr("shorter than the dump's sample interval"));
  const std::string deck = Write("no-f.in", "timestep 1e-5\n");
  Cli no_f;
  EXPECT_EQ(no_f.Run({"analyze", good.c_str(), "--deck", deck.c_str()}), 2);
  EXPECT_THAT(no_f.err.str(), HasSubstr("variable f equal"));
}

}  // namespace
}  // namespace sandswim::cli
