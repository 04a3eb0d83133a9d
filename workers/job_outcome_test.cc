#include "workers/job_outcome.h"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "tests/fixture_file.h"

namespace sandswim::worker {
namespace {

using testing::Fixture;  // tests/fixture_file.h

struct RunFixture {
  DriveInfo drive;
  EngineLog log;
  Result<std::vector<SoSample>> samples = Status::Internal("unread");
};

RunFixture Vibration3s() {
  RunFixture f;
  f.drive = *ReadDriveInfo(Fixture("runs/vibration-3s/drive.in"));
  f.log = ParseEngineLog(Fixture("runs/vibration-3s/log.liggghts"));
  f.samples = SamplesFromDump(Fixture("runs/vibration-3s/so.dump"), f.drive.dt);
  return f;
}

// A completed run is its analysis: the same result as the analysis of its samples, and a trajectory.
TEST(JobOutcomeTest, ACompletedRunIsItsAnalysis) {
  RunFixture f = Vibration3s();
  ASSERT_TRUE(f.samples.ok());
  JobOutcome out = JudgeJob(api::JobKind::kRun, 0, ExitFacts{}, f.log, f.drive, f.samples);
  ASSERT_FALSE(out.failure) << out.failure->message;
  ASSERT_TRUE(out.result.has_value());
  auto want = AnalyzeRun(*f.samples, RunInputsFrom(f.drive, f.log));
  ASSERT_TRUE(want.ok());
  EXPECT_EQ(out.result->uz, want->uz);
  EXPECT_EQ(out.result->uz_stderr, want->uz_stderr);
  EXPECT_EQ(out.result->uz_blocks, want->uz_blocks);
  ASSERT_TRUE(out.trajectory.has_value());
  EXPECT_EQ(out.trajectory->t.size(), out.trajectory->z.size());
  EXPECT_GT(out.trajectory->t.size(), 100u);
  EXPECT_FALSE(out.bed.has_value());
}

TEST(JobOutcomeTest, AnEngineErrorIsTheEnginesExit) {
  RunFixture f = Vibration3s();
  ExitFacts facts;
  facts.exit_code = 1;
  JobOutcome out =
      JudgeJob(api::JobKind::kRun, 0, facts, ParseEngineLog(Fixture("deck_error.log")), f.drive, f.samples);
  ASSERT_TRUE(out.failure.has_value());
  EXPECT_EQ(out.failure->kind, "deck_error");
  EXPECT_TRUE(out.engine_exit);  // a stop of the whole worker may explain it
  EXPECT_FALSE(out.result.has_value());
}

TEST(JobOutcomeTest, AnUnreadableDumpIsBadOutputNamingTheDump) {
  RunFixture f = Vibration3s();
  JobOutcome out = JudgeJob(api::JobKind::kRun, 0, ExitFacts{}, f.log, f.drive, Status::Corruption("dump line 7: x"));
  ASSERT_TRUE(out.failure.has_value());
  EXPECT_EQ(out.failure->kind, "bad_output");
  EXPECT_NE(out.failure->message.find("so.dump"), std::string::npos) << out.failure->message;
  EXPECT_FALSE(out.engine_exit);
}

TEST(JobOutcomeTest, ACompletedBedIsItsLogsFigures) {
  const EngineLog log = ParseEngineLog(Fixture("bed.log"));
  JobOutcome out =
      JudgeJob(api::JobKind::kBed, 0, ExitFacts{}, log, DriveInfo{1e-5, 0, 0, std::nullopt}, std::vector<SoSample>());
  ASSERT_FALSE(out.failure) << out.failure->message;
  ASSERT_TRUE(out.bed.has_value());
  EXPECT_EQ(out.bed->grains, log.bed_grains->grains);
  EXPECT_EQ(out.bed->grain_top, log.bed_grains->grain_top);
  EXPECT_TRUE(out.bed->sha256.empty());  // the runner adds the restart's checksum
}

}  // namespace
}  // namespace sandswim::worker
