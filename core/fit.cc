#include "core/fit.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <numeric>
#include <set>

#include <gsl/gsl_blas.h>
#include <gsl/gsl_cdf.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_fit.h>
#include <gsl/gsl_matrix.h>
#include <gsl/gsl_multifit.h>
#include <gsl/gsl_multifit_nlinear.h>
#include <gsl/gsl_vector.h>

#include "core/branch.h"
#include "core/sweep.h"
#include "core/trajectory.h"

namespace sandswim {
namespace {

// GSL's default handler aborts the process on any error; a fit that fails must be a Status.
void QuietGsl() {
  static std::once_flag once;
  std::call_once(once, [] { gsl_set_error_handler_off(); });
}

bool AllFinite(const std::vector<double>& v) {
  return std::all_of(v.begin(), v.end(), [](double d) { return std::isfinite(d); });
}

// Every one of the n points has an error > 0 (then fits are weighted by them).
bool HasAllErrors(const std::vector<double>& e, size_t n) {
  return e.size() == n && n > 0 && std::all_of(e.begin(), e.end(), [](double v) { return v > 0; });
}

// R^2 = 1 - SSR / SST, SST about the mean; 1 when SST is 0 and the fit is exact.
double RSquared(const std::vector<double>& y, const std::vector<double>& predicted) {
  double mean = std::accumulate(y.begin(), y.end(), 0.0) / static_cast<double>(y.size());
  double ssr = 0, sst = 0;
  for (size_t i = 0; i < y.size(); ++i) {
    ssr += (y[i] - predicted[i]) * (y[i] - predicted[i]);
    sst += (y[i] - mean) * (y[i] - mean);
  }
  if (sst == 0) return ssr == 0 ? 1.0 : 0.0;
  return 1.0 - ssr / sst;
}

// ---- eq. 8 -------------------------------------------------------------------------------------

struct SaturationData {
  const std::vector<double>* x;
  const std::vector<double>* y;
  double sign;
};

int SaturationResidual(const gsl_vector* p, void* data, gsl_vector* r) {
  auto* d = static_cast<SaturationData*>(data);
  double c1 = gsl_vector_get(p, 0), c2 = gsl_vector_get(p, 1);
  for (size_t i = 0; i < d->x->size(); ++i) {
    double model = d->sign * c1 * (1.0 - std::exp(-c2 * (*d->x)[i]));
    gsl_vector_set(r, i, model - (*d->y)[i]);
  }
  return GSL_SUCCESS;
}

int SaturationJacobian(const gsl_vector* p, void* data, gsl_matrix* jac) {
  auto* d = static_cast<SaturationData*>(data);
  double c1 = gsl_vector_get(p, 0), c2 = gsl_vector_get(p, 1);
  for (size_t i = 0; i < d->x->size(); ++i) {
    double x = (*d->x)[i];
    double e = std::exp(-c2 * x);
    gsl_matrix_set(jac, i, 0, d->sign * (1.0 - e));
    gsl_matrix_set(jac, i, 1, d->sign * c1 * x * e);
  }
  return GSL_SUCCESS;
}

// ---- Sweeps ------------------------------------------------------------------------------------

constexpr double kThreeSigmaQuantile = 0.99865;  // one-sided: P(|t| < q) = 99.73 %
constexpr double kSame = 1e-12;                  // relative: two parameter values this close are one value

bool Differ(double a, double b) { return std::fabs(a - b) > kSame * std::max({1.0, std::fabs(a), std::fabs(b)}); }

// Splits samples by the sign of Omega: rising (Omega < 0) first, then sinking (Omega > 0).
// Omega = 0 belongs to neither branch (eq. 8 and 9 are stated per direction of rotation).
std::vector<std::pair<Branch, std::vector<SweepSample>>> Branches(const std::vector<SweepSample>& samples) {
  std::vector<SweepSample> rising, sinking;
  for (const SweepSample& s : samples) {
    const Branch b = BranchOf(s.point);
    if (b == Branch::kRising) rising.push_back(s);
    if (b == Branch::kSinking) sinking.push_back(s);
  }
  std::vector<std::pair<Branch, std::vector<SweepSample>>> out;
  if (!rising.empty()) out.emplace_back(Branch::kRising, std::move(rising));
  if (!sinking.empty()) out.emplace_back(Branch::kSinking, std::move(sinking));
  return out;
}

double ParamOf(const Point& p, const std::string& param) {
  if (param == "Omega") return std::fabs(p.Omega);
  if (param == "A") return p.A;
  return p.f;
}

}  // namespace

// ---- The three laws ----------------------------------------------------------------------------

double SaturationModel(const SaturationFit& fit, double x) { return fit.sign * fit.c1 * (1.0 - std::exp(-fit.c2 * x)); }

double SaturationBandHalfWidth(const SaturationFit& fit, double x) {
  // Gradient of the law in (c1, c2).
  const double e = std::exp(-fit.c2 * x);
  const double g1 = fit.sign * (1.0 - e), g2 = fit.sign * fit.c1 * x * e;
  const double var =
      g1 * g1 * fit.c1_stderr * fit.c1_stderr + 2 * g1 * g2 * fit.c1_c2_cov + g2 * g2 * fit.c2_stderr * fit.c2_stderr;
  return StudentT95(std::max(fit.n - 2, 1)) * std::sqrt(std::max(var, 0.0));
}

double LinearBandHalfWidth(const LinearFit& fit, double a) {
  return StudentT95(std::max(fit.n - 1, 1)) * std::fabs(a) * fit.c3_stderr;
}

Result<SaturationFit> FitSaturation(const std::vector<double>& x, const std::vector<double>& y, int sign,
                                    const std::vector<double>& y_stderr) {
  QuietGsl();
  if (x.size() != y.size() || (!y_stderr.empty() && y_stderr.size() != y.size())) {
    return Status::InvalidArgument("points", "x, U_z and their errors differ in length");
  }
  if (x.size() < 3) {
    return Status::InvalidArgument(
        "points", "eq. 8 has 2 parameters: it needs at least 3 points, got " + std::to_string(x.size()));
  }
  if (!AllFinite(x) || !AllFinite(y) || !AllFinite(y_stderr)) {
    return Status::InvalidArgument("points", "a value is not finite");
  }
  if (sign != 1 && sign != -1) return Status::InvalidArgument("sign", "must be +1 or -1");
  const size_t n = x.size();
  const bool weighted = HasAllErrors(y_stderr, n);

  // Start: C1 from the largest signed U_z, C2 from where the data first reach half of it.
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return x[a] < x[b]; });
  // The largest |Omega| is nearest the plateau: its signed U_z is C1's first guess (negative
  // when the branch moves against `sign`, which the fit then reports as C1 < 0).
  double c1_0 = sign * y[order[n - 1]];
  if (c1_0 == 0) c1_0 = 1e-6;
  double x_half = x[order[n / 2]];
  for (size_t i : order) {
    if (sign * y[i] / c1_0 >= 0.5 && x[i] > 0) {
      x_half = x[i];
      break;
    }
  }
  double c2_0 = x_half > 0 ? std::log(2.0) / x_half : 1.0;

  SaturationData data{&x, &y, static_cast<double>(sign)};
  gsl_multifit_nlinear_fdf fdf;
  fdf.f = SaturationResidual;
  fdf.df = SaturationJacobian;
  fdf.fvv = nullptr;
  fdf.n = n;
  fdf.p = 2;
  fdf.params = &data;
  gsl_multifit_nlinear_parameters params = gsl_multifit_nlinear_default_parameters();
  gsl_multifit_nlinear_workspace* w = gsl_multifit_nlinear_alloc(gsl_multifit_nlinear_trust, &params, n, 2);
  if (w == nullptr) return Status::Internal("GSL could not allocate a workspace");
  gsl_vector* p0 = gsl_vector_alloc(2);
  gsl_matrix* covar = gsl_matrix_alloc(2, 2);
  gsl_vector_set(p0, 0, c1_0);
  gsl_vector_set(p0, 1, c2_0);
  int info = 0;
  gsl_vector* weights = gsl_vector_alloc(n);
  for (size_t i = 0; i < n; ++i) gsl_vector_set(weights, i, weighted ? 1.0 / (y_stderr[i] * y_stderr[i]) : 1.0);
  int status = gsl_multifit_nlinear_winit(p0, weights, &fdf, w);
  if (status == GSL_SUCCESS) {
    status = gsl_multifit_nlinear_driver(500, 1e-10, 1e-10, 1e-12, nullptr, nullptr, &info, w);
  }
  SaturationFit fit;
  fit.sign = sign;
  fit.n = static_cast<int>(n);
  fit.c1 = gsl_vector_get(gsl_multifit_nlinear_position(w), 0);
  fit.c2 = gsl_vector_get(gsl_multifit_nlinear_position(w), 1);
  fit.iterations = static_cast<int>(gsl_multifit_nlinear_niter(w));
  double chisq = 0;
  gsl_blas_ddot(gsl_multifit_nlinear_residual(w), gsl_multifit_nlinear_residual(w), &chisq);
  int covar_status = gsl_multifit_nlinear_covar(gsl_multifit_nlinear_jac(w), 0.0, covar);
  // chisq is weighted when the fit is: (J'WJ)^-1 is then the covariance the points' errors give,
  // widened when the scatter about the law is larger than they say.
  double reduced = chisq / static_cast<double>(n - 2);
  double scale = weighted ? std::max(1.0, reduced) : reduced;
  fit.weighted = weighted;
  fit.c1_stderr = std::sqrt(scale * gsl_matrix_get(covar, 0, 0));
  fit.c2_stderr = std::sqrt(scale * gsl_matrix_get(covar, 1, 1));
  fit.c1_c2_cov = scale * gsl_matrix_get(covar, 0, 1);
  gsl_vector_free(weights);
  gsl_vector_free(p0);
  gsl_matrix_free(covar);
  gsl_multifit_nlinear_free(w);

  if (status != GSL_SUCCESS || covar_status != GSL_SUCCESS || !std::isfinite(fit.c1) || !std::isfinite(fit.c2) ||
      !std::isfinite(fit.c1_stderr) || !std::isfinite(fit.c2_stderr)) {
    return Status::FailedPrecondition(
        "fit", std::string("eq. 8 did not converge (") + gsl_strerror(status) + ", C1 = " + std::to_string(fit.c1) +
                   ", C2 = " + std::to_string(fit.c2) + " after " + std::to_string(fit.iterations) +
                   " iterations): the data may not saturate over this range of |Omega|");
  }
  std::vector<double> predicted(n);
  for (size_t i = 0; i < n; ++i) predicted[i] = SaturationModel(fit, x[i]);
  fit.r2 = RSquared(y, predicted);
  return fit;
}

Result<LinearFit> FitThroughOrigin(const std::vector<double>& a, const std::vector<double>& y,
                                   const std::vector<double>& y_stderr) {
  QuietGsl();
  if (a.size() != y.size() || (!y_stderr.empty() && y_stderr.size() != y.size())) {
    return Status::InvalidArgument("points", "A, U_z and their errors differ in length");
  }
  if (a.size() < 2) {
    return Status::InvalidArgument("points", "eq. 9 needs at least 2 points, got " + std::to_string(a.size()));
  }
  if (!AllFinite(a) || !AllFinite(y) || !AllFinite(y_stderr)) {
    return Status::InvalidArgument("points", "a value is not finite");
  }
  if (std::all_of(a.begin(), a.end(), [](double v) { return v == 0; })) {
    return Status::InvalidArgument("points", "every A is 0: no slope through the origin");
  }
  const size_t n = a.size();
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](size_t i, size_t j) { return a[i] < a[j]; });

  const bool weighted = HasAllErrors(y_stderr, n);
  // The first k points by A. Weighted: cov from the errors, widened by the scatter when larger
  // (chi^2 / (k - 1) > 1); sumsq is then the weighted chi^2, turned back into a residual variance
  // in U_z's units for the range rule below by the mean error^2.
  auto fit_first = [&](size_t k, double* c3, double* cov, double* sumsq) {
    std::vector<double> xs(k), ys(k), ws(k);
    for (size_t i = 0; i < k; ++i) {
      xs[i] = a[order[i]];
      ys[i] = y[order[i]];
      ws[i] = weighted ? 1.0 / (y_stderr[order[i]] * y_stderr[order[i]]) : 1.0;
    }
    if (!weighted) return gsl_fit_mul(xs.data(), 1, ys.data(), 1, k, c3, cov, sumsq);
    int status = gsl_fit_wmul(xs.data(), 1, ws.data(), 1, ys.data(), 1, k, c3, cov, sumsq);
    if (k > 1) *cov *= std::max(1.0, *sumsq / static_cast<double>(k - 1));
    double mean_var = 0;
    for (size_t i = 0; i < k; ++i) mean_var += 1.0 / ws[i];
    *sumsq *= mean_var / static_cast<double>(k);
    return status;
  };

  size_t k = std::min<size_t>(3, n);
  double c3 = 0, cov = 0, sumsq = 0;
  if (fit_first(k, &c3, &cov, &sumsq) != GSL_SUCCESS) {
    return Status::FailedPrecondition("fit", "eq. 9: GSL could not fit the smallest A");
  }
  while (k < n) {
    size_t j = order[k];
    // Prediction interval of the line so far at A_j: s^2 (1 + A_j^2 / sum A^2) = s^2 + A_j^2 cov,
    // plus the point's own error; Student t with k - 1 degrees of freedom at 99.73 % (3 sigma).
    double residual_var = k > 1 ? sumsq / static_cast<double>(k - 1) : 0.0;
    double own = y_stderr.empty() ? 0.0 : y_stderr[j];
    double sigma = std::sqrt(residual_var + a[j] * a[j] * cov + own * own);
    double t = k > 1 ? gsl_cdf_tdist_Pinv(kThreeSigmaQuantile, static_cast<double>(k - 1)) : 3.0;
    if (std::fabs(y[j] - c3 * a[j]) > t * sigma) break;
    ++k;
    fit_first(k, &c3, &cov, &sumsq);
  }
  LinearFit fit;
  fit.weighted = weighted;
  fit.c3 = c3;
  fit.c3_stderr = std::sqrt(std::max(0.0, cov));
  fit.n = static_cast<int>(k);
  fit.n_total = static_cast<int>(n);
  fit.a_from = a[order[0]];
  fit.a_to = a[order[k - 1]];
  std::vector<double> ys(k), predicted(k);
  for (size_t i = 0; i < k; ++i) {
    ys[i] = y[order[i]];
    predicted[i] = c3 * a[order[i]];
  }
  fit.r2 = RSquared(ys, predicted);
  return fit;
}

Result<FastestRise> FitFastestRise(const std::vector<double>& f, const std::vector<double>& y,
                                   const std::vector<double>& y_stderr) {
  QuietGsl();
  if (f.size() != y.size() || (!y_stderr.empty() && y_stderr.size() != y.size())) {
    return Status::InvalidArgument("points", "f, U_z and their errors differ in length");
  }
  if (!AllFinite(f) || !AllFinite(y) || !AllFinite(y_stderr)) {
    return Status::InvalidArgument("points", "a value is not finite");
  }
  // One value per frequency: the mean of repeated points (a sweep shares a point once anyway).
  std::map<double, std::vector<size_t>> by_f;
  for (size_t i = 0; i < f.size(); ++i) by_f[f[i]].push_back(i);
  if (by_f.size() < 3) {
    return Status::InvalidArgument("points",
                                   "the fastest rise needs at least 3 distinct f, got " + std::to_string(by_f.size()));
  }
  std::vector<double> fs, ys, es;
  for (const auto& [freq, idx] : by_f) {
    double sum = 0, var = 0;
    for (size_t i : idx) {
      sum += y[i];
      if (!y_stderr.empty()) var += y_stderr[i] * y_stderr[i];
    }
    fs.push_back(freq);
    ys.push_back(sum / static_cast<double>(idx.size()));
    es.push_back(std::sqrt(var) / static_cast<double>(idx.size()));
  }
  const size_t m = fs.size();
  size_t top = static_cast<size_t>(std::max_element(ys.begin(), ys.end()) - ys.begin());
  FastestRise out;
  if (top == 0 || top == m - 1) {
    out.at_edge = true;
    out.f_c = fs[top];
    out.uz_max = ys[top];
    out.n = 1;
    size_t neighbour = top == 0 ? 1 : m - 2;
    out.interval_lo = std::min(fs[top], fs[neighbour]);
    out.interval_hi = std::max(fs[top], fs[neighbour]);
    return out;
  }
  // U = b0 + b1 u + b2 u^2 with u = f - f_top (centred for conditioning), through the three points.
  const double f0 = fs[top];
  const bool weighted = std::all_of(es.begin() + (top - 1), es.begin() + (top + 2), [](double e) { return e > 0; });
  gsl_matrix* X = gsl_matrix_alloc(3, 3);
  gsl_vector* Y = gsl_vector_alloc(3);
  gsl_vector* W = gsl_vector_alloc(3);
  gsl_vector* c = gsl_vector_alloc(3);
  gsl_matrix* cov = gsl_matrix_alloc(3, 3);
  for (size_t r = 0; r < 3; ++r) {
    double u = fs[top - 1 + r] - f0;
    gsl_matrix_set(X, r, 0, 1.0);
    gsl_matrix_set(X, r, 1, u);
    gsl_matrix_set(X, r, 2, u * u);
    gsl_vector_set(Y, r, ys[top - 1 + r]);
    gsl_vector_set(W, r, weighted ? 1.0 / (es[top - 1 + r] * es[top - 1 + r]) : 1.0);
  }
  gsl_multifit_linear_workspace* work = gsl_multifit_linear_alloc(3, 3);
  double chisq = 0;
  int status = gsl_multifit_wlinear(X, W, Y, c, cov, &chisq, work);
  double b1 = gsl_vector_get(c, 1), b2 = gsl_vector_get(c, 2), b0 = gsl_vector_get(c, 0);
  double v11 = gsl_matrix_get(cov, 1, 1), v22 = gsl_matrix_get(cov, 2, 2), v12 = gsl_matrix_get(cov, 1, 2);
  gsl_multifit_linear_free(work);
  gsl_matrix_free(X);
  gsl_vector_free(Y);
  gsl_vector_free(W);
  gsl_vector_free(c);
  gsl_matrix_free(cov);
  if (status != GSL_SUCCESS || !(b2 < 0)) {
    return Status::FailedPrecondition("fit", "the quadratic through the largest U_z and its neighbours has no maximum");
  }
  double u_c = -b1 / (2 * b2);
  out.f_c = f0 + u_c;
  out.uz_max = b0 + b1 * u_c + b2 * u_c * u_c;
  out.n = 3;
  const double lo = fs[top - 1], hi = fs[top + 1];
  if (weighted) {
    // Delta method: d u_c / d b1 = -1 / (2 b2), d u_c / d b2 = b1 / (2 b2^2).
    double g1 = -1.0 / (2 * b2), g2 = b1 / (2 * b2 * b2);
    double var = g1 * g1 * v11 + g2 * g2 * v22 + 2 * g1 * g2 * v12;
    out.f_c_stderr = std::sqrt(std::max(0.0, var));
    out.interval_lo = std::clamp(out.f_c - out.f_c_stderr, lo, hi);
    out.interval_hi = std::clamp(out.f_c + out.f_c_stderr, lo, hi);
  } else {
    out.interval_lo = lo;
    out.interval_hi = hi;
  }
  return out;
}

// ---- Sweeps ------------------------------------------------------------------------------------

const char* FitKindName(FitKind kind) {
  switch (kind) {
    case FitKind::kNone:
      return "none";
    case FitKind::kSaturation:
      return "saturation";
    case FitKind::kLinear:
      return "linear";
    case FitKind::kFastestRise:
      return "fastest_rise";
  }
  return "none";
}

FitChoice ChooseFit(const std::vector<Point>& points) {
  FitChoice choice;
  if (points.size() < 2) {
    choice.reason = "fewer than 2 points: nothing varies";
    return choice;
  }
  for (const Point& p : points) {
    if (p.mode != Mode::kOscillatory) {
      choice.reason = "the paper's laws are for the oscillatory drive (eq. 6); this sweep has " +
                      std::string(ModeName(p.mode)) + " points";
      return choice;
    }
  }
  const Point& first = points.front();
  bool varies_omega = false, varies_a = false, varies_f = false;
  for (const Point& p : points) {
    varies_omega |= Differ(std::fabs(p.Omega), std::fabs(first.Omega));
    varies_a |= Differ(p.A, first.A);
    varies_f |= Differ(p.f, first.f);
  }
  int varied = static_cast<int>(varies_omega) + static_cast<int>(varies_a) + static_cast<int>(varies_f);
  // A material parameter (core/materials.h): the paper has no law for it, so nothing is fitted,
  // but it is the x axis U_z is shown against.
  std::vector<std::string> materials;
  for (const MaterialField& m : MaterialFields()) {
    for (const Point& p : points) {
      if (Differ(p.materials.*m.member, first.materials.*m.member)) {
        materials.emplace_back(m.name);
        break;
      }
    }
  }
  if (!materials.empty()) {
    if (varied + materials.size() > 1) {
      choice.reason = "more than one of |Omega|, A, f and the materials varies: one at a time is shown against U_z";
      return choice;
    }
    choice = {FitKind::kNone, materials[0],
              materials[0] + " varies: the paper has no law for it; U_z is shown against it, not fitted"};
    return choice;
  }
  if (varied != 1) {
    choice.reason = varied == 0 ? "only the sign of Omega (or nothing) varies: no law to fit"
                                : "more than one of |Omega|, A, f varies: the paper's laws vary one at a time";
    return choice;
  }
  if (varies_omega) {
    choice = {FitKind::kSaturation, "Omega", "|Omega| varies: U_z = +/-C1 (1 - exp(-C2 |Omega|)) (eq. 8)"};
  } else if (varies_a) {
    choice = {FitKind::kLinear, "A", "A varies: U_z = C3 A (eq. 9)"};
  } else {
    choice = {FitKind::kFastestRise, "f", "f varies: the frequency f_c of the fastest rise (Fig. 8)"};
  }
  return choice;
}

SweepFits FitSweep(const std::vector<SweepSample>& samples) {
  std::vector<Point> points;
  for (const SweepSample& s : samples) points.push_back(s.point);
  return FitSweep(samples, ChooseFit(points));
}

SweepFits FitSweep(const std::vector<SweepSample>& samples, const FitChoice& choice) {
  SweepFits fits;
  fits.choice = choice;
  std::vector<SweepSample> conclusive;
  for (const SweepSample& s : samples) {
    if (s.conclusive) {
      conclusive.push_back(s);
    } else {
      fits.left_out.push_back({s.run_id, s.point, s.inconclusive_reason});
    }
  }
  if (fits.choice.kind == FitKind::kNone) return fits;
  for (auto& [side, branch] : Branches(conclusive)) {
    BranchFit b;
    b.branch = BranchName(side);
    b.points = static_cast<int>(branch.size());
    const int sign = ExpectedUzSign(side);
    std::vector<double> x, y, e;
    for (const SweepSample& s : branch) {
      x.push_back(ParamOf(s.point, fits.choice.param));
      y.push_back(s.uz);
      e.push_back(s.uz_stderr);
    }
    switch (fits.choice.kind) {
      case FitKind::kSaturation: {
        auto r = FitSaturation(x, y, sign, e);
        if (r.ok()) {
          b.saturation = *r;
          b.sign_matches_paper = r->c1 > 0;
        } else {
          b.error = r.status().reason();
        }
        break;
      }
      case FitKind::kLinear: {
        auto r = FitThroughOrigin(x, y, e);
        if (r.ok()) {
          b.linear = *r;
          b.sign_matches_paper = sign * r->c3 > 0;
        } else {
          b.error = r.status().reason();
        }
        break;
      }
      case FitKind::kFastestRise: {
        if (sign < 0) {
          b.error = "the fastest rise is a property of the rising branch (Omega < 0)";
          break;
        }
        auto r = FitFastestRise(x, y, e);
        if (r.ok()) {
          b.fastest_rise = *r;
          b.sign_matches_paper = r->uz_max > 0;
        } else {
          b.error = r.status().reason();
        }
        break;
      }
      case FitKind::kNone:
        break;
    }
    fits.branches.push_back(std::move(b));
  }
  return fits;
}

// ---- JSON --------------------------------------------------------------------------------------

void to_json(nlohmann::json& j, const SaturationFit& f) {
  j = {{"law", "U_z = sign * C1 * (1 - exp(-C2 |Omega|))"},
       {"sign", f.sign},
       {"C1", f.c1},
       {"C1_stderr", f.c1_stderr},
       {"C2", f.c2},
       {"C2_stderr", f.c2_stderr},
       {"C1_C2_cov", f.c1_c2_cov},
       {"r2", f.r2},
       {"n", f.n},
       {"iterations", f.iterations},
       {"weighted", f.weighted},
       {"units", {{"C1", "m/s"}, {"C2", "s/rad"}}}};
}

void to_json(nlohmann::json& j, const LinearFit& f) {
  j = {{"law", "U_z = C3 * A"},
       {"C3", f.c3},
       {"C3_stderr", f.c3_stderr},
       {"r2", f.r2},
       {"n", f.n},
       {"n_total", f.n_total},
       {"A_from", f.a_from},
       {"A_to", f.a_to},
       {"weighted", f.weighted},
       {"units", {{"C3", "1/s"}, {"A", "m"}}}};
}

void to_json(nlohmann::json& j, const FastestRise& f) {
  j = {{"f_c", f.f_c},
       {"f_c_stderr", f.f_c_stderr},
       {"interval", {f.interval_lo, f.interval_hi}},
       {"Uz_max", f.uz_max},
       {"at_edge", f.at_edge},
       {"n", f.n},
       {"units", {{"f_c", "Hz"}, {"Uz_max", "m/s"}}}};
}

void to_json(nlohmann::json& j, const BranchFit& b) {
  j = {{"branch", b.branch}, {"points", b.points}, {"error", b.error}};
  // The side of Omega its points are on (core/branch.h), so that a client need not know the rule.
  j["omega_sign"] = OmegaSign(ParseBranch(b.branch).value_or(Branch::kNone));
  if (b.saturation) j["saturation"] = *b.saturation;
  if (b.linear) j["linear"] = *b.linear;
  if (b.fastest_rise) j["fastest_rise"] = *b.fastest_rise;
  j["sign_matches_paper"] = b.sign_matches_paper ? nlohmann::json(*b.sign_matches_paper) : nlohmann::json(nullptr);
}

void to_json(nlohmann::json& j, const SweepFits& s) {
  j = {{"kind", FitKindName(s.choice.kind)},
       {"param", s.choice.param},
       {"reason", s.choice.reason},
       {"branches", s.branches}};
  nlohmann::json left_out = nlohmann::json::array();
  for (const LeftOut& l : s.left_out) {
    left_out.push_back({{"run_id", l.run_id}, {"point", PointToJson(l.point)}, {"reason", l.reason}});
  }
  j["left_out"] = std::move(left_out);
}

}  // namespace sandswim
