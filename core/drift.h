// Drift: did a point's U_z change between two runs of a campaign (night A, night B)? The per-point
// decision of the nightly drift report (server/analysis/drift_report.h), a pure function here so
// that its false-alarm rate and power can be measured on the truth engine (tests/truth/,
// bench_drift_alarms) on the same code the daemon runs.
//
// RULE 2 (kDriftRuleVersion). A point is compared over the beds whose rate is conclusive on both
// nights; each bed k gives a difference d_k = U_k,now - U_k,before, and the point's difference is
// their mean D = sum d_k / n. On one bed the two runs share the bed's effect, which cancels in d_k,
// so the difference's variance is the runs' own:
//   Var(D) = sum_k (se_k,now^2 + se_k,before^2) / n^2
// with Welch-Satterthwaite's degrees of freedom from each run's own (a run's error rests on its
// blocks - 1: 2-4 at smoke; a normal quantile there is too narrow). A pair whose two runs ran on
// different beds (a bed re-poured: a new engine or template changes a bed's key) also differs by
// the beds: each side adds (bed_sd_rel |U|)^2 (the scale's prior, core/scale.h; infinite degrees of
// freedom); with no prior such a pair is held to a campaign's tolerance alone, or with none not
// compared ("other beds, their scatter is not known").
// The point DRIFTED when |D| > t(0.975, dof) sqrt(Var(D)) -- a two-sided test at 5 % per point,
// whose p-value is given -- and, when the campaign sets a tolerance (> 0), also |D| > tolerance (a
// change must be both real and as large as the campaign cares about; the tolerance alone, with
// errors larger than it, flagged noise). A rate without an error (uz_stderr 0) can only be held to
// a campaign's tolerance (no test, no p-value); with no tolerance it is not compared ("no error").
//
// The CAMPAIGN (any point drifted): across the m points compared, Holm's step-down procedure at
// family-wise 5 % on the points' p-values (HolmFlags): "the campaign drifted" is wrong at most 5 %
// of the nights nothing changed, while per point 5 % of a 58-point campaign is ~3 false alarms a
// night.
//
// RULE 1 (reports before rule 2): per run |d| > 1.96 sqrt(se^2 + se_before^2), a normal quantile
// with each run's 2-4 dof errors; per point the same on the means over each night's conclusive beds
// with their between-bed errors (which hold the bed effect that cancels). DecideDrift keeps rule
// 1 on one bed so that its false alarms can be measured beside rule 2's (bench_drift_alarms).
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_DRIFT_H_
#define SANDSWIM_CORE_DRIFT_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace sandswim {

// The drift rule the daemon applies; a report states the rule it was made with.
inline constexpr int kDriftRuleVersion = 2;
// Degrees of freedom that stand for "normal" (an error with no stated dof).
inline constexpr double kNormalDof = 1e7;

// One bed's rate on both nights.
struct DriftBedPair {
  double uz = 0, uz_stderr = 0, dof = kNormalDof;  // m/s, now (stderr 0: no error); dof of its error
  double uz_previous = 0, uz_stderr_previous = 0, dof_previous = kNormalDof;
  bool same_bed = true;  // both runs on one bed (false: a bed re-poured between them)
};

struct DriftTest {
  std::vector<DriftBedPair> beds;  // the beds conclusive on both nights
  double tolerance_mps = 0;        // the campaign's drift_tolerance_mps (0: none)
  double bed_sd_rel = 0;           // the scale's bed-to-bed prior (0: not known)
  int rule = kDriftRuleVersion;    // 1 or 2 (1: one bed only)
};

struct DriftDecision {
  bool compared = false;
  std::string not_compared;  // why not, when !compared
  int beds = 0;              // n, the beds the difference is over
  double difference = 0;     // m/s, D
  double stderr_mps = 0;     // m/s, sqrt(Var(D))
  double dof = kNormalDof;   // Welch-Satterthwaite's
  double bound = 0;          // m/s, t(0.975, dof) * stderr: the 95 % bound of |D| with no change
  double tolerance = 0;      // m/s, what |D| was held to: the bound, or the larger of it and the campaign's
  bool tested = false;       // the errors allowed a test: bound, dof and p_value are its
  double p_value = 1;        // two-sided, of D against no change
  bool drifted = false;      // at 5 % per point
};

DriftDecision DecideDrift(const DriftTest& test);

// Holm's step-down at family-wise level `alpha` over the p-values: true where a hypothesis of
// "no change" is rejected. Ties keep input order.
std::vector<bool> HolmFlags(const std::vector<double>& p_values, double alpha = 0.05);

// The measured false-alarm rates of the rule at a design (bench_drift_alarms on the truth engine,
// two nights of one law on the same beds), committed here as data: counts, so that the text can
// quote the upper 95 % bound.
struct DriftAlarmRates {
  const char* campaign;
  const char* scale;
  int beds;      // K
  int rule;      // kDriftRuleVersion it was measured with
  int analysis;  // api::kAnalysisVersion of the runs' U_z
  int64_t campaigns;                      // simulated night pairs
  int64_t points, points_drifted;         // per point (over its beds)
  int64_t campaigns_drifted;              // Holm: the campaign said "drifted"
  int64_t campaigns_any_point;            // at least one point drifted at 5 % per point
};
// The committed rates at (campaign, scale, K) for the current rule; nullptr: not measured.
const DriftAlarmRates* FindDriftAlarmRates(const std::string& campaign, const std::string& scale, int beds);
// "false alarms <= 5.3 % per point, <= 6.1 % per campaign (any point, Holm) at this design (paper-58 at smoke,
// K = 1 bed, drift rule 2; 300 simulated night pairs)" or "false alarms: not measured at this design
// (campaign at scale, K = 2); the rule's nominal level is 5 % per point and per campaign (Holm)".
// The rates were measured on two nights on the same beds with both runs' intervals known:
// `same_beds_known_errors` false (a pair on a re-poured or unknown bed, or an error without its
// interval) is another design, and the text says "not measured".
std::string DriftAlarmText(const std::string& campaign, const std::string& scale, int beds,
                           bool same_beds_known_errors = true);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_DRIFT_H_
