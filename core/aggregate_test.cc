#include "core/aggregate.h"

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include <gsl/gsl_cdf.h>
#include <gtest/gtest.h>

#include "core/scale.h"

namespace sandswim {
namespace {

ReplicateValue Value(int replicate, std::optional<double> uz, bool conclusive = true) {
  ReplicateValue v;
  v.run_id = 100 + replicate;
  v.replicate = replicate;
  v.bed_id = 10 + replicate;
  v.state = JobState::kDone;
  v.conclusive = conclusive;
  v.uz = uz;
  if (uz) {
    v.uz_stderr = 0.001;
    v.uz_ci95 = 0.003;
  }
  return v;
}

// A results page finds a dof for each of its (up to 10,000) runs: halving [0.5, 1e7] 200 times
// took 200 t quantiles a run, 11 s a page. The count, not a time, holds the cost down.
TEST(AggregateTest, TheDofBehindAnIntervalIsFoundInAFewQuantiles) {
  // Near dof = 1 (ln dof = 0) a relative stopping test has no tolerance left: 0.6-1.75 and
  // 1.000001 are where it took 26-36 quantiles.
  for (double dof : {0.6, 0.9, 1.0, 1.000001, 1.2, 1.5, 1.75, 2.0, 3.0, 7.0, 19.0, 99.0, 1000.0, 1e5, 5e6}) {
    for (double se : {1e-6, 0.3, 2.0}) {
      const DofSearch found = SearchDofOfInterval(se, gsl_cdf_tdist_Pinv(0.975, dof) * se);
      EXPECT_NEAR(found.dof, dof, 1e-8 * dof) << "se " << se;
      EXPECT_LE(found.quantiles, 25) << "dof " << dof << ", se " << se;
      EXPECT_EQ(DofOfInterval(se, gsl_cdf_tdist_Pinv(0.975, dof) * se), found.dof);
    }
  }
  // The ends: a normal quantile's interval, and one wider than t(0.975, 0.5)'s.
  EXPECT_EQ(DofOfInterval(1.0, 1.959963984540054), 1e7);
  EXPECT_EQ(DofOfInterval(1.0, 1e6), 0.5);
  // No finite ratio (a zero error, NaN): the fewest dof, the widest quantile, never a normal's.
  EXPECT_EQ(DofOfInterval(0.0, 0.01), 0.5);
  EXPECT_EQ(DofOfInterval(1.0, std::nan("")), 0.5);
  EXPECT_EQ(DofOfInterval(1.0, std::numeric_limits<double>::infinity()), 0.5);
}

TEST(AggregateTest, ThreeBedsGiveTheirMeanAndTheScatterBetweenThem) {
  ReplicateAggregate a = AggregateReplicates({Value(2, 0.14), Value(0, 0.10), Value(1, 0.12)});
  EXPECT_EQ(a.replicates, 3);
  EXPECT_EQ(a.conclusive, 3);
  EXPECT_TRUE(a.complete);
  ASSERT_TRUE(a.uz_mean && a.uz_sd_between && a.uz_stderr && a.uz_ci95);
  EXPECT_NEAR(*a.uz_mean, 0.12, 1e-12);
  EXPECT_NEAR(*a.uz_sd_between, 0.02, 1e-12);
  EXPECT_NEAR(*a.uz_stderr, 0.02 / std::sqrt(3.0), 1e-12);
  EXPECT_NEAR(*a.uz_ci95, 4.302653 * 0.02 / std::sqrt(3.0), 1e-5);  // t(0.975, 2)
  EXPECT_TRUE(a.note.empty());
  ASSERT_EQ(a.values.size(), 3u);  // each replicate's value, in replicate order
  EXPECT_EQ(a.values[0].replicate, 0);
  EXPECT_EQ(a.values[2].uz, 0.14);
}

TEST(AggregateTest, InconclusiveAndUnfinishedReplicatesAreListedNotAveraged) {
  ReplicateValue queued = Value(2, std::nullopt, false);
  queued.state = JobState::kQueued;
  ReplicateAggregate a = AggregateReplicates({Value(0, 0.10), Value(1, 0.5, false), queued, Value(3, 0.14)});
  EXPECT_EQ(a.replicates, 4);
  EXPECT_EQ(a.conclusive, 2);
  EXPECT_FALSE(a.complete);  // the point is not conclusive: its mean is shown, not used
  EXPECT_EQ(AggregateToJson(a)["complete"], false);
  EXPECT_NEAR(*a.uz_mean, 0.12, 1e-12);
  EXPECT_NE(a.note.find("2 of 4"), std::string::npos) << a.note;
  EXPECT_EQ(a.values.size(), 4u);
}

TEST(AggregateTest, OneConclusiveBedKeepsItsOwnErrorAndSaysTheScatterIsUnknown) {
  ReplicateAggregate one = AggregateReplicates({Value(0, 0.1)});
  EXPECT_EQ(one.conclusive, 1);
  EXPECT_EQ(one.uz_mean, 0.1);
  EXPECT_EQ(one.uz_stderr, 0.001);
  EXPECT_EQ(one.uz_ci95, 0.003);
  EXPECT_FALSE(one.uz_sd_between.has_value());
  EXPECT_NE(one.note.find("not known"), std::string::npos);

  ReplicateAggregate none = AggregateReplicates({Value(0, 0.2, false), Value(1, std::nullopt, false)});
  EXPECT_EQ(none.conclusive, 0);
  EXPECT_FALSE(none.uz_mean.has_value());
  EXPECT_FALSE(none.uz_ci95.has_value());
  EXPECT_NE(none.note.find("no conclusive replicate"), std::string::npos);
}

// One bed at a scale with a measured bed-to-bed prior: the point's error adds it (se^2 + (r U)^2),
// and says so; two beds measure their own scatter and never use the prior; a point of two beds
// with one conclusive is not complete and keeps the run's error.
TEST(AggregateTest, OneBedAddsTheScalesBedPrior) {
  ReplicateAggregate one = AggregateReplicates({Value(0, 0.1)}, 0.17);
  EXPECT_TRUE(one.bed_prior);
  EXPECT_NEAR(*one.uz_stderr, std::sqrt(0.001 * 0.001 + 0.017 * 0.017), 1e-12);
  EXPECT_NEAR(*one.uz_ci95, std::sqrt(0.003 * 0.003 + 1.96 * 1.96 * 0.017 * 0.017), 1e-12);
  EXPECT_NE(one.note.find("17 % of |U_z|"), std::string::npos) << one.note;
  ReplicateAggregate two = AggregateReplicates({Value(0, 0.1), Value(1, 0.12)}, 0.17);
  EXPECT_FALSE(two.bed_prior);
  EXPECT_NEAR(*two.uz_stderr, 0.01, 1e-12);
  ReplicateAggregate half = AggregateReplicates({Value(0, 0.1), Value(1, std::nullopt, false)}, 0.17);
  EXPECT_FALSE(half.bed_prior);
  EXPECT_EQ(half.uz_stderr, 0.001);
  EXPECT_EQ(FindScale("smoke")->bed_sd_rel, 0.17);
  EXPECT_FALSE(FindScale("paper")->bed_sd_rel.has_value());
}

// DofOfInterval before it stopped at convergence: a fixed 200 bisections. Kept here as the reference.
double DofOfIntervalBy200Bisections(double se, double ci95) {
  const double ratio = ci95 / se;
  if (ratio <= gsl_cdf_ugaussian_Pinv(0.975) * (1 + 1e-9)) return 1e7;
  double lo = 0.5, hi = 1e7;
  for (int i = 0; i < 200; ++i) {
    const double mid = std::sqrt(lo * hi);
    if (gsl_cdf_tdist_Pinv(0.975, mid) > ratio) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return std::sqrt(lo * hi);
}

// Stopping the bisection once it has converged gives the value 200 bisections gave, over the whole
// range: intervals made with 0.5 to 1e7 degrees of freedom, ratios off that grid, and the ends.
TEST(AggregateTest, TheIntervalsDegreesOfFreedomMatchTheFullBisection) {
  std::vector<double> ratios;
  for (double dof = 0.5; dof < 2e7; dof *= 1.37) ratios.push_back(gsl_cdf_tdist_Pinv(0.975, dof));
  for (double r = 1.9600001; r < 1e3; r *= 1.11) ratios.push_back(r);
  ratios.push_back(1e6);  // beyond t(0.975, 0.5): pinned at the low end
  for (double se : {1e-6, 0.003, 2.0}) {
    for (double ratio : ratios) {
      const double want = DofOfIntervalBy200Bisections(se, ratio * se);
      const double got = DofOfInterval(se, ratio * se);
      // Where t's quantile is flat in dof (dof in the thousands and up), many dof give the same
      // interval; what must agree is the quantile the dof stands for, and the dof where it matters.
      EXPECT_NEAR(gsl_cdf_tdist_Pinv(0.975, got), gsl_cdf_tdist_Pinv(0.975, want), 1e-12 * ratio)
          << "ratio " << ratio << " se " << se;
      if (want < 1e3) EXPECT_NEAR(got, want, 1e-10 * want) << "ratio " << ratio << " se " << se;
    }
  }
  EXPECT_EQ(DofOfInterval(1.0, gsl_cdf_ugaussian_Pinv(0.975)), 1e7);  // a normal quantile's ratio
}

// On data with a known answer: beds whose rates scatter around a true mean (normal, between-bed
// sd 0.01 m/s). The 95 % interval of K = 3 replicates must hold the truth about 95 % of the time.
TEST(AggregateTest, TheIntervalCoversTheTrueMeanAtItsNominalRate) {
  std::mt19937_64 rng(20261125);
  std::normal_distribution<double> bed(0.05, 0.01);
  const int trials = 20000;
  int covered = 0;
  for (int i = 0; i < trials; ++i) {
    ReplicateAggregate a = AggregateReplicates({Value(0, bed(rng)), Value(1, bed(rng)), Value(2, bed(rng))});
    if (std::fabs(*a.uz_mean - 0.05) <= *a.uz_ci95) ++covered;
  }
  const double rate = static_cast<double>(covered) / trials;
  EXPECT_GT(rate, 0.94);
  EXPECT_LT(rate, 0.96);
}

// Two beds that agree by chance far better than their runs are precise: the error of the mean is
// the runs' own, propagated, not the beds' tiny scatter.
TEST(AggregateTest, TheErrorIsNeverSmallerThanTheRunsOwn) {
  ReplicateValue a = Value(0, 0.100), b = Value(1, 0.101);
  a.uz_stderr = 0.13;
  b.uz_stderr = 0.16;
  ReplicateAggregate agg = AggregateReplicates({a, b});
  ASSERT_TRUE(agg.uz_stderr && agg.uz_sd_between);
  EXPECT_NEAR(*agg.uz_sd_between, 0.001 / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(*agg.uz_stderr, std::sqrt(0.13 * 0.13 + 0.16 * 0.16) / 2, 1e-12);
  EXPECT_NEAR(*agg.uz_ci95, 12.706205 * *agg.uz_stderr, 1e-5);  // t(0.975, 1)
  EXPECT_NE(agg.note.find("less than their runs' own errors"), std::string::npos) << agg.note;
}

// The point as evidence over its K beds: a censored bed is counted (its sign, its bound, its part
// of a lower estimate), never dropped; an open bed (failed, unfinished, neither) leaves no evidence.
ReplicateValue Censored(int replicate, int side, double bound) {
  ReplicateValue v = Value(replicate, std::nullopt, false);
  v.censored = side;
  v.bound = bound;
  return v;
}

TEST(AggregateTest, CensoredBedsAreEvidenceOfSignAndALowerEstimate) {
  ReplicateAggregate measured = AggregateReplicates({Value(0, 0.10), Value(1, 0.12), Value(2, 0.14)});
  EXPECT_EQ(measured.evidence, ReplicateAggregate::Evidence::kMeasured);
  EXPECT_EQ(measured.sign, 1);
  EXPECT_FALSE(measured.uz_low.has_value());

  ReplicateAggregate cut = AggregateReplicates({Value(0, 0.10), Censored(1, 1, 0.09), Censored(2, 1, 0.15)});
  EXPECT_EQ(cut.evidence, ReplicateAggregate::Evidence::kCensored);
  EXPECT_FALSE(cut.complete);
  EXPECT_EQ(cut.censored_beds, 2);
  EXPECT_EQ(cut.sign, 1);
  ASSERT_TRUE(cut.bound && cut.uz_low);
  EXPECT_NEAR(*cut.bound, 0.09, 1e-12);                   // the smallest censored bound
  EXPECT_NEAR(*cut.uz_low, (0.10 + 0.09 + 0.15) / 3, 1e-12);  // every bed, the censored by their bound
  EXPECT_NEAR(*cut.uz_mean, 0.10, 1e-12);                 // shown, over the conclusive bed only

  // Sinking at the floor: the lower estimate keeps the sign.
  ReplicateAggregate floor = AggregateReplicates({Value(0, -0.05), Censored(1, -1, 0.08)});
  EXPECT_EQ(floor.sign, -1);
  EXPECT_NEAR(*floor.uz_low, (-0.05 - 0.08) / 2, 1e-12);

  // Beds that disagree clearly: no sign, no lower estimate.
  ReplicateAggregate split = AggregateReplicates({Value(0, -0.05), Censored(1, 1, 0.08)});
  EXPECT_EQ(split.evidence, ReplicateAggregate::Evidence::kCensored);
  EXPECT_EQ(split.sign, 0);
  EXPECT_FALSE(split.uz_low.has_value());
  // A bed whose own interval holds 0 does not stop the sign the beds show together...
  ReplicateAggregate near0 = AggregateReplicates({Value(0, 0.002), Censored(1, 1, 0.08)});
  EXPECT_EQ(near0.sign, 1);
  // ... but alone it shows none; two such beds may (0.004 against sqrt(2) 0.001 t(0.975, ~9)).
  EXPECT_EQ(AggregateReplicates({Value(0, 0.002)}).sign, 0);
  EXPECT_EQ(BedsSign({Value(0, 0.002), Value(1, 0.002)}, 0.025), 1);
  EXPECT_EQ(BedsSign({Value(0, 0.0005), Value(1, 0.0005)}, 0.025), 0);

  // A failed or unfinished bed: no evidence at all, whatever the others say.
  ReplicateValue failed = Value(2, std::nullopt, false);
  failed.state = JobState::kFailed;
  ReplicateAggregate open = AggregateReplicates({Value(0, 0.10), Censored(1, 1, 0.09), failed});
  EXPECT_EQ(open.evidence, ReplicateAggregate::Evidence::kOpen);
  EXPECT_EQ(open.open_beds, 1);
  EXPECT_EQ(open.sign, 0);
  EXPECT_FALSE(open.uz_low.has_value());
}

TEST(AggregateTest, JsonCarriesEveryReplicate) {
  nlohmann::json j = AggregateToJson(AggregateReplicates({Value(0, 0.1), Value(1, 0.2)}));
  EXPECT_EQ(j["replicates"], 2);
  EXPECT_EQ(j["conclusive"], 2);
  EXPECT_NEAR(j["uz_mean"].get<double>(), 0.15, 1e-12);
  ASSERT_EQ(j["values"].size(), 2u);
  EXPECT_EQ(j["values"][1]["bed_id"], 11);
  EXPECT_EQ(j["values"][1]["uz"], 0.2);
}

}  // namespace
}  // namespace sandswim
