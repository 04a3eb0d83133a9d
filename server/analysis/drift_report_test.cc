// Drift reports: what a change is held to (a campaign's tolerance, else the errors of the two
// estimates), points compared over their replicate beds, and rates of different analyses never
// compared. The scheduler's tests (server/jobs/scheduler_test.cc) run drift reports end to end.
#include "server/analysis/drift_report.h"

#include <optional>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/drift.h"

namespace sandswim {
namespace {

// Without a campaign tolerance, a change is held to the 95 % bound of the difference of two
// estimates (t sqrt(se^2 + se_before^2), core/drift.h); each point is compared over its replicate
// beds too, each bed with itself.
TEST(DriftReportTest, ADerivedToleranceComesFromTheErrorsAndPointsAggregateTheirBeds) {
  const nlohmann::json point = {{"mode", "oscillatory"}, {"Omega", -80}};
  auto run = [&](int replicate, double uz, std::optional<double> se) {
    DriftPoint p;
    p.point = point;
    p.replicate = replicate;
    p.run_id = 10 + replicate;
    p.bed_id = 100 + replicate;  // the same beds both nights
    p.state = JobState::kDone;
    p.uz = uz;
    p.uz_stderr = se;
    p.analysis = api::kAnalysisVersion;
    return p;
  };
  DriftReport previous;
  previous.campaign_run_id = 1;
  previous.rows = {run(0, 0.100, 0.003), run(1, 0.120, 0.003), run(2, 0.110, 0.003)};
  DriftReport now;
  now.campaign = "tiny";
  now.scale = "smoke";
  now.trigger = "manual";
  now.campaign_run_id = 2;
  now.tolerance_mps = 0;  // derived
  // Bed 0 moved by 0.005 (within 1.96 sqrt(2) 0.003 = 0.0083), bed 1 by 0.010 (beyond), bed 2 has
  // no error now: not compared.
  now.rows = {run(0, 0.105, 0.003), run(1, 0.130, 0.003), run(2, 0.140, std::nullopt)};
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  ASSERT_TRUE(now.rows[0].tolerance.has_value());
  EXPECT_NEAR(*now.rows[0].tolerance, 1.96 * std::sqrt(2.0) * 0.003, 1e-6);  // no dof stated: normal
  EXPECT_FALSE(now.rows[0].drifted);
  EXPECT_TRUE(now.rows[1].drifted);
  EXPECT_TRUE(now.rows[2].no_error);
  EXPECT_EQ(now.compared, 2);
  EXPECT_EQ(now.drifted, 1);
  EXPECT_EQ(now.no_error, 1);
  EXPECT_NE(now.summary.find("1 drifted beyond its 95 % bound"), std::string::npos) << now.summary;
  EXPECT_NE(now.summary.find(", 1 not compared (no error)"), std::string::npos) << now.summary;
  // The point over its beds (core/drift.h rule 2): beds 0 and 1 have errors on both nights, each
  // compared with itself: a mean change of 0.0075 against sqrt(4 0.003^2) / 2 = 0.003, beyond
  // 1.96 0.003 (the runs state no dof: normal). The means over the beds are shown beside it.
  ASSERT_EQ(now.aggregates.size(), 1u);
  const DriftAggregate& a = now.aggregates[0];
  EXPECT_EQ(a.replicates, 3);
  EXPECT_EQ(a.replicates_previous, 3);
  EXPECT_NEAR(*a.uz_mean, 0.125, 1e-12);
  EXPECT_NEAR(*a.uz_mean_previous, 0.110, 1e-12);
  EXPECT_EQ(a.beds_compared, 2);
  EXPECT_NEAR(*a.difference, 0.0075, 1e-12);
  EXPECT_NEAR(*a.tolerance, 1.96 * 0.003, 1e-4);
  EXPECT_TRUE(a.drifted);
  ASSERT_TRUE(a.p_value.has_value());
  EXPECT_NEAR(*a.p_value, 0.0124, 1e-4);
  EXPECT_TRUE(a.drifted_familywise);  // the campaign's one point: Holm at 0.05
  EXPECT_TRUE(now.campaign_drifted);
  EXPECT_EQ(now.rule, kDriftRuleVersion);
  EXPECT_EQ(now.points_compared, 1);
  EXPECT_NE(now.summary.find("; 1 of 1 points' means over their beds drifted; the campaign drifted: 1 point(s) at "
                             "family-wise 5 % (Holm)"),
            std::string::npos)
      << now.summary;
  EXPECT_EQ(now.false_alarms.rfind("false alarms: not measured at this design (tiny at smoke, K = 3 beds)", 0), 0u)
      << now.false_alarms;
  // A campaign tolerance is a size a change must also reach, for runs and points alike; a rate
  // without an error is held to it alone (bed 2: 0.030; the point: the mean change over its three
  // beds, 0.015).
  now.tolerance_mps = 0.012;
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_EQ(now.drifted, 1);  // bed 2's 0.030; bed 1's 0.010 is within
  EXPECT_TRUE(now.rows[2].drifted);
  EXPECT_TRUE(now.aggregates[0].drifted);
  // Round trip through the stored JSON.
  DriftReport back = nlohmann::json(now).get<DriftReport>();
  ASSERT_EQ(back.aggregates.size(), 1u);
  EXPECT_EQ(back.aggregates[0].difference, now.aggregates[0].difference);
  EXPECT_EQ(back.rows[1].replicate, 1);
  EXPECT_EQ(back.rule, kDriftRuleVersion);
  EXPECT_EQ(back.aggregates[0].beds_compared, 3);
  // A report stored before rules were numbered reads as rule 1.
  nlohmann::json old = now;
  old.erase("rule");
  EXPECT_EQ(old.get<DriftReport>().rule, 1);

  // A previous report that does not know its beds (stored before bed ids were kept): the beds may
  // have been re-poured, so each pair gets the scale's bed-to-bed prior (smoke's) and bed 1's 0.010
  // is no longer beyond chance; the committed false-alarm rates (same beds) are not quoted for it.
  now.tolerance_mps = 0;
  for (DriftPoint& p : previous.rows) p.bed_id = 0;
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_FALSE(now.rows[1].drifted);
  EXPECT_GT(*now.rows[1].tolerance, 1.96 * std::sqrt(2.0) * 0.003);
  // paper-58 at smoke has committed rates, measured on the same beds: not for this pair.
  EXPECT_EQ(DriftAlarmText("paper-58", "smoke", 1).rfind("false alarms <= ", 0), 0u);
  EXPECT_NE(DriftAlarmText("paper-58", "smoke", 1, false).find("not measured at this design"), std::string::npos);
}

// After an upgrade of the U_z analysis, the first report compares no rate with one the old
// analysis made (a stored report without the field was made by analysis 1), however far it moved.
TEST(DriftReportTest, RatesOfDifferentAnalysesAreNotCompared) {
  const nlohmann::json point = {{"mode", "oscillatory"}, {"Omega", 80}};
  DriftPoint old_row =
      nlohmann::json{{"point", point}, {"run_id", 1}, {"state", "done"}, {"uz", 0.010}}.get<DriftPoint>();
  EXPECT_EQ(old_row.analysis, 1);
  DriftReport previous;
  previous.campaign_run_id = 1;
  previous.rows = {old_row};
  DriftReport now;
  now.campaign = "tiny";
  now.scale = "smoke";
  now.trigger = "manual";
  now.campaign_run_id = 2;
  now.tolerance_mps = 0.005;
  DriftPoint p;
  p.point = point;
  p.run_id = 2;
  p.state = JobState::kDone;
  p.uz = 0.090;
  p.analysis = api::kAnalysisVersion;
  now.rows = {p};
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_EQ(now.compared, 0);
  EXPECT_EQ(now.drifted, 0);
  EXPECT_EQ(now.estimator_changed, 1);
  EXPECT_TRUE(now.rows[0].estimator_changed);
  EXPECT_FALSE(now.rows[0].difference.has_value());
  EXPECT_NE(now.summary.find(", 1 not compared (U_z analysis changed)"), std::string::npos) << now.summary;
  // The same analysis on both sides is compared.
  previous.rows[0].analysis = api::kAnalysisVersion;
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_EQ(now.compared, 1);
  EXPECT_EQ(now.drifted, 1);
  EXPECT_EQ(now.estimator_changed, 0);
  // Round trip through the stored JSON.
  DriftReport back = nlohmann::json(now).get<DriftReport>();
  EXPECT_EQ(back.rows[0].analysis, api::kAnalysisVersion);
}

// A point's mean over its beds is compared only when it shares its estimator with the earlier one:
// one analysis made every rate, or each bed's rate was made by the same analysis on both sides. One
// bed's rate re-made by a newer analysis keeps the point out of the comparison, while its runs of
// one analysis are still compared one by one.
TEST(DriftReportTest, PointMeansMixingAnalysesAreNotCompared) {
  const nlohmann::json point = {{"mode", "oscillatory"}, {"Omega", 80}};
  auto run = [&](int replicate, double uz, int analysis) {
    DriftPoint p;
    p.point = point;
    p.replicate = replicate;
    p.run_id = 10 + replicate;
    p.state = JobState::kDone;
    p.uz = uz;
    p.uz_stderr = 0.001;
    p.analysis = analysis;
    return p;
  };
  const int v = api::kAnalysisVersion;
  DriftReport previous;
  previous.campaign_run_id = 1;
  previous.rows = {run(0, 0.010, v), run(1, 0.012, v - 1)};
  DriftReport now;
  now.campaign = "tiny";
  now.scale = "smoke";
  now.trigger = "manual";
  now.campaign_run_id = 2;
  now.rows = {run(0, 0.050, v), run(1, 0.052, v)};
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_EQ(now.compared, 1);  // bed 0, the same analysis on both sides
  EXPECT_EQ(now.estimator_changed, 1);
  ASSERT_EQ(now.aggregates.size(), 1u);
  EXPECT_TRUE(now.aggregates[0].estimator_changed);
  EXPECT_FALSE(now.aggregates[0].difference.has_value());
  EXPECT_FALSE(now.aggregates[0].drifted);
  EXPECT_EQ(now.points_compared, 0);
  // One analysis throughout: compared, and a 0.04 m/s jump against errors of 0.001 drifted.
  previous.rows[1].analysis = v;
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_FALSE(now.aggregates[0].estimator_changed);
  EXPECT_TRUE(now.aggregates[0].drifted);
  EXPECT_EQ(now.points_compared, 1);
  // Mixed within this report, bed 1 by another analysis than before: not compared.
  now.rows[1].analysis = v - 1;
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_TRUE(now.aggregates[0].estimator_changed);
  EXPECT_EQ(now.points_compared, 0);
  EXPECT_TRUE(nlohmann::json(now).get<DriftReport>().aggregates[0].estimator_changed);
  // Mixed the same way on both sides (bed 1 by the older analysis both times): compared.
  previous.rows[1].analysis = v - 1;
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_FALSE(now.aggregates[0].estimator_changed);
  EXPECT_TRUE(now.aggregates[0].drifted);
  EXPECT_EQ(now.points_compared, 1);
  // Different beds on each side, of different analyses: not compared.
  now.rows[1].inconclusive = true;       // now: bed 0 by v; before: beds 0 (v) and 1 (v - 1)
  previous.rows[0].inconclusive = true;  // before: bed 1 by v - 1 alone
  CompareWithPrevious(now, &previous, CronZone::kUtc);
  EXPECT_TRUE(now.aggregates[0].estimator_changed);
  EXPECT_EQ(now.points_compared, 0);
}

}  // namespace
}  // namespace sandswim
