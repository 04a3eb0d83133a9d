#include "core/drift.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

#include <gsl/gsl_cdf.h>

#include "core/api.h"
#include "core/claim_rates.h"

namespace sandswim {
namespace {

// Measured by bench_drift_alarms (tests/bench/bench_drift_alarms.cc), rule 2, analysis 4: two
// nights of law `paper` on the same beds. Regenerate after a change of the rule or the analysis.
constexpr DriftAlarmRates kMeasured[] = {
    {"paper-58", "smoke", 1, 2, 4, 300, 10686, 152, 2, 122},
    {"paper-58", "smoke", 3, 2, 4, 150, 6117, 84, 2, 67},
};

std::string Percent(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", 100 * v);
  return buf;
}

}  // namespace

DriftDecision DecideDrift(const DriftTest& test) {
  DriftDecision d;
  const int n = static_cast<int>(test.beds.size());
  d.beds = n;
  if (n == 0) {
    d.not_compared = "no bed conclusive on both nights";
    return d;
  }
  if (test.rule == 1 && n != 1) {
    d.not_compared = "drift rule 1 compares one bed at a time";
    return d;
  }
  double sum = 0, var = 0, welch = 0;
  bool errors = true;
  for (const DriftBedPair& b : test.beds) {
    sum += b.uz - b.uz_previous;
    errors = errors && b.uz_stderr > 0 && b.uz_stderr_previous > 0;
    const double v_now = b.uz_stderr * b.uz_stderr, v_before = b.uz_stderr_previous * b.uz_stderr_previous;
    var += v_now + v_before;
    if (test.rule == 1) continue;  // a normal quantile, on the same bed
    welch += v_now * v_now / b.dof + v_before * v_before / b.dof_previous;
    if (!b.same_bed) {
      if (test.bed_sd_rel <= 0) {
        // No error for the beds' part: a campaign's tolerance alone, else nothing to hold it to.
        if (test.tolerance_mps > 0) {
          errors = false;
          continue;
        }
        d.not_compared = "other beds, their scatter is not known";
        return d;
      }
      // Two beds differ by their effects: each side's, the prior's (a known variance: no dof term).
      const double bed = test.bed_sd_rel * (std::fabs(b.uz) + std::fabs(b.uz_previous)) / 2;
      var += 2 * bed * bed;
    }
  }
  d.difference = sum / n;
  if (!errors) {
    if (test.tolerance_mps <= 0) {
      d.not_compared = "no error";
      return d;
    }
    d.tolerance = test.tolerance_mps;
    d.drifted = std::fabs(d.difference) > d.tolerance;
    d.compared = true;
    return d;
  }
  d.tested = true;
  d.stderr_mps = std::sqrt(var) / n;
  const double z = std::fabs(d.difference) / d.stderr_mps;
  if (test.rule == 1) {
    // Rule 1, kept to measure it beside rule 2: a normal quantile on the runs' own errors, and a
    // campaign's tolerance in its place.
    d.dof = kNormalDof;
    d.bound = 1.96 * d.stderr_mps;
    d.p_value = 2 * gsl_cdf_ugaussian_Q(z);
    d.tolerance = test.tolerance_mps > 0 ? test.tolerance_mps : d.bound;
  } else {
    d.dof = welch > 0 ? std::min(kNormalDof, var * var / welch) : kNormalDof;
    d.bound = gsl_cdf_tdist_Pinv(0.975, d.dof) * d.stderr_mps;
    d.p_value = 2 * gsl_cdf_tdist_Q(z, d.dof);
    d.tolerance = std::max(d.bound, test.tolerance_mps);
  }
  d.drifted = std::fabs(d.difference) > d.tolerance;
  d.compared = true;
  return d;
}

std::vector<bool> HolmFlags(const std::vector<double>& p_values, double alpha) {
  const size_t m = p_values.size();
  std::vector<size_t> order(m);
  std::iota(order.begin(), order.end(), size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) { return p_values[a] < p_values[b]; });
  std::vector<bool> flags(m, false);
  for (size_t i = 0; i < m; ++i) {
    if (p_values[order[i]] > alpha / static_cast<double>(m - i)) break;
    flags[order[i]] = true;
  }
  return flags;
}

const DriftAlarmRates* FindDriftAlarmRates(const std::string& campaign, const std::string& scale, int beds) {
  for (const DriftAlarmRates& r : kMeasured)
    if (r.rule == kDriftRuleVersion && r.analysis == api::kAnalysisVersion && campaign == r.campaign && scale == r.scale && beds == r.beds &&
        r.campaigns > 0)
      return &r;
  return nullptr;
}

std::string DriftAlarmText(const std::string& campaign, const std::string& scale, int beds,
                           bool same_beds_known_errors) {
  const DriftAlarmRates* r = FindDriftAlarmRates(campaign, scale, beds);
  const std::string k = "K = " + std::to_string(beds) + (beds == 1 ? " bed" : " beds");
  const std::string nominal = "; the rule's nominal level is 5 % per point and 5 % per campaign (any point, Holm)";
  if (r == nullptr) return "false alarms: not measured at this design (" + campaign + " at " + scale + ", " + k + ")" + nominal;
  if (!same_beds_known_errors) {
    return "false alarms: not measured at this design (" + campaign + " at " + scale + ", " + k +
           ", some runs compared across re-poured or unknown beds or without their intervals)" + nominal;
  }
  const double point_hi = WilsonInterval(r->points_drifted, r->points).second;
  const double campaign_hi = WilsonInterval(r->campaigns_drifted, r->campaigns).second;
  return "false alarms <= " + Percent(point_hi) + " % per point, <= " + Percent(campaign_hi) +
         " % per campaign (any point, Holm) at this design (" + campaign + " at " + scale + ", " + k +
         ", drift rule " + std::to_string(r->rule) + "; " + std::to_string(r->campaigns) +
         " night pairs simulated on the truth engine)";
}

}  // namespace sandswim
