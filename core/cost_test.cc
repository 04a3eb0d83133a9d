#include "core/cost.h"

#include <cmath>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

TEST(CostTest, FitRatePoolsWorkAndTime) {
  // Two runs: 1e9 particle-steps in 600 s and 1e9 in 800 s -> 7e-7 s a particle-step.
  EngineRate r = FitRate({{1e9, 600}, {1e9, 800}}, DefaultRate(), "two runs");
  EXPECT_DOUBLE_EQ(r.s_per_unit, 7e-7);
  EXPECT_EQ(r.samples, 2);
  EXPECT_EQ(r.basis, "two runs");
  // Spread of log rates ln(8/6) / sqrt(2) over sqrt(2): about 0.14.
  EXPECT_NEAR(r.rel_error, std::log(800.0 / 600.0) / std::sqrt(2.0) / std::sqrt(2.0), 1e-12);
}

TEST(CostTest, FitRateNeverClaimsBetterThanItsFloor) {
  EngineRate r = FitRate({{1e9, 600}, {1e9, 600}, {2e9, 1200}}, DefaultRate(), "same");
  EXPECT_DOUBLE_EQ(r.rel_error, kMinRateRelError);
}

TEST(CostTest, FitRateFallsBackWithoutUsableSamples) {
  EngineRate r = FitRate({{0, 10}, {1e9, 0}, {NAN, 3}}, DefaultRate(), "none");
  EXPECT_EQ(r.samples, 0);
  EXPECT_DOUBLE_EQ(r.s_per_unit, kDefaultSecondsPerParticleStep);
}

TEST(CostTest, EstimatedGrainsScaleWithTheBedsVolume) {
  EXPECT_DOUBLE_EQ(EstimatedGrains(*FindScale("smoke")), 6682);
  // The paper's box holds about 7e4 grains (core/scale.cc), mini about 1.5e4: within 35 %.
  EXPECT_NEAR(EstimatedGrains(*FindScale("paper")), 7e4, 0.35 * 7e4);
  EXPECT_NEAR(EstimatedGrains(*FindScale("mini")), 1.5e4, 0.35 * 1.5e4);
}

TEST(CostTest, PlanWallTimeSpreadsRunsOverSlotsAfterTheBed) {
  EngineRate run{1e-6, 0.2, 5, "runs"}, bed{0.1, 0.3, 1, "bed"};
  // One bed of 999 grains (99.9 s), four runs of 1e8 particle-steps (100 s each).
  Plan plan;
  plan.scale = "smoke";
  plan.beds.resize(1);
  plan.runs.resize(4);
  for (auto& r : plan.runs) r.steps = 100000;
  PlanCost c = CostOfPlan(plan, {999.0}, run, bed);
  EXPECT_EQ(c.runs, 4);
  EXPECT_DOUBLE_EQ(c.particle_steps, 4e8);
  EXPECT_DOUBLE_EQ(c.run_core_s, 400);
  EXPECT_NEAR(c.bed_core_s, 99.9, 1e-9);
  EXPECT_NEAR(c.WallSeconds(1), 499.9, 1e-9);
  EXPECT_NEAR(c.WallSeconds(2), 299.9, 1e-9);  // the bed alone, then two runs at a time
  EXPECT_NEAR(c.WallSeconds(8), 199.9, 1e-9);  // never less than the bed plus one run
  EXPECT_GT(c.rel_error, 0.15);
  EXPECT_LT(c.rel_error, 0.3);
  // A bed not prepared yet counts the scale's estimate.
  EXPECT_DOUBLE_EQ(CostOfPlan(plan, {}, run, bed).bed_core_s, 668.2);
}

TEST(CostTest, EtaCountsWhatIsLeftOfRunningRunsAndBeds) {
  EngineRate run{1e-6, 0.1, 5, "runs"}, bed{0.1, 0.3, 1, "bed"};
  std::vector<WorkLeft> left;
  left.push_back({WorkLeft::Kind::kRun, true, 1000, 100000, 25000, 80});  // 75 s left
  left.push_back({WorkLeft::Kind::kRun, false, 1000, 100000, 0, 0});      // 100 s
  left.push_back({WorkLeft::Kind::kRun, false, 1000, 100000, 0, 0});      // 100 s
  auto eta = EstimateEta(left, run, bed, 1.0, 0.0, 2);
  ASSERT_TRUE(eta.has_value());
  EXPECT_DOUBLE_EQ(eta->seconds, 137.5);
  EXPECT_DOUBLE_EQ(eta->rel_error, 0.1);
  // Runs that stop at half their steps, as the done ones did: the running one is past that.
  eta = EstimateEta(left, run, bed, 0.5, 0.2, 2);
  EXPECT_DOUBLE_EQ(eta->seconds, (25 + 50 + 50) / 2.0);
  EXPECT_NEAR(eta->rel_error, std::hypot(0.1, 0.2), 1e-12);
  EXPECT_NE(eta->basis.find("50 %"), std::string::npos);
  // A running bed with 30 s left holds its runs: never less than the longest item.
  std::vector<WorkLeft> bed_only = {{WorkLeft::Kind::kBed, true, 1000, 0, 0, 70}};
  eta = EstimateEta(bed_only, run, bed, 1.0, 0.0, 2);
  EXPECT_DOUBLE_EQ(eta->seconds, 30);
  EXPECT_FALSE(EstimateEta({}, run, bed, 1.0, 0.0, 2).has_value());
}

}  // namespace
}  // namespace sandswim
