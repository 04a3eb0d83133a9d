#include "platform/slurm.h"

#include <chrono>
#include <deque>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim::slurm {
namespace {

using ::testing::ElementsAre;
using ::testing::HasSubstr;

// Answers queued outputs in order and records every command.
class FakeSlurm : public SlurmCommands {
 public:
  Result<CommandOutput> Run(const std::vector<std::string>& argv,
                            const std::vector<std::pair<std::string, std::string>>& env) override {
    calls.push_back(argv);
    envs.push_back(env);
    if (answers.empty()) return Status::Unavailable("no slurm here");
    Result<CommandOutput> a = answers.front();
    answers.pop_front();
    return a;
  }
  std::deque<Result<CommandOutput>> answers;
  std::vector<std::vector<std::string>> calls;
  std::vector<std::vector<std::pair<std::string, std::string>>> envs;
};

double Seconds(const std::string& text) { return ParseSlurmDuration(text).value().value(); }

TEST(ParseSlurmDurationTest, ReadsEverySyntaxSlurmPrintsAndTakes) {
  EXPECT_EQ(Seconds("30"), 30 * 60);       // bare minutes
  EXPECT_EQ(Seconds("5:07"), 5 * 60 + 7);  // M:S, how squeue %L prints under an hour
  EXPECT_EQ(Seconds("1:58:03"), 3600 + 58 * 60 + 3);
  EXPECT_EQ(Seconds("2-03"), 2 * 86400 + 3 * 3600);
  EXPECT_EQ(Seconds("2-03:04"), 2 * 86400 + 3 * 3600 + 4 * 60);
  EXPECT_EQ(Seconds("1-00:00:09\n"), 86400 + 9);
  EXPECT_FALSE(ParseSlurmDuration("UNLIMITED").value().has_value());
  EXPECT_FALSE(ParseSlurmDuration("NOT_SET").value().has_value());
}

TEST(ParseSlurmDurationTest, RefusesWhatIsNotATimeNamingTheField) {
  for (const char* bad : {"", "abc", "1:2:3:4", "-5", "1-", "1.5", "1:-2", "1-2-3"}) {
    auto r = ParseSlurmDuration(bad, "time");
    ASSERT_FALSE(r.ok()) << bad;
    EXPECT_EQ(r.status().field(), "time") << bad;
  }
}

TEST(ShouldLeaseTest, OutsideAnAllocationAlwaysLeases) {
  EXPECT_TRUE(ShouldLease(std::nullopt, std::nullopt, 300));
  EXPECT_TRUE(ShouldLease(std::nullopt, 1e9, 300));
}

TEST(ShouldLeaseTest, UsesTheKnownRunTimeElseTheMargin) {
  // No run done yet: the margin decides.
  EXPECT_TRUE(ShouldLease(301, std::nullopt, 300));
  EXPECT_FALSE(ShouldLease(299, std::nullopt, 300));
  // Runs take 40 s here: 100 s left is enough even though it is under the margin ...
  EXPECT_TRUE(ShouldLease(100, 40, 300));
  // ... and 30 s is not.
  EXPECT_FALSE(ShouldLease(30, 40, 300));
  EXPECT_FALSE(ShouldLease(0, 0.5, 300));
}

TEST(PilotSbatchArgsTest, PilotAsksForNodesTasksAndTheWarningSignal) {
  PilotRequest r;
  r.nodes = 2;
  r.ranks_per_run = 4;
  r.tasks_per_node = 16;
  r.time = "2:00:00";
  r.partition = "compute";
  r.script = "/opt/sandswim/pilot.sbatch";
  auto argv = PilotSbatchArgs(r);
  ASSERT_TRUE(argv.ok()) << argv.status().ToString();
  EXPECT_THAT(*argv, ElementsAre("sbatch", "--parsable", "--job-name", "sandswim", "--time", "2:00:00", "--nodes", "2",
                                 "--ntasks-per-node", "16", "--signal=B:USR1@120", "--partition", "compute",
                                 "--export=ALL", "/opt/sandswim/pilot.sbatch"));
}

TEST(PilotSbatchArgsTest, ArrayHasOneRunPerElementAndAThrottle) {
  PilotRequest r;
  r.ranks_per_run = 2;
  r.time = "30";
  r.array = 10;
  r.throttle = 3;
  r.script = "array.sbatch";
  auto argv = PilotSbatchArgs(r);
  ASSERT_TRUE(argv.ok()) << argv.status().ToString();
  EXPECT_THAT(*argv, ElementsAre("sbatch", "--parsable", "--job-name", "sandswim", "--time", "30", "--nodes", "1",
                                 "--ntasks", "2", "--array", "0-9%3", "--export=ALL", "array.sbatch"));
}

TEST(PilotSbatchArgsTest, TasksPerNodeDefaultsToOneRun) {
  PilotRequest r;
  r.ranks_per_run = 3;
  r.time = "10:00";
  r.script = "p";
  auto argv = PilotSbatchArgs(r);
  ASSERT_TRUE(argv.ok());
  EXPECT_THAT(*argv, ::testing::Contains("--ntasks-per-node"));
  auto it = std::find(argv->begin(), argv->end(), "--ntasks-per-node");
  EXPECT_EQ(*(it + 1), "3");
}

TEST(PilotSbatchArgsTest, RefusesBadValuesNamingTheField) {
  auto field_of = [](PilotRequest r) {
    if (r.script.empty()) r.script = "p";
    auto a = PilotSbatchArgs(r);
    return a.ok() ? std::string("(ok)") : a.status().field();
  };
  PilotRequest base;
  base.time = "1:00:00";
  EXPECT_EQ(field_of(base), "(ok)");
  PilotRequest r = base;
  r.nodes = 0;
  EXPECT_EQ(field_of(r), "nodes");
  r = base;
  r.ranks_per_run = 0;
  EXPECT_EQ(field_of(r), "ranks-per-run");
  r = base;
  r.time = "soon";
  EXPECT_EQ(field_of(r), "time");
  r = base;
  r.time = "";
  EXPECT_EQ(field_of(r), "time");
  r = base;
  r.time = "2";  // 120 s: no room for the 120 s warning
  EXPECT_EQ(field_of(r), "time");
  r = base;
  r.array = 2;
  r.time = "5";  // 300 s: no longer than the 300 s a first run is expected to take
  EXPECT_EQ(field_of(r), "time");
  r.end_margin_s = 60;
  EXPECT_EQ(field_of(r), "(ok)");
  r = base;
  r.throttle = 2;  // without an array
  EXPECT_EQ(field_of(r), "throttle");
  r = base;
  r.array = 2;
  r.throttle = 3;
  EXPECT_EQ(field_of(r), "throttle");
  r = base;
  r.ranks_per_run = 8;
  r.tasks_per_node = 4;  // one node of 4 cannot hold 8 ranks
  EXPECT_EQ(field_of(r), "tasks-per-node");
}

TEST(ParseSbatchJobIdTest, ReadsParsableOutput) {
  EXPECT_EQ(ParseSbatchJobId("1234\n").value(), 1234);
  EXPECT_EQ(ParseSbatchJobId("77;cluster-a\n").value(), 77);
  EXPECT_EQ(ParseSbatchJobId("sbatch: warning: something\n88\n").value(), 88);
  EXPECT_FALSE(ParseSbatchJobId("sbatch: error: Batch job submission failed").ok());
  EXPECT_FALSE(ParseSbatchJobId("").ok());
}

TEST(AllocationDeadlineTest, AsksSqueueOnceThenCountsDownUntilRefresh) {
  FakeSlurm slurm;
  slurm.answers.push_back(CommandOutput{0, "10:00\n", ""});
  slurm.answers.push_back(CommandOutput{0, "1:00:00\n", ""});  // the limit was extended
  double now = 1000;
  AllocationDeadline deadline(
      slurm, "42", [&] { return now; }, /*refresh_s=*/60);
  EXPECT_EQ(deadline.SecondsLeft().value().value(), 600);
  ASSERT_EQ(slurm.calls.size(), 1u);
  EXPECT_THAT(slurm.calls[0], ElementsAre("squeue", "-h", "-j", "42", "-o", "%L"));
  now += 30;
  EXPECT_EQ(deadline.SecondsLeft().value().value(), 570);
  EXPECT_EQ(slurm.calls.size(), 1u);
  now += 31;
  EXPECT_EQ(deadline.SecondsLeft().value().value(), 3600);
  EXPECT_EQ(slurm.calls.size(), 2u);
}

TEST(AllocationDeadlineTest, KeepsCountingDownWhenSlurmStopsAnswering) {
  FakeSlurm slurm;
  slurm.answers.push_back(CommandOutput{0, "5:00", ""});
  slurm.answers.push_back(CommandOutput{1, "", "slurm_load_jobs error: Socket timed out"});
  double now = 0;
  AllocationDeadline deadline(
      slurm, "7", [&] { return now; }, 10);
  EXPECT_EQ(deadline.SecondsLeft().value().value(), 300);
  now = 100;
  EXPECT_EQ(deadline.SecondsLeft().value().value(), 200);
  now = 400;
  EXPECT_EQ(deadline.SecondsLeft().value().value(), 0);
}

TEST(AllocationDeadlineTest, NoAnswerAtAllIsAnError) {
  FakeSlurm slurm;
  slurm.answers.push_back(CommandOutput{1, "", "Invalid job id specified"});
  AllocationDeadline deadline(slurm, "9", [] { return 0.0; });
  auto left = deadline.SecondsLeft();
  ASSERT_FALSE(left.ok());
  EXPECT_THAT(left.status().ToString(), HasSubstr("Invalid job id"));
}

TEST(AllocationDeadlineTest, UnlimitedHasNoEnd) {
  FakeSlurm slurm;
  slurm.answers.push_back(CommandOutput{0, "UNLIMITED\n", ""});
  AllocationDeadline deadline(slurm, "9", [] { return 0.0; });
  EXPECT_FALSE(deadline.SecondsLeft().value().has_value());
}

TEST(ProcessSlurmCommandsTest, CapturesOutputAndExitCode) {
  ProcessSlurmCommands real;
  auto r = real.Run({"sh", "-c", "echo out; echo err >&2; echo $SANDSWIM_X; exit 3"}, {{"SANDSWIM_X", "y"}});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->out, "out\ny\n");
  EXPECT_EQ(r->err, "err\n");
  EXPECT_EQ(r->exit_code, 3);
  auto missing = real.Run({"sandswim-no-such-command"});
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.status().code(), StatusCode::kUnavailable);
}

// A command that hangs (a controller that never answers) is killed after the timeout.
TEST(ProcessSlurmCommandsTest, AHungCommandIsKilledAfterTheTimeout) {
  ProcessSlurmCommands real(/*timeout_s=*/0.3);
  const auto t0 = std::chrono::steady_clock::now();
  auto r = real.Run({"sleep", "30"});
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kUnavailable);
  EXPECT_NE(r.status().reason().find("did not finish"), std::string::npos) << r.status().ToString();
  EXPECT_LT(took, 10.0);
}

}  // namespace
}  // namespace sandswim::slurm
