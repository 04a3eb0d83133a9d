#include "core/cost.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

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

// The share now: the running runs' pooled rate over the window against the model's; its error
// how far it moved from the window before (else from the runs' attempts so far).
TEST(CostTest, TheShareNowScalesTheRateAndItsChangeWidensTheError) {
  const EngineRate model{1e-6, 0.1, 5, "measured: 5 done runs"};
  // Two runs at a third of the model's rate over 10 min; the 10 min before at the model's.
  const std::vector<RateSample> recent = {{2e8, 600}, {1e8, 300}}, before = {{6e8, 600}, {6e8, 600}};
  const Share share = CurrentShare(recent, before, {}, model, kShareWindowS);
  ASSERT_TRUE(share.measured);
  EXPECT_NEAR(share.factor, 3, 1e-12);
  EXPECT_EQ(share.engines, 2);
  ASSERT_TRUE(share.factor_before.has_value());
  EXPECT_NEAR(*share.factor_before, 1, 1e-12);
  // Taken halfway: a third of the rate now, the model's before; the truth may lie toward either.
  EXPECT_NEAR(share.scale, std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(share.rel_error, std::hypot(std::log(3.0) / 2, std::log(3.0)), 1e-12);
  const EngineRate now = AtShare(model, share);
  EXPECT_GT(now.s_per_unit, model.s_per_unit);
  EXPECT_LT(now.s_per_unit, 3e-6);
  EXPECT_NEAR(now.rel_error, std::hypot(0.1, share.rel_error), 1e-12);
  EXPECT_EQ(now.basis,
            "measured: 5 done runs; now 2 engines at 0.33 of that rate over the last 10 min (1.00 over the 10 min "
            "before); taken halfway: 0.58, ± 123 % for the share");
  // A steady share: the rate as it was, the error the model's.
  const Share steady = CurrentShare({{6e8, 600}}, {{6e8, 600}}, {}, model, kShareWindowS);
  EXPECT_NEAR(steady.factor, 1, 1e-12);
  EXPECT_NEAR(AtShare(model, steady).rel_error, 0.1, 1e-12);
  // No window before: the attempts so far; stretches too short to say anything: unmeasured.
  const Share young = CurrentShare({{2e8, 400}}, {}, {{4e8, 500}}, model, kShareWindowS);
  ASSERT_TRUE(young.factor_before.has_value());
  EXPECT_NEAR(*young.factor_before, 1.25, 1e-12);
  EXPECT_EQ(young.before_basis, "their attempts so far");
  const Share none = CurrentShare({{1e6, kMinShareStretchS / 2}}, {}, {}, model, kShareWindowS);
  EXPECT_FALSE(none.measured);
  EXPECT_EQ(AtShare(model, none).s_per_unit, model.s_per_unit);
  EXPECT_EQ(AtShare(model, none).basis, model.basis);
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

// The last bed granted finds the queue dry and takes the slots still idle (up to max_ranks); the
// others, and every bed when there are more beds than slots, run on one rank.
TEST(CostTest, TheLastBedTakesTheIdleSlots) {
  EXPECT_EQ(BedRanks(1, 2, 2), (std::vector<int>{2}));
  EXPECT_EQ(BedRanks(1, 8, 8), (std::vector<int>{8}));
  EXPECT_EQ(BedRanks(1, 8, 4), (std::vector<int>{4}));  // --max-ranks caps it
  EXPECT_EQ(BedRanks(1, 2, 1), (std::vector<int>{1}));  // a worker that does not widen
  EXPECT_EQ(BedRanks(1, 2, 0), (std::vector<int>{1}));
  EXPECT_EQ(BedRanks(3, 8, 8), (std::vector<int>{1, 1, 6}));
  EXPECT_EQ(BedRanks(2, 2, 2), (std::vector<int>{1, 1}));
  EXPECT_EQ(BedRanks(3, 2, 2), (std::vector<int>{1, 1, 1}));
  EXPECT_TRUE(BedRanks(0, 2, 2).empty());
}

TEST(CostTest, BedsAreCostedAtTheRanksTheyGet) {
  EngineRate run{1e-6, 0.2, 5, "runs"}, bed{0.1, 0.3, 1, "bed"};
  Plan plan;  // one bed of 999 grains (99.9 s on one rank), four runs of 100 s
  plan.scale = "smoke";
  plan.beds.resize(1);
  plan.runs.resize(4);
  for (auto& r : plan.runs) r.steps = 100000;
  const PlanCost c = CostOfPlan(plan, {999.0}, run, bed);
  // No widening: as WallSeconds.
  for (int slots : {1, 2, 8}) EXPECT_NEAR(PlanWallOn(c, slots, 1, {{1, bed}}).s, c.WallSeconds(slots), 1e-9);
  // On 2 slots the bed runs on 2 ranks at the 2-rank rate measured (0.07 s a grain), then the runs.
  PlanWall w = PlanWallOn(c, 2, 2, {{1, bed}, {2, {0.07, 0.1, 3, "two"}}});
  EXPECT_EQ(w.bed_ranks, (std::vector<int>{2}));
  EXPECT_NEAR(w.s, 69.93 + 200, 1e-9);
  EXPECT_NEAR(w.rel_error, std::hypot(0.2 * 200, 0.1 * 69.93) / 269.93, 1e-12);
  // Nothing measured on 2 ranks: the one-rank rate over 1.42, with the guess's error added.
  w = PlanWallOn(c, 2, 2, {{1, bed}});
  EXPECT_NEAR(w.s, 99.9 / kDefaultTwoRankSpeedup + 200, 1e-9);
  EXPECT_NEAR(w.rel_error,
              std::hypot(0.2 * 200, std::hypot(0.3, kDefaultRateRelError) * 99.9 / kDefaultTwoRankSpeedup) /
                  (99.9 / kDefaultTwoRankSpeedup + 200),
              1e-12);
  // No rates at all: the default bed rate.
  EXPECT_NEAR(PlanWallOn(c, 1, 1, {}).s, 999 * kDefaultBedSecondsPerGrain + 400, 1e-9);
}

TEST(CostTest, EtaCountsWhatIsLeftOfRunningRunsAndBeds) {
  EngineRate run{1e-6, 0.1, 5, "runs"}, bed{0.1, 0.3, 1, "bed"};
  std::vector<WorkLeft> left;
  left.push_back({WorkLeft::Kind::kRun, true, 1000, 100000, 25000, 80});  // 75 s left
  left.push_back({WorkLeft::Kind::kRun, false, 1000, 100000, 0, 0});      // 100 s
  left.push_back({WorkLeft::Kind::kRun, false, 1000, 100000, 0, 0});      // 100 s
  auto eta = EstimateEta(left, run, bed, StepShare{}, 2);
  ASSERT_TRUE(eta.has_value());
  EXPECT_DOUBLE_EQ(eta->seconds, 137.5);
  EXPECT_DOUBLE_EQ(eta->rel_error, 0.1);  // no target, none done: counted to their ends, the rate's error
  // Runs that stop at half their steps, as four done ones did (sd 0.1): the running one is not
  // past that. Each run's own scatter (0.1 x 100 s) and the mean's (0.1 / sqrt(4) x 100 s, shared).
  eta = EstimateEta(left, run, bed, StepShare{4, 0.5, 0.1}, 2);
  EXPECT_DOUBLE_EQ(eta->seconds, (25 + 50 + 50) / 2.0);
  const double t3 = 1 + 0.5 / 3 + 0.25 / 9 + 0.0625 / 27;  // Student's t at one sigma, 3 dof: 1.197
  const double length_sigma = t3 * std::hypot(3 * 5.0, std::sqrt(3 * 10.0 * 10.0));
  EXPECT_NEAR(eta->rel_error, std::hypot(0.1, length_sigma / 125), 1e-12);
  EXPECT_NE(eta->basis.find("50 %"), std::string::npos);
  // A running bed with 30 s left holds its runs: never less than the longest item.
  std::vector<WorkLeft> bed_only = {{WorkLeft::Kind::kBed, true, 1000, 0, 0, 70}};
  eta = EstimateEta(bed_only, run, bed, StepShare{}, 2);
  EXPECT_DOUBLE_EQ(eta->seconds, 30);
  EXPECT_FALSE(EstimateEta({}, run, bed, StepShare{}, 2).has_value());
}

// Runs with a precision target end between their earliest target stop and their deck's end.
// Before any is done they are expected halfway, with that range's spread as the error (it was
// every run to its end, with the rate's 10 % alone); a running run that outlived the done runs'
// share is expected halfway through the rest of its range, not at once (it said 0 s left, 0 error).
TEST(CostTest, EtaOfRunsWithATargetSpansTheirRange) {
  EngineRate run{1e-6, 0.1, 5, "runs"}, bed{0.1, 0.3, 1, "bed"};
  WorkLeft w{WorkLeft::Kind::kRun, false, 1000, 100000, 0, 0};
  w.min_steps = 40000;  // ends between 40 and 100 s
  auto eta = EstimateEta({w, w}, run, bed, StepShare{}, 1);
  ASSERT_TRUE(eta.has_value());
  EXPECT_DOUBLE_EQ(eta->seconds, 140);
  EXPECT_NEAR(eta->rel_error, std::hypot(0.1, 2 * 60 / std::sqrt(12.0) / 140), 1e-12);
  EXPECT_NE(eta->basis.find("halfway"), std::string::npos);
  // The last run, running at 80 % while the done ones used 50 %: 10 s expected, +-5.8 s.
  WorkLeft last = w;
  last.running = true;
  last.steps_done = 80000;
  eta = EstimateEta({last}, run, bed, StepShare{10, 0.5, 0.1}, 1);
  EXPECT_DOUBLE_EQ(eta->seconds, 10);
  EXPECT_NEAR(eta->rel_error, std::hypot(0.1, 20 / std::sqrt(12.0) / 10), 1e-12);
  // A share below the earliest stop is held at it.
  eta = EstimateEta({w}, run, bed, StepShare{10, 0.2, 0.01}, 1);
  EXPECT_DOUBLE_EQ(eta->seconds, 40);
}

// The stated error is honest: runs whose targets end them anywhere in their range, the runs of a
// scope alike (a share drawn for the scope, each run near it) or each on its own, predicted after
// 0..n-1 of them are done. With the rate known exactly, the truth lies within the stated 1 sigma
// about as often as a normal error says (68 %; at least 60 % asked) and within 2 sigma at least
// 90 % of the time. With the old rule (every
// run to its end before one was done; afterwards sd / sqrt(runs left) of the mean share alone) the
// truth was inside 1 sigma far less often.
TEST(CostTest, EtaErrorCoversRunsThatStopEarlyAtTheirTarget) {
  const EngineRate run{1e-6, 0, 5, "exact"}, bed{0.1, 0, 1, "bed"};
  const int n = 12;
  const double lo_share = 0.3;
  uint64_t seed = 12345;
  auto uniform = [&seed]() {  // a fixed generator: the same draws on every platform
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(seed >> 11) / static_cast<double>(1ULL << 53);
  };
  for (bool alike : {true, false}) {
    int within1 = 0, within2 = 0, trials = 0;
    for (int trial = 0; trial < 400; ++trial) {
      const double scope_share = lo_share + (1 - lo_share) * uniform();
      std::vector<double> shares;
      for (int i = 0; i < n; ++i) {
        const double own = alike ? std::clamp(scope_share + 0.05 * (uniform() - 0.5), lo_share, 1.0)
                                 : lo_share + (1 - lo_share) * uniform();
        shares.push_back(own);
      }
      for (int k = 0; k < n; ++k) {  // k done, the rest queued, one engine
        StepShare share;
        if (k > 0) {
          double mean = 0, ss = 0;
          for (int i = 0; i < k; ++i) mean += shares[i];
          mean /= k;
          for (int i = 0; i < k; ++i) ss += (shares[i] - mean) * (shares[i] - mean);
          share = {k, mean, k > 1 ? std::sqrt(ss / (k - 1)) : 0.5 * mean};
        }
        std::vector<WorkLeft> left;
        double truth = 0;
        for (int i = k; i < n; ++i) {
          WorkLeft w{WorkLeft::Kind::kRun, false, 1000, 100000, 0, 0};
          w.min_steps = static_cast<int64_t>(lo_share * 100000);
          left.push_back(w);
          truth += shares[i] * 100;
        }
        auto eta = EstimateEta(left, run, bed, share, 1);
        ASSERT_TRUE(eta.has_value());
        const double z = std::fabs(truth - eta->seconds) / (eta->rel_error * eta->seconds);
        within1 += z <= 1;
        within2 += z <= 2;
        ++trials;
      }
    }
    const double c1 = static_cast<double>(within1) / trials, c2 = static_cast<double>(within2) / trials;
    EXPECT_GE(c1, 0.6) << (alike ? "alike" : "independent") << ": within 1 sigma " << c1;
    EXPECT_GE(c2, 0.9) << (alike ? "alike" : "independent") << ": within 2 sigma " << c2;
    std::printf("runs %s: truth within 1 sigma %.1f %%, within 2 sigma %.1f %%\n",
                alike ? "alike" : "each on its own", 100 * c1, 100 * c2);
  }
}

}  // namespace
}  // namespace sandswim
