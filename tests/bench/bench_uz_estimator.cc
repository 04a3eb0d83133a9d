// bench_uz_estimator: why U_z is the mean of whole-period block rates (core/trajectory.h).
//
//   bench_uz_estimator [--seeds N]
//
// On synthetic trajectories with a known drift, harmonics at f, 2f, 3f (2f dominating) and
// correlated noise (tests/synthetic_trajectory.h), over windows of 2, 4 and 10 periods after a
// one-period transient, compares three estimators of the drift:
//   line+f     least squares z = c0 + U t + sinusoid at f, error from the fit's residuals (the
//              estimator of analysis version 1)
//   line+3h    least squares with harmonics f, 2f, 3f, error from the fit's residuals
//   blocks     the mean of once-per-period block rates, error from their scatter (analysis 2)
// and prints, per estimator: the bias (mean error, % of the drift), the rms error, the ratio of
// the stated standard error to the actual scatter of the estimates, and the coverage of the
// stated 95 % interval (Student t with the estimator's degrees of freedom).
// Two noise models: "jitter" (stationary AR(1) in z, lag-1 autocorrelation 0.99 per 1 ms sample)
// and "wander" (AR(1) noise in the velocity, integrated: each period's advance varies).
// A program to run on demand: it asserts nothing.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "core/trajectory.h"
#include "tests/synthetic_trajectory.h"

namespace sandswim {
namespace {

constexpr double kPi = 3.14159265358979323846;

struct Estimate {
  double u = 0, se = 0;
  int dof = 0;
  bool ok = false;
};

// Ordinary least squares of z on [1, t, sin/cos(2 pi h f t) for h = 1..harmonics] over
// [t0, t1]; the slope and its textbook standard error.
Estimate RegressionSlope(const std::vector<SoSample>& s, double t0, double t1, double f, int harmonics) {
  const int k = 2 + 2 * harmonics;
  std::vector<std::vector<double>> m(k, std::vector<double>(2 * k, 0.0));
  std::vector<double> rhs(k, 0.0);
  std::vector<double> x(k);
  int n = 0;
  auto basis = [&](double t) {
    x[0] = 1;
    x[1] = t - t0;
    for (int h = 1; h <= harmonics; ++h) {
      x[2 * h] = std::sin(2 * kPi * h * f * t);
      x[2 * h + 1] = std::cos(2 * kPi * h * f * t);
    }
  };
  for (const SoSample& p : s) {
    if (p.t < t0 - 1e-9 || p.t > t1 + 1e-9) continue;
    basis(p.t);
    ++n;
    for (int a = 0; a < k; ++a) {
      rhs[a] += x[a] * p.z;
      for (int b = 0; b < k; ++b) m[a][b] += x[a] * x[b];
    }
  }
  for (int a = 0; a < k; ++a) m[a][k + a] = 1;
  for (int c = 0; c < k; ++c) {
    int p = c;
    for (int r = c + 1; r < k; ++r)
      if (std::fabs(m[r][c]) > std::fabs(m[p][c])) p = r;
    if (std::fabs(m[p][c]) < 1e-14) return {};
    std::swap(m[c], m[p]);
    double d = m[c][c];
    for (double& v : m[c]) v /= d;
    for (int r = 0; r < k; ++r) {
      if (r == c) continue;
      double q = m[r][c];
      for (int j = 0; j < 2 * k; ++j) m[r][j] -= q * m[c][j];
    }
  }
  std::vector<double> coef(k, 0.0);
  for (int a = 0; a < k; ++a)
    for (int b = 0; b < k; ++b) coef[a] += m[a][k + b] * rhs[b];
  double ssr = 0;
  for (const SoSample& p : s) {
    if (p.t < t0 - 1e-9 || p.t > t1 + 1e-9) continue;
    basis(p.t);
    double r = p.z;
    for (int a = 0; a < k; ++a) r -= coef[a] * x[a];
    ssr += r * r;
  }
  Estimate e;
  e.u = coef[1];
  e.dof = n - k;
  e.se = std::sqrt(ssr / e.dof * m[1][k + 1]);
  e.ok = true;
  return e;
}

struct Tally {
  double sum_err = 0, sum_err2 = 0, sum_se = 0;
  int covered = 0, n = 0, with_interval = 0;
  void Add(const Estimate& e, double truth) {
    double err = e.u - truth;
    sum_err += err;
    sum_err2 += err * err;
    ++n;
    if (e.se > 0 && e.dof >= 1) {
      sum_se += e.se;
      ++with_interval;
      if (std::fabs(err) <= StudentT95(e.dof) * e.se) ++covered;
    }
  }
  void Print(const char* name, double truth) const {
    double bias = sum_err / n, rms = std::sqrt(sum_err2 / n);
    double sd = std::sqrt(std::max(0.0, sum_err2 / n - bias * bias));
    if (with_interval == 0) {
      std::printf("    %-8s bias %+6.1f %%  rms %5.1f %%  (no error: too few periods)\n", name, 100 * bias / truth,
                  100 * rms / truth);
      return;
    }
    std::printf("    %-8s bias %+6.1f %%  rms %5.1f %%  stated/actual error %5.2f  95 %% coverage %5.1f %%\n", name,
                100 * bias / truth, 100 * rms / truth, sum_se / with_interval / sd, 100.0 * covered / with_interval);
  }
};

}  // namespace
}  // namespace sandswim

int main(int argc, char** argv) {
  using namespace sandswim;
  int seeds = 1000;
  for (int i = 1; i + 1 < argc; ++i)
    if (std::strcmp(argv[i], "--seeds") == 0) seeds = std::atoi(argv[i + 1]);
  struct Model {
    const char* name;
    testing::SyntheticSo so;
  };
  std::vector<Model> models(2);
  models[0].name = "jitter (stationary AR(1) in z, sd 1 mm, phi 0.99 per ms)";
  models[0].so.z_noise_sd = 0.001;
  // As measured on real 3 s smoke runs: each period's advance varies by ~2 mm, and consecutive
  // period rates are nearly uncorrelated (the model of core/trajectory_test.cc).
  models[1].name = "wander (integrated AR(1) velocity noise, sd 8 mm/s, phi 0.99 per ms, + 0.5 mm jitter)";
  models[1].so.z_noise_sd = 0.0005;
  models[1].so.v_noise_sd = 0.008;
  std::printf(
      "drift 0.05 m/s, f = 3 Hz, harmonics 2 / 6 / 1.5 mm at f / 2f / 3f (fixed phases, as a drive "
      "fixes them), %d seeds\n",
      seeds);
  for (Model& m : models) {
    std::printf("\n%s\n", m.name);
    for (int periods : {1, 2, 4, 10}) {
      testing::SyntheticSo so = m.so;
      const double T = 1 / so.f;
      so.duration = (periods + 1) * T + 1e-3;  // the run ends on the step after the last period
      Tally line_f, line_3h, blocks;
      for (int seed = 1; seed <= seeds; ++seed) {
        auto s = testing::MakeSyntheticSo(so, static_cast<uint64_t>(seed));
        line_f.Add(RegressionSlope(s, T, so.duration, so.f, 1), so.drift);
        line_3h.Add(RegressionSlope(s, T, so.duration, so.f, 3), so.drift);
        BlockRate b = MeanBlockRate(s, T, T, periods);
        Estimate e;
        e.u = b.rate;
        e.se = b.se.value_or(0);
        e.dof = periods - 1;
        blocks.Add(e, so.drift);
      }
      std::printf("  %d periods\n", periods);
      line_f.Print("line+f", so.drift);
      line_3h.Print("line+3h", so.drift);
      blocks.Print("blocks", so.drift);
    }
  }
  return 0;
}
