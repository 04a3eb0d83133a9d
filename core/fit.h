// Fits: the paper's laws fitted to a sweep's U_z values (paper Sec. 3.2, eqs. 8 and 9, Fig. 8).
//
//   Omega sweeps  U_z = s * C1 * (1 - exp(-C2 |Omega|))   (eq. 8), s = +1 for the rising branch
//                 (Omega < 0) and -1 for the sinking branch (Omega > 0), each branch fitted on its
//                 own by nonlinear least squares (GSL multifit_nlinear, trust region). C1 and C2
//                 are free (a C1 < 0 means the branch moves the other way than the paper's sign).
//   A sweeps      U_z = C3 * A through the origin (eq. 9), per branch (GSL gsl_fit_mul), fitted
//                 over the range of A where the law holds (LinearFit below says how it is found).
//   f sweeps      the frequency f_c of the fastest rise: a quadratic through the largest U_z of
//                 the rising branch and its two neighbours in f, its vertex, with an interval.
//
// Weights: when every point of a branch has its own U_z error (core/trajectory.h: from the scatter
// of its whole-period block rates), eqs. 8 and 9 are weighted least squares, weights 1 / stderr^2,
// and a parameter's error is the covariance (J'WJ)^-1 scaled by max(1, chi^2 / (n - p)): the
// points' own errors, or the scatter about the law when that is larger (the law does not hold
// exactly, or the errors are too small). When some point has no error (its window held fewer than
// 3 periods) the fit is unweighted and its errors are the usual (J'J)^-1 SSR / (n - p);
// `weighted` says which. Inconclusive runs never reach a fit: FitSweep leaves them out and lists
// them. R^2 is 1 - SSR / SST (unweighted) with SST about the mean (so a law through the origin can
// score below 0 when it fits worse than a constant). The f_c quadratic uses the points' errors
// (it has no residual degrees of freedom).
//
// Which law applies is decided by what the sweep's points vary (ChooseFit): oscillatory points
// that differ only in |Omega| (and the sign of Omega), only in A, or only in f. Anything else
// gets no fit, with the reason. Durations are ignored (scales shorten runs per point).
//
// Thread safety: pure functions (GSL's error handler is turned off once, process-wide, so GSL
// reports errors by return value instead of aborting).
#ifndef SANDSWIM_CORE_FIT_H_
#define SANDSWIM_CORE_FIT_H_

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/point.h"
#include "core/status.h"

namespace sandswim {

// ---- The three laws, on plain numbers -----------------------------------------------------------

// eq. 8 on one branch: U_z = sign * c1 * (1 - exp(-c2 * x)), x = |Omega| in rad/s.
struct SaturationFit {
  int sign = 1;                  // +1 rising, -1 sinking
  double c1 = 0, c1_stderr = 0;  // m/s
  double c2 = 0, c2_stderr = 0;  // s/rad (1 / (rad/s))
  double c1_c2_cov = 0;          // their covariance, scaled as the errors are
  double r2 = 0;
  int n = 0;  // points fitted
  int iterations = 0;
  bool weighted = false;  // by the points' U_z errors (see above)
};
// REQUIRES: x.size() == y.size(). InvalidArgument (field "points") with fewer than 3 points or
// non-finite values; FailedPrecondition ("fit") when the solver does not converge to finite
// parameters (e.g. U_z growing linearly with no sign of saturation: C2 -> 0, C1 -> infinity).
// `y_stderr` may be empty, or hold a 0 for a point with no error: then the fit is unweighted.
Result<SaturationFit> FitSaturation(const std::vector<double>& x, const std::vector<double>& y, int sign,
                                    const std::vector<double>& y_stderr = {});
double SaturationModel(const SaturationFit& fit, double x);  // sign * c1 * (1 - exp(-c2 x))
// Half the width of the fitted law's 95 % confidence band at x: Student t (n - 2 degrees of
// freedom) times the law's standard error there, from the parameters' covariance (delta method).
double SaturationBandHalfWidth(const SaturationFit& fit, double x);

// eq. 9 on one branch: U_z = c3 * A through the origin, over [a_from, a_to].
// The range: points sorted by A; the first three (the smallest A) are always in; the next point
// joins while its U_z lies within the 99.73 % ("3 sigma") prediction interval of the line fitted
// to the points before it: Student t (k - 1 degrees of freedom) times sigma, sigma^2 = the fit's
// residual variance + (A * stderr(c3))^2 + the point's own U_z stderr^2. The first point outside
// ends the range (the paper saw sinking plateau past A ~ 0.06 m).
struct LinearFit {
  double c3 = 0, c3_stderr = 0;  // (m/s) / m = 1/s
  double r2 = 0;
  int n = 0;                    // points in the range
  int n_total = 0;              // points of the branch
  double a_from = 0, a_to = 0;  // m: the range of A the law holds over
  bool weighted = false;        // by the points' U_z errors (see above)
};
// Half the width of the line's 95 % confidence band at A: Student t (n - 1) * A * stderr(c3).
double LinearBandHalfWidth(const LinearFit& fit, double a);
// InvalidArgument ("points") with fewer than 2 points, non-finite values, or all A = 0.
// `y_stderr` may be empty (no point errors).
Result<LinearFit> FitThroughOrigin(const std::vector<double>& a, const std::vector<double>& y,
                                   const std::vector<double>& y_stderr = {});

// The frequency of the fastest rise.
struct FastestRise {
  double f_c = 0;                           // Hz
  double f_c_stderr = 0;                    // Hz (0 when the maximum is at an edge)
  double interval_lo = 0, interval_hi = 0;  // Hz: f_c -/+ stderr, clipped to the neighbours
  double uz_max = 0;                        // m/s, the quadratic's value at f_c (or the largest U_z at an edge)
  bool at_edge = false;                     // the largest U_z is at the lowest or highest f of the sweep
  int n = 0;                                // points in the local fit
};
// InvalidArgument ("points") with fewer than 3 distinct f or non-finite values. Where the
// largest U_z is at an edge, f_c is that f and the interval runs to the neighbour's f.
// `y_stderr` may be empty; without point errors the interval is the neighbours' f.
Result<FastestRise> FitFastestRise(const std::vector<double>& f, const std::vector<double>& y,
                                   const std::vector<double>& y_stderr = {});

// ---- Sweeps -------------------------------------------------------------------------------------

// One finished run of a sweep: its point and its U_z.
struct SweepSample {
  Point point;
  double uz = 0;         // m/s
  double uz_stderr = 0;  // m/s (0: unknown)
  double uz_ci95 = 0;    // m/s, half-width of its 95 % interval (0: unknown); figures draw it
  int64_t run_id = 0;
  bool conclusive = true;             // false: left out of the fit (listed in SweepFits::left_out)
  bool has_uz = true;                 // false: no U_z at all (no whole period); `uz` means nothing
  std::string inconclusive_reason{};  // (an initializer: brace-initialised samples may leave it out)
};

enum class FitKind { kNone, kSaturation, kLinear, kFastestRise };
const char* FitKindName(FitKind kind);  // "none", "saturation", "linear", "fastest_rise"

// Which law a sweep's points call for, and the parameter on the x axis.
struct FitChoice {
  FitKind kind = FitKind::kNone;
  std::string param;   // "Omega", "A", "f", a material ("so_density": no law, an x axis), "" for none
  std::string reason;  // why this law, or why none
};
FitChoice ChooseFit(const std::vector<Point>& points);

// One branch of a sweep's fit: "rising" (Omega < 0) or "sinking" (Omega > 0).
struct BranchFit {
  std::string branch;
  int points = 0;  // finished runs of the branch
  std::optional<SaturationFit> saturation;
  std::optional<LinearFit> linear;
  std::optional<FastestRise> fastest_rise;
  std::string error;  // why the law could not be fitted ("" when it was)
  // Does the branch move the paper's way (rising up, sinking down)? Unset without a fit.
  std::optional<bool> sign_matches_paper;
};

// A finished run a fit leaves out, and why.
struct LeftOut {
  int64_t run_id = 0;
  Point point;
  std::string reason;
};

struct SweepFits {
  FitChoice choice;
  std::vector<BranchFit> branches;  // rising first; a branch with no points is left out
  std::vector<LeftOut> left_out;    // inconclusive runs
};
// Fits the law ChooseFit() picks for the samples' points. Never fails: a branch that cannot be
// fitted says why in its `error`.
SweepFits FitSweep(const std::vector<SweepSample>& samples);
// The same with the law chosen beforehand (e.g. from all points of a sweep, of which only some
// have finished).
SweepFits FitSweep(const std::vector<SweepSample>& samples, const FitChoice& choice);

// JSON (field names as above; absent optionals are left out):
// {"kind","param","reason","branches":[{"branch","points","saturation"?:{...},"linear"?:{...},
//  "fastest_rise"?:{...},"error","sign_matches_paper"?}],"left_out":[{"run_id","point","reason"}]}
void to_json(nlohmann::json& j, const SaturationFit& f);
void to_json(nlohmann::json& j, const LinearFit& f);
void to_json(nlohmann::json& j, const FastestRise& f);
void to_json(nlohmann::json& j, const BranchFit& b);
void to_json(nlohmann::json& j, const SweepFits& s);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_FIT_H_
