// The `converges` rule (core/convergence.h) on synthetic pairs whose answer is known: equal U_z
// at both steps is equivalent, a bias past the margin differs, too few or too noisy runs are
// inconclusive, a run missing at either step keeps the point missing.
#include "core/convergence.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/sweep.h"

namespace sandswim {
namespace {

using ::testing::HasSubstr;

ClaimRun Run(int64_t id, const Point& p, int replicate, double uz, double se, double osc = 0.004) {
  ClaimRun r;
  r.run_id = id;
  r.point = p;
  r.replicate = replicate;
  r.state = JobState::kDone;
  api::RunResult res;
  res.uz = uz;
  res.uz_stderr = se;
  res.uz_ci95 = 2.776 * se;  // 4 dof
  res.uz_blocks = 5;
  res.conclusive = true;
  res.stop_reason = "duration";
  res.z_osc_amplitude = osc;
  r.result = res;
  return r;
}

Claim Rule() {
  Claim c;
  c.id = "DT";
  c.rule = {{"kind", "converges"}, {"reference", {"ref"}}, {"sweeps", {"coarse"}}};
  return c;
}

// Reference and coarse sweeps of the baseline pair on `beds` beds: the coarse step's U_z is the
// reference's plus `bias`, each bed's value moved by its packing (`bed_shift`), which pairs cancel.
ClaimInput Pairs(double bias, int beds, double se, double dt = 5e-5) {
  ClaimInput in;
  in.scale = "smoke";
  ClaimSweep ref, coarse;
  ref.name = "ref";
  coarse.name = "coarse";
  int64_t id = 1;
  for (double Omega : {-80.0, 80.0}) {
    const double u = Omega < 0 ? 0.10 : -0.05;
    Point a = OscillatoryPoint(0.03, 3, Omega, 4), b = a;
    b.dt_s = dt;
    for (int k = 0; k < beds; ++k) {
      const double bed_shift = 0.01 * (k - 1);
      const double wiggle = se * 0.3 * ((k % 2) ? 1 : -1);
      ref.runs.push_back(Run(id++, a, k, u + bed_shift, se));
      coarse.runs.push_back(Run(id++, b, k, u + bed_shift + bias + wiggle, se));
    }
  }
  in.sweeps = {ref, coarse};
  return in;
}

ClaimVerdict Evaluate(const ClaimInput& in) {
  Claim c = Rule();
  return EvaluateClaims({c}, in).front();
}

TEST(ConvergenceTest, EqualRatesPairedByBedAreEquivalent) {
  const ClaimVerdict v = Evaluate(Pairs(0, 3, 0.002));
  EXPECT_EQ(v.verdict, Verdict::kHolds) << v.reason;
  ASSERT_EQ(v.parts.size(), 1u);
  EXPECT_EQ(v.parts[0].name, "dt = 5e-05 s (coarse)");
  EXPECT_THAT(v.reason, HasSubstr("converged up to dt = 5e-05 s"));
  ASSERT_EQ(v.parts[0].figures.size(), 2u);
  EXPECT_THAT(v.parts[0].figures[0].note, HasSubstr("3 bed(s) paired"));
  EXPECT_THAT(v.parts[0].figures[0].note, HasSubstr("z amplitude at f 4 mm"));
}

TEST(ConvergenceTest, ABiasPastTheMarginDiffers) {
  // Margin at the rising point: 10 % of 0.10 = 0.010 m/s; a 0.03 m/s bias is well past it.
  const ClaimVerdict v = Evaluate(Pairs(0.03, 3, 0.002));
  EXPECT_EQ(v.verdict, Verdict::kDiffers) << v.reason;
  EXPECT_THAT(v.reason, HasSubstr("no longer step shown equivalent"));
}

TEST(ConvergenceTest, NoisyRunsAreInconclusiveNeverEquivalent) {
  const ClaimVerdict v = Evaluate(Pairs(0, 1, 0.02));
  EXPECT_EQ(v.verdict, Verdict::kInconclusive) << v.reason;
}

TEST(ConvergenceTest, ARunMissingAtEitherStepKeepsThePointMissing) {
  ClaimInput in = Pairs(0, 3, 0.002);
  in.sweeps[0].runs[1].state = JobState::kFailed;
  in.sweeps[0].runs[1].result.reset();
  const ClaimVerdict v = Evaluate(in);
  EXPECT_EQ(v.verdict, Verdict::kInconclusive);
  ASSERT_EQ(v.missing.size(), 1u);
  EXPECT_THAT(v.missing[0].why, HasSubstr("failed"));
}

TEST(ConvergenceTest, TheCampaignsRuleParses) {
  auto c = BuiltinCampaign("dt-convergence");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  ASSERT_EQ(c->claims.size(), 1u);
  EXPECT_EQ(c->claims[0].kind(), "converges");
  EXPECT_EQ(c->claims[0].rule["margin_rel"], 0.1);
  nlohmann::json bad = BuiltinCampaignDefinition("dt-convergence").value();
  bad["claims"][0]["rule"]["margin_rel"] = 1.5;
  EXPECT_EQ(ParseCampaign(bad).status().field(), "claims[0].rule.margin_rel");
}

}  // namespace
}  // namespace sandswim
