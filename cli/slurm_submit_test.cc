#include "cli/slurm_submit.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <memory>
#include <sstream>

#include "cli/commands.h"

namespace sandswim::cli {
namespace {

using ::testing::Contains;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::Pair;

const std::string kScripts = std::string(SANDSWIM_SOURCE_DIR) + "/deploy/slurm";

// sbatch, scripted: records the command and its environment, answers `answer`.
class FakeSbatch : public slurm::SlurmCommands {
 public:
  Result<slurm::CommandOutput> Run(const std::vector<std::string>& argv,
                                   const std::vector<std::pair<std::string, std::string>>& env) override {
    argv_ = argv;
    env_ = env;
    return answer;
  }
  slurm::CommandOutput answer{0, "4711\n", ""};
  std::vector<std::string> argv_;
  std::vector<std::pair<std::string, std::string>> env_;
};

SlurmSubmitOptions Pilot() {
  SlurmSubmitOptions o;
  o.request.nodes = 1;
  o.request.ranks_per_run = 1;
  o.request.tasks_per_node = 2;
  o.request.time = "10:00";
  o.scripts_dir = kScripts;
  o.server = "http://login1:8080";
  o.token = "s3cret";
  o.worker = "/opt/sandswim/bin/sandswim-worker";
  return o;
}

TEST(SubmitToSlurmTest, PilotGoesToSbatchWithTheDaemonInItsEnvironmentNotItsArgv) {
  FakeSbatch sbatch;
  auto done = SubmitToSlurm(sbatch, Pilot());
  ASSERT_TRUE(done.ok()) << done.status().ToString();
  EXPECT_EQ(done->job_id, 4711);
  EXPECT_EQ(sbatch.argv_.front(), "sbatch");
  EXPECT_EQ(sbatch.argv_.back(), kScripts + "/pilot.sbatch");
  EXPECT_THAT(sbatch.argv_, Contains("--signal=B:USR1@120"));
  EXPECT_THAT(sbatch.env_, Contains(Pair("SANDSWIM_SERVER", "http://login1:8080")));
  EXPECT_THAT(sbatch.env_, Contains(Pair("SANDSWIM_TOKEN", "s3cret")));
  EXPECT_THAT(sbatch.env_, Contains(Pair("SANDSWIM_RANKS", "1")));
  EXPECT_THAT(sbatch.env_, Contains(Pair("SANDSWIM_WORKER", "/opt/sandswim/bin/sandswim-worker")));
  for (const std::string& a : sbatch.argv_) EXPECT_THAT(a, Not(HasSubstr("s3cret")));
  EXPECT_THAT(done->env, Contains(Pair("SANDSWIM_TOKEN", "(set)")));
}

TEST(SubmitToSlurmTest, ArrayUsesTheArrayScript) {
  FakeSbatch sbatch;
  SlurmSubmitOptions o = Pilot();
  o.request.tasks_per_node = 0;
  o.request.array = 2;
  o.request.throttle = 1;
  ASSERT_TRUE(SubmitToSlurm(sbatch, o).ok());
  EXPECT_EQ(sbatch.argv_.back(), kScripts + "/array.sbatch");
  EXPECT_THAT(sbatch.argv_, Contains("0-1%1"));
}

TEST(SubmitToSlurmTest, SlurmsRefusalIsPassedOn) {
  FakeSbatch sbatch;
  sbatch.answer = {1, "",
                   "sbatch: error: Batch job submission failed: Requested node configuration is not available\n"};
  auto done = SubmitToSlurm(sbatch, Pilot());
  ASSERT_FALSE(done.ok());
  EXPECT_EQ(done.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_THAT(done.status().reason(), HasSubstr("Requested node configuration is not available"));
}

TEST(SubmitToSlurmTest, BadOptionsNameTheFlag) {
  FakeSbatch sbatch;
  SlurmSubmitOptions o = Pilot();
  o.request.nodes = 0;
  EXPECT_EQ(SubmitToSlurm(sbatch, o).status().field(), "--nodes");
  o = Pilot();
  o.request.script = "/nonexistent/pilot.sbatch";
  EXPECT_EQ(SubmitToSlurm(sbatch, o).status().field(), "--script");
  o = Pilot();
  o.server = "login1:8080";
  EXPECT_EQ(SubmitToSlurm(sbatch, o).status().field(), "--server");
  EXPECT_TRUE(sbatch.argv_.empty());  // nothing was submitted
}

// Through the command table: `sandswim slurm submit` prints the job id.
TEST(SlurmCommandTest, SubmitPrintsTheJobId) {
  std::ostringstream out, err;
  Environment env;
  env.out = &out;
  env.err = &err;
  env.getenv = [](const char* name) -> const char* {
    std::string n = name;
    if (n == "SANDSWIM_SLURM_SCRIPTS") return SANDSWIM_SOURCE_DIR "/deploy/slurm";
    if (n == "SANDSWIM_TOKEN") return "tok";
    return nullptr;
  };
  // The command owns (and destroys) its SlurmCommands: this one reports into `fake`.
  auto fake = std::make_shared<FakeSbatch>();
  struct Forward : slurm::SlurmCommands {
    std::shared_ptr<FakeSbatch> to;
    Result<slurm::CommandOutput> Run(const std::vector<std::string>& argv,
                                     const std::vector<std::pair<std::string, std::string>>& env) override {
      return to->Run(argv, env);
    }
  };
  env.make_slurm = [fake] {
    auto f = std::make_unique<Forward>();
    f->to = fake;
    return std::unique_ptr<slurm::SlurmCommands>(std::move(f));
  };
  const char* argv[] = {"sandswim",        "--server", "http://10.0.0.1:8080", "slurm", "submit", "--nodes", "2",
                        "--ranks-per-run", "4",        "--tasks-per-node",     "8",     "--time", "1:00:00"};
  int code = RunCli(static_cast<int>(std::size(argv)), argv, env);
  ASSERT_EQ(code, kExitOk) << err.str();
  EXPECT_EQ(out.str(), "4711\n");
  EXPECT_THAT(fake->argv_, Contains("--ntasks-per-node"));
  EXPECT_THAT(fake->env_, Contains(Pair("SANDSWIM_SERVER", "http://10.0.0.1:8080")));
  EXPECT_THAT(fake->env_, Contains(Pair("SANDSWIM_TOKEN", "tok")));
  EXPECT_THAT(fake->env_, Contains(Pair("SANDSWIM_RANKS", "4")));

  std::ostringstream out2, err2;
  env.out = &out2;
  env.err = &err2;
  const char* bad[] = {"sandswim", "slurm", "submit", "--time", "soon"};
  EXPECT_EQ(RunCli(static_cast<int>(std::size(bad)), bad, env), kExitUsage);
  EXPECT_THAT(err2.str(), HasSubstr("--time"));
}

}  // namespace
}  // namespace sandswim::cli
