#include "core/aggregate.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include <gsl/gsl_cdf.h>
#include <gsl/gsl_errno.h>
#include <gsl/gsl_roots.h>

#include "core/trajectory.h"

namespace sandswim {

namespace {
bool MeasuredBed(const ReplicateValue& v) {
  return v.conclusive && v.uz && std::isfinite(*v.uz) && v.uz_stderr && *v.uz_stderr > 0 && v.uz_ci95 &&
         *v.uz_ci95 > 0;
}
bool CensoredBed(const ReplicateValue& v) { return !MeasuredBed(v) && v.censored != 0 && v.bound > 0; }

// The degrees of freedom a run's own 95 % interval was made with.
double DofOf(const ReplicateValue& v) { return DofOfInterval(*v.uz_stderr, *v.uz_ci95); }
}  // namespace

int BedsSign(const std::vector<ReplicateValue>& values, double tail) {
  double sum = 0, var = 0, welch = 0;
  int sign_of_censored = 0, own = 0;
  bool any = false;
  for (const ReplicateValue& v : values) {
    int s = 0;
    if (MeasuredBed(v)) {
      sum += *v.uz;
      const double se2 = *v.uz_stderr * *v.uz_stderr;
      var += se2;
      welch += se2 * se2 / DofOf(v);
      s = *v.uz - *v.uz_ci95 > 0 ? 1 : *v.uz + *v.uz_ci95 < 0 ? -1 : 0;
    } else if (CensoredBed(v)) {
      sum += v.censored * v.bound;
      s = v.censored;
      if (sign_of_censored != 0 && s != sign_of_censored) return 0;
      sign_of_censored = s;
    } else {
      return 0;  // an open bed: no evidence
    }
    // A bed that shows a sign against another's: the sign is not the drive's.
    if (s != 0 && own != 0 && s != own) return 0;
    if (s != 0) own = s;
    any = true;
  }
  if (!any) return 0;
  if (var <= 0) return sign_of_censored;  // every bed censored, all at one boundary
  const double half = gsl_cdf_tdist_Pinv(1 - tail, welch > 0 ? var * var / welch : 1e7) * std::sqrt(var);
  const int sign = sum - half > 0 ? 1 : sum + half < 0 ? -1 : 0;
  return own != 0 && sign != own ? 0 : sign;
}

DofSearch SearchDofOfInterval(double se, double ci95) {
  struct Target {
    double ratio;
    int quantiles;
  } target{ci95 / se, 0};
  // An interval with no finite ratio to its error (se = 0, or NaN) says nothing of its dof: the fewest
  // (0.5), the widest quantile, as the bisection this replaced gave.
  if (!std::isfinite(target.ratio)) return {0.5, 0};
  if (target.ratio <= gsl_cdf_ugaussian_Pinv(0.975) * (1 + 1e-9)) return {1e7, 0};
  // t(0.975, e^x) - ratio falls as x = ln(dof) grows; its root in [ln 0.5, ln 1e7] by Brent's method.
  // (Halving that range 200 times took 1.2 ms a run: 11 s for a page of 10,000 runs' aggregates.)
  auto excess = [](double x, void* t) {
    auto* target = static_cast<Target*>(t);
    ++target->quantiles;
    return gsl_cdf_tdist_Pinv(0.975, std::exp(x)) - target->ratio;
  };
  double lo = std::log(0.5), hi = std::log(1e7);
  if (!(excess(lo, &target) > 0)) return {0.5, target.quantiles};  // wider than t(0.975, 0.5)'s
  if (!(excess(hi, &target) < 0)) return {1e7, target.quantiles};
  gsl_function f{excess, &target};
  gsl_root_fsolver* solver = gsl_root_fsolver_alloc(gsl_root_fsolver_brent);
  gsl_root_fsolver_set(solver, &f, lo, hi);  // straddles the root: checked above, so no GSL error
  for (int i = 0; i < 100; ++i) {
    if (gsl_root_fsolver_iterate(solver) != GSL_SUCCESS) break;
    lo = gsl_root_fsolver_x_lower(solver);
    hi = gsl_root_fsolver_x_upper(solver);
    // Absolute in ln(dof) (1e-13: dof to 1e-13 relative): a relative test has no tolerance left
    // near ln(dof) = 0 (dof near 1 took 26-36 quantiles with one).
    if (gsl_root_test_interval(lo, hi, 1e-13, 0) != GSL_CONTINUE) break;
  }
  const double dof = std::exp(gsl_root_fsolver_root(solver));
  gsl_root_fsolver_free(solver);
  return {dof, target.quantiles};
}

double DofOfInterval(double se, double ci95) { return SearchDofOfInterval(se, ci95).dof; }

ReplicateAggregate AggregateReplicates(std::vector<ReplicateValue> values, double bed_sd_rel) {
  std::sort(values.begin(), values.end(),
            [](const ReplicateValue& a, const ReplicateValue& b) { return a.replicate < b.replicate; });
  ReplicateAggregate a;
  a.replicates = static_cast<int>(values.size());
  std::vector<double> rates;
  const ReplicateValue* single = nullptr;
  double within_ss = 0;  // sum of the runs' own squared standard errors
  bool all_have_errors = true;
  for (const ReplicateValue& v : values) {
    if (!v.conclusive || !v.uz || !std::isfinite(*v.uz)) continue;
    rates.push_back(*v.uz);
    single = &v;
    if (v.uz_stderr && std::isfinite(*v.uz_stderr)) {
      within_ss += *v.uz_stderr * *v.uz_stderr;
    } else {
      all_have_errors = false;
    }
  }
  a.conclusive = static_cast<int>(rates.size());
  a.complete = a.conclusive > 0 && a.conclusive == a.replicates;
  const int n = a.conclusive;
  const std::string of_k = std::to_string(n) + " of " + std::to_string(a.replicates) + " replicate(s)";
  if (n == 0) {
    a.note = a.replicates == 0 ? "no runs" : "no conclusive replicate (" + of_k + ")";
  } else if (n == 1) {
    a.uz_mean = rates[0];
    a.uz_stderr = single->uz_stderr;
    a.uz_ci95 = single->uz_ci95;
    a.note = a.replicates == 1 ? "one bed: the scatter between beds is not known"
                               : "one conclusive replicate (" + of_k + "): the scatter between beds is not known";
    if (a.replicates == 1 && bed_sd_rel > 0 && a.uz_stderr && a.uz_ci95) {
      const double bed = bed_sd_rel * std::fabs(rates[0]);
      a.uz_stderr = std::sqrt(*a.uz_stderr * *a.uz_stderr + bed * bed);
      a.uz_ci95 = std::sqrt(*a.uz_ci95 * *a.uz_ci95 + 1.96 * 1.96 * bed * bed);
      a.bed_prior = true;
      char buf[160];
      std::snprintf(buf, sizeof buf,
                    "one bed: its error adds the scale's bed-to-bed scatter, %.0f %% of |U_z| (a prior from replicate "
                    "beds)",
                    100 * bed_sd_rel);
      a.note = buf;
    }
  } else {
    double mean = 0;
    for (double r : rates) mean += r;
    mean /= n;
    double ss = 0;
    for (double r : rates) ss += (r - mean) * (r - mean);
    const double sd = std::sqrt(ss / (n - 1));
    a.uz_mean = mean;
    a.uz_sd_between = sd;
    a.uz_stderr = sd / std::sqrt(static_cast<double>(n));
    if (n < a.replicates) a.note = "over " + of_k + ": the others are not conclusive, so the point is not";
    // The runs' own noise alone gives the mean an error of sqrt(sum se_i^2) / n; a few beds that
    // happen to agree more closely than that must not claim a smaller one.
    const double within = std::sqrt(within_ss) / n;
    if (all_have_errors && within > *a.uz_stderr) {
      a.uz_stderr = within;
      a.note += std::string(a.note.empty() ? "" : "; ") +
                "the beds scatter less than their runs' own errors: the error is theirs, sqrt(sum se^2)/n";
    }
    a.uz_ci95 = StudentT95(n - 1) * *a.uz_stderr;
  }
  // As evidence: each bed measured, censored or open, and the point by the rule in the header.
  double low_sum = 0, bound = 0;
  for (const ReplicateValue& v : values) {
    if (MeasuredBed(v)) {
      low_sum += *v.uz;
    } else if (CensoredBed(v)) {
      low_sum += v.censored * v.bound;
      bound = a.censored_beds == 0 ? v.bound : std::min(bound, v.bound);
      ++a.censored_beds;
    } else {
      ++a.open_beds;
    }
  }
  if (a.replicates > 0 && a.open_beds == 0) {
    a.evidence = a.censored_beds == 0 ? ReplicateAggregate::Evidence::kMeasured
                                      : ReplicateAggregate::Evidence::kCensored;
    a.sign = BedsSign(values, 0.025);
    if (a.censored_beds > 0) {
      a.bound = bound;
      if (a.sign != 0) a.uz_low = low_sum / a.replicates;
    }
  }
  a.values = std::move(values);
  return a;
}

std::vector<PointAggregate> AggregateByPoint(const std::vector<std::pair<Point, ReplicateValue>>& runs) {
  std::map<DriveId, size_t> index;
  std::vector<Point> points;
  std::vector<std::vector<ReplicateValue>> groups;
  for (const auto& [point, value] : runs) {
    auto [it, inserted] = index.emplace(DriveIdOf(point), points.size());
    if (inserted) {
      points.push_back(point);
      groups.emplace_back();
    }
    groups[it->second].push_back(value);
  }
  std::vector<PointAggregate> out;
  out.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) out.push_back({points[i], AggregateReplicates(std::move(groups[i]))});
  return out;
}

std::string DescribeAggregate(const ReplicateAggregate& a, bool with_units) {
  auto two_digits = [](double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.2g", v);
    return std::string(buf);
  };
  const std::string units = with_units ? " m/s" : "";
  const std::string beds =
      std::to_string(a.conclusive) + " of " + std::to_string(a.replicates) + " bed" + (a.replicates == 1 ? "" : "s");
  if (!a.uz_mean) return "inconclusive (" + beds + " conclusive)";
  if (a.conclusive == 1) {
    const std::string value = a.uz_stderr ? WithError(*a.uz_mean, *a.uz_stderr) : "≈" + two_digits(*a.uz_mean);
    return value + units + ", " + beds + ": between-bed scatter unknown";
  }
  return WithError(*a.uz_mean, *a.uz_stderr) + units + ", " + beds + " (between-bed sd " +
         two_digits(*a.uz_sd_between) + units + ")";
}

nlohmann::json AggregateToJson(const ReplicateAggregate& a) {
  nlohmann::json j = {{"replicates", a.replicates},
                      {"conclusive", a.conclusive},
                      {"complete", a.complete},
                      {"note", a.note},
                      {"uz_text", DescribeAggregate(a, false)}};
  auto put = [&](const char* key, const std::optional<double>& v) {
    if (v) j[key] = *v;
  };
  put("uz_mean", a.uz_mean);
  put("uz_sd_between", a.uz_sd_between);
  put("uz_stderr", a.uz_stderr);
  put("uz_ci95", a.uz_ci95);
  nlohmann::json values = nlohmann::json::array();
  for (const ReplicateValue& v : a.values) {
    nlohmann::json e = {{"run_id", v.run_id},
                        {"replicate", v.replicate},
                        {"bed_id", v.bed_id},
                        {"state", v.state},
                        {"conclusive", v.conclusive}};
    if (v.uz) e["uz"] = *v.uz;
    if (v.uz_stderr) e["uz_stderr"] = *v.uz_stderr;
    if (v.uz_ci95) e["uz_ci95"] = *v.uz_ci95;
    values.push_back(std::move(e));
  }
  j["values"] = std::move(values);
  return j;
}

}  // namespace sandswim
