// The drive's time step (core/numerics.h): its criteria at the matrix's extremes, the bounds that
// refuse an asked step, the default that shrinks for a point that needs it, and everything counted
// in steps following the step (core/deck.h).
#include "core/numerics.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/deck.h"
#include "core/keys.h"
#include "core/sweep.h"

namespace sandswim {
namespace {

using ::testing::HasSubstr;

Point Baseline(double Omega = -80) { return OscillatoryPoint(0.03, 3, Omega, 4); }

TEST(NumericsTest, Table1sStepAtTheBaselineIsFarInsideEveryBound) {
  const StepCriteria c = JudgeStep(Baseline(), 1e-5);
  EXPECT_NEAR(c.grain_rayleigh_fraction, 1e-5 / 8.56e-4, 2e-4);  // 1.2 %
  EXPECT_EQ(c.speed_from, "oscillatory rotation");
  EXPECT_NEAR(c.speed_mps, 80 * 0.06, 1e-12);
  EXPECT_GT(c.contact_steps, 140);  // a Hertz contact of ~1.5 ms at 4.8 m/s
  EXPECT_LT(c.contact_steps, 160);
  EXPECT_NEAR(c.pass_steps, 0.02 / (4.8 * 1e-5), 1e-6);
  EXPECT_EQ(c.level, StepLevel::kOk);
}

TEST(NumericsTest, FastRotationsAreWhereALongStepIsRefused) {
  // |Omega| = 1280: the SO's surface at 76.8 m/s passes a 2 cm grain in 5.2 steps of 5e-5 s.
  EXPECT_EQ(JudgeStep(Baseline(-1280), 5e-5).level, StepLevel::kRefused);
  EXPECT_THAT(JudgeStep(Baseline(-1280), 5e-5).refusal, HasSubstr("pass a grain diameter"));
  EXPECT_EQ(JudgeStep(Baseline(-1280), 2.5e-5).level, StepLevel::kWarned);
  EXPECT_EQ(JudgeStep(Baseline(-640), 1e-4).level, StepLevel::kRefused);
  EXPECT_EQ(JudgeStep(Baseline(-640), 5e-5).level, StepLevel::kWarned);
  // The baseline at 1e-4 s: 11.7 % of the Rayleigh time and 15 steps a contact, warned, run.
  const StepCriteria c = JudgeStep(Baseline(), 1e-4);
  EXPECT_EQ(c.level, StepLevel::kWarned);
  EXPECT_EQ(c.warnings.size(), 2u);
  // f = 30 Hz, A = 0.03: 5.65 m/s of vibration is its fastest speed.
  const StepCriteria f30 = JudgeStep(OscillatoryPoint(0.03, 30, -80, 1), 1e-4);
  EXPECT_EQ(f30.speed_from, "vibration");
  EXPECT_NE(f30.level, StepLevel::kRefused);
  // The largest accepted step is on the bound: refused just above it.
  const double largest = LargestAcceptedStep(Baseline(-1280));
  EXPECT_NE(JudgeStep(Baseline(-1280), largest).level, StepLevel::kRefused);
  EXPECT_EQ(JudgeStep(Baseline(-1280), largest * 1.02).level, StepLevel::kRefused);
}

TEST(NumericsTest, AnAskedStepIsTakenOrRefusedNamingTheFieldAndTheCriterion) {
  const Scale& smoke = *FindScale("smoke");
  Point p = Baseline();
  ASSERT_TRUE(ResolveDriveStep(p, smoke, Numerics{5e-5}).ok());
  EXPECT_EQ(p.dt_s, 5e-5);
  EXPECT_EQ(DriveStep(p), 5e-5);
  Point fast = Baseline(1280);
  const Status s = ResolveDriveStep(fast, smoke, Numerics{5e-5});
  EXPECT_EQ(s.field(), "numerics.dt");
  EXPECT_THAT(s.reason(), HasSubstr("pass a grain diameter"));
  EXPECT_THAT(s.reason(), HasSubstr("at most 2.6e-05 s"));
  // Table 1's own step asked: the point is what it always was.
  Point same = Baseline();
  ASSERT_TRUE(ResolveDriveStep(same, smoke, Numerics{1e-5}).ok());
  EXPECT_FALSE(same.dt_s.has_value());
}

TEST(NumericsTest, ADefaultNeverMakesAPointInvalidItShrinksDownTheLadder) {
  Scale coarse = *FindScale("smoke");
  coarse.default_dt_s = 1e-4;
  Point slow = Baseline();
  ASSERT_TRUE(ResolveDriveStep(slow, coarse, Numerics{}).ok());
  EXPECT_EQ(DriveStep(slow), 1e-4);
  Point mid = Baseline(640);
  ASSERT_TRUE(ResolveDriveStep(mid, coarse, Numerics{}).ok());
  EXPECT_EQ(DriveStep(mid), 5e-5);
  Point fast = Baseline(-1280);
  ASSERT_TRUE(ResolveDriveStep(fast, coarse, Numerics{}).ok());
  EXPECT_EQ(DriveStep(fast), 2.5e-5);
  // Past what Table 1's step takes (|Omega| = 5000: 300 m/s), the default goes below the ladder.
  Point fastest = Baseline(5000);
  ASSERT_TRUE(ResolveDriveStep(fastest, *FindScale("smoke"), Numerics{}).ok());
  EXPECT_LT(DriveStep(fastest), 1e-5);
  EXPECT_NE(JudgeStep(fastest, DriveStep(fastest)).level, StepLevel::kRefused);
}

TEST(NumericsTest, BadStepsAreRefusedNamingDt) {
  for (const char* bad : {R"({"dt": -1e-5})", R"({"dt": 0})", R"({"dt": "5e-5"})", R"({"dt": 1e-9})",
                          R"({"dt": 0.01})", R"({"step": 5e-5})", R"([5e-5])"}) {
    const Result<Numerics> n = ParseNumerics(nlohmann::json::parse(bad));
    ASSERT_FALSE(n.ok()) << bad;
    EXPECT_EQ(n.status().code(), StatusCode::kInvalidArgument) << bad;
  }
  EXPECT_EQ(ParseNumerics(nlohmann::json::parse(R"({"dt": 5e-5})"))->dt_s, 5e-5);
  // In a sweep, with its path; and where it does not belong (a point's base), refused.
  auto sweep = [](const std::string& extra) {
    return ParseSweep(nlohmann::json::parse(R"({"name": "s", "scale": "smoke", "base": {"mode": "oscillatory", "A": 0.03,
      "f": 3, "Omega": -80, "duration_s": 1)" + extra));
  };
  EXPECT_EQ(sweep(R"(}, "numerics": {"dt": -1}})").status().field(), "numerics.dt");
  EXPECT_FALSE(sweep(R"(, "dt_s": 5e-5}})").ok());
  EXPECT_FALSE(sweep(R"(, "numerics": {"dt": 5e-5}}})").ok());
}

TEST(NumericsTest, EverythingCountedInStepsFollowsTheStep) {
  const Scale& smoke = *FindScale("smoke");
  Point p = Baseline();
  const std::string table1 = RenderDriveDeck(p, smoke, std::nullopt);
  ASSERT_TRUE(ResolveDriveStep(p, smoke, Numerics{5e-5}).ok());
  const std::string deck = RenderDriveDeck(p, smoke, std::nullopt);
  EXPECT_THAT(deck, HasSubstr("timestep        5e-05\n"));
  EXPECT_THAT(deck, HasSubstr("run 20 pre no post no"));          // the omega chunk: 1 ms
  EXPECT_THAT(deck, HasSubstr("dump traj so custom 20 so.dump"));  // the dump: 1 ms
  EXPECT_THAT(deck, HasSubstr("thermo          200\n"));            // 10 ms
  EXPECT_THAT(deck, HasSubstr("# Time step 5e-05 s, not Table 1's rule"));
  EXPECT_EQ(DriveSteps(p, std::nullopt), 80000);  // 4 s
  EXPECT_EQ(DriveFacts(p, smoke).dt, 5e-5);
  EXPECT_NE(RunKey(deck, "bed", "engine"), RunKey(table1, "bed", "engine"));
  // At 30 Hz the chunk still holds 20 updates a period.
  Point f30 = OscillatoryPoint(0.03, 30, -80, 1);
  ASSERT_TRUE(ResolveDriveStep(f30, smoke, Numerics{5e-5}).ok());
  EXPECT_LE(OmegaUpdateSteps(f30) * 5e-5 * 30 * kMinOmegaUpdatesPerPeriod, 1 + 1e-9);
}

TEST(NumericsTest, PointsAtDifferentStepsNeverPoolAndTheStepIsStored) {
  Point a = Baseline(), b = Baseline();
  b.dt_s = 5e-5;
  EXPECT_FALSE(SameDrive(a, b));
  EXPECT_NE(DriveIdOf(a), DriveIdOf(b));
  Result<Point> stored = StoredPoint("oscillatory", "x", 0.03, 3, -80, 0, 4, std::nullopt, 5e-5);
  ASSERT_TRUE(stored.ok());
  EXPECT_TRUE(SameDrive(*stored, b));
  EXPECT_FALSE(StoredPoint("oscillatory", "x", 0.03, 3, -80, 0, 4, std::nullopt, -1.0).ok());
  // Two sweeps of one point at two steps plan two runs; at one step, one.
  auto plan = [](const std::string& dt1, const std::string& dt2) {
    std::vector<SweepSpec> sweeps;
    for (const std::string& dt : {dt1, dt2}) {
      auto s = ParseSweep(nlohmann::json::parse(R"({"name": "s)" + dt + R"(", "scale": "smoke", "numerics": {"dt": )" +
                                                dt + R"(}, "base": {"mode": "oscillatory", "A": 0.03, "f": 3,
          "Omega": -80, "duration_s": 1}})"));
      EXPECT_TRUE(s.ok()) << s.status().ToString();
      sweeps.push_back(*s);
    }
    return PlanSweeps(sweeps, *FindScale("smoke"), "engine");
  };
  EXPECT_EQ(plan("1e-05", "5e-05")->runs.size(), 2u);
  EXPECT_EQ(plan("5e-05", "5e-05")->runs.size(), 1u);
  const nlohmann::json j = PlannedRunToJson(plan("1e-05", "5e-05")->runs[1]);
  EXPECT_EQ(j["dt_s"], 5e-5);
  EXPECT_EQ(j["dt_criteria"]["level"], "ok");
}

TEST(NumericsTest, TheConvergenceCampaignPlansAtEveryStepItsPointsTake) {
  auto c = BuiltinCampaign("dt-convergence");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  auto plans = PlanSubmission(c->sweeps, "engine", PlanOptions{}, true);
  ASSERT_TRUE(plans.ok()) << plans.status().ToString();
  std::map<double, int> by_step;
  for (const PlannedRun& r : (*plans)[0].plan.runs) ++by_step[DriveStep(r.point)];
  // 18 points at 1e-5 and 2.5e-5, 16 at 5e-5 (no |Omega| = 1280), 14 at 1e-4 (nor 640), 3 beds each.
  EXPECT_EQ(by_step[1e-5], 54);
  EXPECT_EQ(by_step[2.5e-5], 54);
  EXPECT_EQ(by_step[5e-5], 48);
  EXPECT_EQ(by_step[1e-4], 42);
}

}  // namespace
}  // namespace sandswim
