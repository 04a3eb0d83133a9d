// The drift decision (core/drift.h): what a change is held to, and the campaign's Holm verdict.
// Its false alarms and power are measured on the truth engine (tests/truth/truth_test.cc
// DriftAlarmTest, bench_drift_alarms).
#include "core/drift.h"

#include <cmath>

#include <gsl/gsl_cdf.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

DriftBedPair Pair(double uz, double se, double dof, double before, double se_before, double dof_before) {
  DriftBedPair b;
  b.uz = uz;
  b.uz_stderr = se;
  b.dof = dof;
  b.uz_previous = before;
  b.uz_stderr_previous = se_before;
  b.dof_previous = dof_before;
  return b;
}

// Rule 2 holds a run's change to Student t with Welch's dof from both runs' own: two errors of
// 0.003 m/s on 3 dof each give 6 dof and a bound of t(0.975, 6) sqrt(2) 0.003 = 0.0104 m/s, where
// rule 1's normal quantile gave 0.0083 m/s; a change of 0.009 m/s is within rule 2's, beyond rule 1's.
TEST(DriftTest, OneBedIsHeldToWelchsStudentT) {
  DriftTest test;
  test.beds = {Pair(0.109, 0.003, 3, 0.100, 0.003, 3)};
  const DriftDecision d = DecideDrift(test);
  ASSERT_TRUE(d.compared);
  EXPECT_TRUE(d.tested);
  EXPECT_NEAR(d.difference, 0.009, 1e-12);
  EXPECT_NEAR(d.dof, 6, 1e-9);
  EXPECT_NEAR(d.bound, gsl_cdf_tdist_Pinv(0.975, 6) * std::sqrt(2.0) * 0.003, 1e-12);
  EXPECT_NEAR(d.p_value, 2 * gsl_cdf_tdist_Q(0.009 / (std::sqrt(2.0) * 0.003), 6), 1e-12);
  EXPECT_GT(d.p_value, 0.05);
  EXPECT_FALSE(d.drifted);
  test.rule = 1;
  const DriftDecision old = DecideDrift(test);
  EXPECT_NEAR(old.bound, 1.96 * std::sqrt(2.0) * 0.003, 1e-12);
  EXPECT_TRUE(old.drifted);
}

// A point's beds are each compared with themselves: three beds far apart (their effects) that each
// moved by 0.004 m/s drifted by 0.004 against sqrt(3 * 2 * 0.002^2) / 3 = 0.0016; the spread between
// the beds plays no part.
TEST(DriftTest, APointsBedsArePairedSoTheirEffectsCancel) {
  DriftTest test;
  test.beds = {Pair(0.084, 0.002, 1e7, 0.080, 0.002, 1e7), Pair(0.124, 0.002, 1e7, 0.120, 0.002, 1e7),
               Pair(0.104, 0.002, 1e7, 0.100, 0.002, 1e7)};
  const DriftDecision d = DecideDrift(test);
  ASSERT_TRUE(d.compared);
  EXPECT_EQ(d.beds, 3);
  EXPECT_NEAR(d.difference, 0.004, 1e-12);
  EXPECT_NEAR(d.stderr_mps, std::sqrt(6 * 0.002 * 0.002) / 3, 1e-12);
  EXPECT_TRUE(d.drifted);
  // Rule 1 compares one bed at a time.
  test.rule = 1;
  EXPECT_FALSE(DecideDrift(test).compared);
}

// A bed re-poured between the nights adds both beds' effects, from the scale's prior; with none,
// the pair is not compared.
TEST(DriftTest, AnotherBedAddsTheBedToBedScatter) {
  DriftTest test;
  DriftBedPair b = Pair(0.120, 0.002, 1e7, 0.100, 0.002, 1e7);
  b.same_bed = false;
  test.beds = {b};
  test.bed_sd_rel = 0.17;
  const DriftDecision d = DecideDrift(test);
  ASSERT_TRUE(d.compared);
  const double bed = 0.17 * 0.110;
  EXPECT_NEAR(d.stderr_mps, std::sqrt(2 * 0.002 * 0.002 + 2 * bed * bed), 1e-12);
  EXPECT_FALSE(d.drifted);  // 0.020 against 1.96 * 0.027
  test.bed_sd_rel = 0;
  const DriftDecision unknown = DecideDrift(test);
  EXPECT_FALSE(unknown.compared);
  EXPECT_EQ(unknown.not_compared, "other beds, their scatter is not known");
  test.tolerance_mps = 0.015;  // a campaign's tolerance is all such a pair can be held to
  const DriftDecision held = DecideDrift(test);
  EXPECT_TRUE(held.compared);
  EXPECT_FALSE(held.tested);
  EXPECT_TRUE(held.drifted);
  test.tolerance_mps = 0;
  // On the same bed the same change is far beyond the runs' errors.
  test.beds[0].same_bed = true;
  EXPECT_TRUE(DecideDrift(test).drifted);
}

// A campaign's tolerance is a size a change must also reach; without errors it is all there is,
// and without either nothing is compared.
TEST(DriftTest, ACampaignsToleranceAndRatesWithoutErrors) {
  DriftTest test;
  test.beds = {Pair(0.110, 0.001, 1e7, 0.100, 0.001, 1e7)};
  test.tolerance_mps = 0.02;
  DriftDecision d = DecideDrift(test);
  EXPECT_NEAR(d.tolerance, 0.02, 1e-12);
  EXPECT_FALSE(d.drifted);  // real (p ~ 1e-12), smaller than the campaign cares about
  EXPECT_LT(d.p_value, 1e-6);
  test.tolerance_mps = 0.005;
  EXPECT_TRUE(DecideDrift(test).drifted);
  test.beds[0].uz_stderr = 0;
  d = DecideDrift(test);
  EXPECT_TRUE(d.compared);
  EXPECT_FALSE(d.tested);
  EXPECT_TRUE(d.drifted);
  test.tolerance_mps = 0;
  d = DecideDrift(test);
  EXPECT_FALSE(d.compared);
  EXPECT_EQ(d.not_compared, "no error");
  EXPECT_FALSE(DecideDrift(DriftTest{}).compared);
}

// Holm: the smallest p against alpha / m, the next against alpha / (m - 1), ..., stopping at the
// first that fails.
TEST(DriftTest, HolmStepsDown) {
  EXPECT_EQ(HolmFlags({0.01, 0.04, 0.03}, 0.05), (std::vector<bool>{true, false, false}));
  EXPECT_EQ(HolmFlags({0.01, 0.02, 0.3}, 0.05), (std::vector<bool>{true, true, false}));
  EXPECT_EQ(HolmFlags({0.03, 0.03}, 0.05), (std::vector<bool>{false, false}));
  EXPECT_EQ(HolmFlags({0.0001, 0.02}, 0.05), (std::vector<bool>{true, true}));
  EXPECT_TRUE(HolmFlags({}).empty());
}

// The text a report quotes: the measured rates' upper bounds at a design with a measurement, the
// nominal level where there is none.
TEST(DriftTest, TheFalseAlarmTextQuotesTheMeasurementOrSaysThereIsNone) {
  const std::string none = DriftAlarmText("tiny", "smoke", 2);
  EXPECT_EQ(none,
            "false alarms: not measured at this design (tiny at smoke, K = 2 beds); the rule's nominal level is 5 % "
            "per point and 5 % per campaign (any point, Holm)");
  ASSERT_NE(FindDriftAlarmRates("paper-58", "smoke", 1), nullptr);
  const std::string measured = DriftAlarmText("paper-58", "smoke", 1);
  EXPECT_EQ(measured.rfind("false alarms <= ", 0), 0u) << measured;
  EXPECT_NE(measured.find("% per point, <= "), std::string::npos) << measured;
  EXPECT_NE(measured.find("at this design (paper-58 at smoke, K = 1 bed, drift rule 2; "), std::string::npos)
      << measured;
}

}  // namespace
}  // namespace sandswim
