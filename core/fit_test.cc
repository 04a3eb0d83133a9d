// The fits recover known parameters from noisy synthetic data (fixed-seed RNG) within their
// stated errors, and ChooseFit picks the law from what the points vary.
#include "core/fit.h"

#include <cmath>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;

std::vector<double> OmegaGrid() {  // |Omega| = 10 * 2^n, n = 0..7 (paper Fig. 6)
  std::vector<double> x;
  for (int n = 0; n <= 7; ++n) x.push_back(10.0 * std::pow(2.0, n));
  return x;
}

std::vector<double> Saturating(const std::vector<double>& x, int sign, double c1, double c2, double noise,
                               std::mt19937& rng) {
  std::normal_distribution<double> gauss(0.0, noise);
  std::vector<double> y;
  for (double xi : x) y.push_back(sign * c1 * (1 - std::exp(-c2 * xi)) + gauss(rng));
  return y;
}

TEST(FitSaturationTest, RecoversC1AndC2OfBothBranchesWithinTheirErrors) {
  std::mt19937 rng(20240611);
  const std::vector<double> x = OmegaGrid();
  for (int sign : {1, -1}) {
    const double c1 = sign > 0 ? 0.020 : 0.012, c2 = sign > 0 ? 0.015 : 0.03;
    auto fit = FitSaturation(x, Saturating(x, sign, c1, c2, 4e-4, rng), sign);
    ASSERT_TRUE(fit.ok()) << fit.status().ToString();
    EXPECT_GT(fit->c1_stderr, 0);
    EXPECT_GT(fit->c2_stderr, 0);
    EXPECT_NEAR(fit->c1, c1, 3 * fit->c1_stderr);
    EXPECT_NEAR(fit->c2, c2, 3 * fit->c2_stderr);
    EXPECT_GT(fit->r2, 0.95);
    EXPECT_EQ(fit->n, 8);
    EXPECT_NEAR(SaturationModel(*fit, 1e6), sign * fit->c1, 1e-12);
  }
}

// The stated standard errors mean what they say: over many noisy data sets the truth lies within
// one standard error about two times in three.
TEST(FitSaturationTest, StandardErrorsCoverTheTruthAboutTwoTimesInThree) {
  std::mt19937 rng(7);
  const std::vector<double> x = OmegaGrid();
  int within = 0, fitted = 0;
  for (int trial = 0; trial < 300; ++trial) {
    auto fit = FitSaturation(x, Saturating(x, 1, 0.02, 0.02, 5e-4, rng), 1);
    if (!fit.ok()) continue;
    ++fitted;
    if (std::fabs(fit->c1 - 0.02) <= fit->c1_stderr) ++within;
  }
  ASSERT_GT(fitted, 290);
  double coverage = static_cast<double>(within) / fitted;
  EXPECT_GT(coverage, 0.55);
  EXPECT_LT(coverage, 0.80);
}

// The fitted law's 95 % band means what it says: over many noisy data sets the true law lies within
// it about 95 times in 100, at every |Omega| (the band narrows to 0 at Omega = 0).
TEST(FitSaturationTest, TheBandCoversTheTrueLawNineteenTimesInTwenty) {
  std::mt19937 rng(11);
  const std::vector<double> x = OmegaGrid();
  for (int sign : {1, -1}) {
    for (double at : {15.0, 60.0, 300.0, 1280.0}) {
      int within = 0, fitted = 0;
      for (int trial = 0; trial < 400; ++trial) {
        auto fit = FitSaturation(x, Saturating(x, sign, 0.02, 0.02, 5e-4, rng), sign);
        if (!fit.ok()) continue;
        ++fitted;
        const double truth = sign * 0.02 * (1 - std::exp(-0.02 * at));
        if (std::fabs(SaturationModel(*fit, at) - truth) <= SaturationBandHalfWidth(*fit, at)) ++within;
        EXPECT_EQ(SaturationBandHalfWidth(*fit, 0), 0);
      }
      ASSERT_GT(fitted, 390);
      const double coverage = static_cast<double>(within) / fitted;
      EXPECT_GT(coverage, 0.90) << "sign " << sign << " at |Omega| = " << at;
      EXPECT_LT(coverage, 0.99) << "sign " << sign << " at |Omega| = " << at;
    }
  }
}

TEST(FitThroughOriginTest, TheBandCoversTheTrueLineNineteenTimesInTwenty) {
  std::mt19937 rng(12);
  std::normal_distribution<double> gauss(0.0, 5e-4);
  std::vector<double> a;
  for (int i = 1; i <= 6; ++i) a.push_back(0.01 * i);
  int within = 0, fitted = 0;
  for (int trial = 0; trial < 400; ++trial) {
    std::vector<double> y;
    for (double ai : a) y.push_back(0.3 * ai + gauss(rng));
    auto fit = FitThroughOrigin(a, y);
    if (!fit.ok() || fit->n != 6) continue;
    ++fitted;
    if (std::fabs(fit->c3 * 0.05 - 0.3 * 0.05) <= LinearBandHalfWidth(*fit, 0.05)) ++within;
  }
  ASSERT_GT(fitted, 300);
  const double coverage = static_cast<double>(within) / fitted;
  EXPECT_GT(coverage, 0.90);
  EXPECT_LT(coverage, 0.99);
}

TEST(FitSaturationTest, RefusesTooFewPointsAndReportsAWrongSign) {
  auto few = FitSaturation({10, 20}, {0.01, 0.02}, 1);
  ASSERT_FALSE(few.ok());
  EXPECT_EQ(few.status().field(), "points");
  EXPECT_FALSE(FitSaturation({10, 20, 40}, {0.01, NAN, 0.02}, 1).ok());
  // A "sinking" branch that rises: the fit still converges, with C1 < 0.
  std::mt19937 rng(3);
  const std::vector<double> x = OmegaGrid();
  auto wrong = FitSaturation(x, Saturating(x, 1, 0.01, 0.02, 2e-4, rng), -1);
  ASSERT_TRUE(wrong.ok()) << wrong.status().ToString();
  EXPECT_LT(wrong->c1, 0);
}

TEST(FitThroughOriginTest, RecoversC3AndTheRangeBeforeAPlateau) {
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss(0.0, 2e-4);
  std::vector<double> a, y, e;
  const double c3 = -0.25;  // sinking: U_z = C3 A with C3 < 0
  for (int i = 1; i <= 10; ++i) {
    double A = 0.01 * i;
    a.push_back(A);
    y.push_back(c3 * std::min(A, 0.06) + gauss(rng));  // plateau past A = 0.06
    e.push_back(2e-4);
  }
  auto fit = FitThroughOrigin(a, y, e);
  ASSERT_TRUE(fit.ok()) << fit.status().ToString();
  EXPECT_NEAR(fit->c3, c3, 3 * fit->c3_stderr);
  EXPECT_GT(fit->c3_stderr, 0);
  EXPECT_DOUBLE_EQ(fit->a_from, 0.01);
  EXPECT_NEAR(fit->a_to, 0.06, 1e-12);  // 0.07 sits 0.0025 off the line: 12 sigma
  EXPECT_EQ(fit->n, 6);
  EXPECT_EQ(fit->n_total, 10);
  EXPECT_GT(fit->r2, 0.99);
}

TEST(FitThroughOriginTest, AWholeLineIsOneRangeAndBadInputIsRefused) {
  std::mt19937 rng(5);
  std::normal_distribution<double> gauss(0.0, 1e-4);
  std::vector<double> a, y;
  for (int i = 1; i <= 10; ++i) {
    a.push_back(0.01 * i);
    y.push_back(0.3 * a.back() + gauss(rng));
  }
  auto fit = FitThroughOrigin(a, y);
  ASSERT_TRUE(fit.ok());
  EXPECT_EQ(fit->n, 10);
  EXPECT_NEAR(fit->c3, 0.3, 3 * fit->c3_stderr);
  EXPECT_EQ(FitThroughOrigin({0.01}, {0.1}).status().field(), "points");
  EXPECT_EQ(FitThroughOrigin({0, 0}, {0.1, 0.2}).status().field(), "points");
}

TEST(FitFastestRiseTest, FindsTheVertexWithinItsError) {
  std::mt19937 rng(42);
  std::normal_distribution<double> gauss(0.0, 1e-4);
  const std::vector<double> f = {1, 2, 3, 4, 5, 6, 8, 10, 20, 30};
  std::vector<double> y, e;
  for (double fi : f) {
    y.push_back(0.02 - 0.002 * (fi - 5.3) * (fi - 5.3) + gauss(rng));
    e.push_back(1e-4);
  }
  auto rise = FitFastestRise(f, y, e);
  ASSERT_TRUE(rise.ok()) << rise.status().ToString();
  EXPECT_FALSE(rise->at_edge);
  EXPECT_GT(rise->f_c_stderr, 0);
  EXPECT_NEAR(rise->f_c, 5.3, 3 * rise->f_c_stderr);
  EXPECT_LE(rise->interval_lo, rise->f_c);
  EXPECT_GE(rise->interval_hi, rise->f_c);
  EXPECT_GE(rise->interval_lo, 4);
  EXPECT_LE(rise->interval_hi, 6);
  EXPECT_NEAR(rise->uz_max, 0.02, 5e-4);
}

TEST(FitFastestRiseTest, AMaximumAtTheEdgeIsSaidSo) {
  auto rise = FitFastestRise({1, 2, 3, 4}, {0.01, 0.02, 0.03, 0.04});
  ASSERT_TRUE(rise.ok());
  EXPECT_TRUE(rise->at_edge);
  EXPECT_EQ(rise->f_c, 4);
  EXPECT_EQ(rise->interval_lo, 3);
  EXPECT_EQ(rise->interval_hi, 4);
  EXPECT_FALSE(FitFastestRise({1, 1, 2}, {0.1, 0.2, 0.3}).ok());  // 2 distinct f
}

std::vector<SweepSample> Samples(const std::vector<double>& omegas, double A, double f) {
  std::vector<SweepSample> s;
  for (double om : omegas) s.push_back({OscillatoryPoint(A, f, om, 4), 0, 0});
  return s;
}

std::vector<Point> PointsOf(const std::vector<SweepSample>& s) {
  std::vector<Point> p;
  for (const auto& x : s) p.push_back(x.point);
  return p;
}

TEST(ChooseFitTest, TheLawFollowsWhatTheSweepVaries) {
  EXPECT_EQ(ChooseFit(PointsOf(Samples({-10, -20, -40, 10, 20, 40}, 0.03, 3))).kind, FitKind::kSaturation);
  EXPECT_EQ(ChooseFit(PointsOf(Samples({-10, -20, -40}, 0.03, 3))).param, "Omega");
  std::vector<Point> a_sweep, f_sweep, both;
  for (double A : {0.01, 0.02, 0.03}) {
    for (double om : {-80.0, 80.0}) a_sweep.push_back(OscillatoryPoint(A, 3, om, 4));
  }
  for (double f : {1.0, 2.0, 3.0}) f_sweep.push_back(OscillatoryPoint(0.03, f, -80, 4));
  both = a_sweep;
  both.push_back(OscillatoryPoint(0.03, 5, 80, 4));
  EXPECT_EQ(ChooseFit(a_sweep).kind, FitKind::kLinear);
  EXPECT_EQ(ChooseFit(f_sweep).kind, FitKind::kFastestRise);
  FitChoice none = ChooseFit(both);
  EXPECT_EQ(none.kind, FitKind::kNone);
  EXPECT_THAT(none.reason, HasSubstr("more than one"));
  // The baseline: only the sign of Omega varies.
  EXPECT_EQ(ChooseFit(PointsOf(Samples({-80, 80}, 0.03, 3))).kind, FitKind::kNone);
  // Other modes: none.
  Point vib;
  vib.mode = Mode::kVibration;
  vib.A = 0.03;
  vib.f = 3;
  vib.duration_s = 4;
  Point vib2 = vib;
  vib2.A = 0.05;
  EXPECT_THAT(ChooseFit({vib, vib2}).reason, HasSubstr("oscillatory"));
  // A material: no law, but the x axis; with a drive parameter beside it, none.
  std::vector<Point> density;
  for (double rho : {1250.0, 2500.0, 5000.0}) {
    for (double om : {-80.0, 80.0}) {
      density.push_back(OscillatoryPoint(0.03, 3, om, 4));
      density.back().materials.rho_so = rho;
    }
  }
  FitChoice by_density = ChooseFit(density);
  EXPECT_EQ(by_density.kind, FitKind::kNone);
  EXPECT_EQ(by_density.param, "so_density");
  EXPECT_THAT(by_density.reason, HasSubstr("no law"));
  density.push_back(OscillatoryPoint(0.05, 3, 80, 4));
  EXPECT_EQ(ChooseFit(density).param, "");
  EXPECT_THAT(ChooseFit(density).reason, HasSubstr("more than one"));
}

TEST(FitSweepTest, FitsEachBranchOfAnOmegaSweepAndChecksTheSigns) {
  std::mt19937 rng(99);
  const std::vector<double> x = OmegaGrid();
  std::vector<double> up = Saturating(x, 1, 0.02, 0.02, 3e-4, rng);
  std::vector<double> down = Saturating(x, -1, 0.01, 0.03, 3e-4, rng);
  std::vector<SweepSample> samples;
  for (size_t i = 0; i < x.size(); ++i) {
    samples.push_back({OscillatoryPoint(0.03, 3, -x[i], 4), up[i], 1e-4});
    samples.push_back({OscillatoryPoint(0.03, 3, x[i], 4), down[i], 1e-4});
  }
  SweepFits fits = FitSweep(samples);
  EXPECT_EQ(fits.choice.kind, FitKind::kSaturation);
  ASSERT_EQ(fits.branches.size(), 2u);
  EXPECT_EQ(fits.branches[0].branch, "rising");
  EXPECT_EQ(fits.branches[1].branch, "sinking");
  // The JSON says each branch's side of Omega = 0 (the dashboard draws the fit there).
  EXPECT_EQ(nlohmann::json(fits.branches[0])["omega_sign"], -1);
  EXPECT_EQ(nlohmann::json(fits.branches[1])["omega_sign"], 1);
  for (const BranchFit& b : fits.branches) {
    ASSERT_TRUE(b.saturation.has_value()) << b.error;
    EXPECT_EQ(b.points, 8);
    EXPECT_EQ(b.sign_matches_paper, true);
  }
  EXPECT_NEAR(fits.branches[0].saturation->c1, 0.02, 3 * fits.branches[0].saturation->c1_stderr);
  EXPECT_NEAR(fits.branches[1].saturation->c2, 0.03, 3 * fits.branches[1].saturation->c2_stderr);
  nlohmann::json j = fits;
  EXPECT_EQ(j["kind"], "saturation");
  EXPECT_EQ(j["branches"][1]["saturation"]["sign"], -1);
  EXPECT_TRUE(j["branches"][0]["saturation"].contains("C2_stderr"));
}

TEST(FitSweepTest, ABranchTooSmallToFitSaysWhy) {
  std::vector<SweepSample> samples = {{OscillatoryPoint(0.03, 3, -10, 4), 0.01, 0},
                                      {OscillatoryPoint(0.03, 3, -20, 4), 0.015, 0}};
  SweepFits fits = FitSweep(samples);
  ASSERT_EQ(fits.branches.size(), 1u);
  EXPECT_FALSE(fits.branches[0].saturation.has_value());
  EXPECT_THAT(fits.branches[0].error, HasSubstr("at least 3 points"));
  EXPECT_FALSE(fits.branches[0].sign_matches_paper.has_value());
}

// Points with their own errors (some ten times others) are weighted by them: over many noisy
// draws the stated standard error of C1 covers the truth about two times in three, and a point with
// no error turns weighting off.
TEST(FitSaturationTest, WeightsByThePointsErrors) {
  std::mt19937 rng(7);
  const std::vector<double> x = OmegaGrid();
  std::vector<double> e;
  for (size_t i = 0; i < x.size(); ++i) e.push_back(i % 2 ? 2e-3 : 2e-4);
  int within = 0, trials = 300;
  for (int trial = 0; trial < trials; ++trial) {
    std::vector<double> y;
    for (size_t i = 0; i < x.size(); ++i) {
      std::normal_distribution<double> gauss(0.0, e[i]);
      y.push_back(0.02 * (1 - std::exp(-0.02 * x[i])) + gauss(rng));
    }
    auto fit = FitSaturation(x, y, 1, e);
    ASSERT_TRUE(fit.ok()) << fit.status().ToString();
    ASSERT_TRUE(fit->weighted);
    if (std::fabs(fit->c1 - 0.02) <= fit->c1_stderr) ++within;
  }
  EXPECT_GT(within, 0.55 * trials);
  EXPECT_LT(within, 0.85 * trials);
  std::vector<double> y = Saturating(x, 1, 0.02, 0.02, 2e-4, rng);
  e[3] = 0;
  auto unweighted = FitSaturation(x, y, 1, e);
  ASSERT_TRUE(unweighted.ok());
  EXPECT_FALSE(unweighted->weighted);
  auto linear = FitThroughOrigin({0.01, 0.02, 0.03}, {0.011, 0.019, 0.031}, {1e-3, 1e-3, 1e-3});
  ASSERT_TRUE(linear.ok());
  EXPECT_TRUE(linear->weighted);
  EXPECT_FALSE(FitThroughOrigin({0.01, 0.02, 0.03}, {0.011, 0.019, 0.031})->weighted);
}

// Inconclusive runs never reach a fit: they are listed as left out, with their reason.
TEST(FitSweepTest, LeavesOutInconclusiveRunsAndListsThem) {
  std::mt19937 rng(3);
  const std::vector<double> x = OmegaGrid();
  std::vector<double> up = Saturating(x, 1, 0.02, 0.02, 3e-4, rng);
  std::vector<SweepSample> samples;
  for (size_t i = 0; i < x.size(); ++i) {
    SweepSample s{OscillatoryPoint(0.03, 3, -x[i], 4), up[i], 3e-4};
    s.run_id = static_cast<int64_t>(i + 1);
    samples.push_back(s);
  }
  samples[7].uz = -5;  // would wreck the fit
  samples[7].conclusive = false;
  samples[7].inconclusive_reason = "the steady window holds 1 whole period";
  SweepFits fits = FitSweep(samples);
  ASSERT_EQ(fits.branches.size(), 1u);
  EXPECT_EQ(fits.branches[0].points, 7);
  ASSERT_TRUE(fits.branches[0].saturation.has_value());
  EXPECT_NEAR(fits.branches[0].saturation->c1, 0.02, 3 * fits.branches[0].saturation->c1_stderr);
  ASSERT_EQ(fits.left_out.size(), 1u);
  EXPECT_EQ(fits.left_out[0].run_id, 8);
  nlohmann::json j = fits;
  EXPECT_EQ(j["left_out"][0]["reason"], "the steady window holds 1 whole period");
  EXPECT_EQ(j["branches"][0]["saturation"]["weighted"], true);
}

}  // namespace
}  // namespace sandswim
