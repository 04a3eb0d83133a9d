// Claims: the paper's findings a campaign tests (SPEC.md "claim", F1-F6), as data in the campaign
// file, and the verdict a campaign run's results give each: holds, differs or inconclusive.
//
// A claim is {"id","title","source","paper":{"text",...},"rule":{"kind",...params}}. The rule's kind
// is one of a few generic tests; its parameters (which sweeps, the paper's numbers it is compared
// with) are the campaign file's, never this code's. ParseClaims() validates them against the
// campaign's sweep names and names the bad field ("[2].rule.kind"; ParseCampaign prefixes
// "claims").
//
// Points. A point of a sweep runs on K replicate beds; a claim looks at all K runs, never at the
// beds that happen to suit it (the fast beds meet the surface first: dropping them biases towards
// slow ones). Each run is one of:
//   measured   done, conclusive, U_z with a standard error (core/trajectory.h);
//   censored   done, cut short at the surface's or the floor's clearance (its stop or its window
//              ended there) before enough whole periods: its sign is the boundary's, and its drift
//              covered at least |dz| - a in its simulated time t, a = the z amplitude at f the
//              analysis measured over whole periods or, with no whole period, the drive's A; so
//              |U_z| >= (|dz| - a) / t. A run that moved less than a is no evidence;
//   no evidence  failed, cancelled, queued, running, or done with neither a U_z nor a boundary.
// A point over its K runs follows core/aggregate.h's stated rule (AggregateReplicates, "as
// evidence"): *measured* when all K runs are (its value their aggregate: the mean, the between-bed
// error for K >= 2, the run's own with the scale's bed prior for K = 1); *censored* when every run
// is measured or censored, one at least censored: a sign (BedsSign: the beds' summed drift clear
// of 0 by their own errors, no bed the other way), a bound (the smallest censored bed's) and, with
// a sign, a lower estimate of U_z (the mean over all K beds, each censored one at its bound); any
// other point is missing (a failed or unfinished bed keeps it from deciding), listed in `missing`
// with each bed's reason. Nothing is dropped silently. A rule that needs a sign (sign, modes
// "rises") takes every point with evidence and decides its sign by BedsSign; F2's saturation takes
// a censored point's lower estimate where a low value works against the verdict (below); the other
// fits take only measured points and list censored ones as missing ("a sign and a bound, no
// rate"). A claim never holds while a point it needs is missing.
//
// Errors that do not rest on a few periods. A run's error rests on 2-4 degrees of freedom (3-5
// periods): a chi^2 of points about a law with such errors refuses a true law 21-43 % of the time.
// The fitted rules below (saturation, linear_in_A, interior_maximum) therefore weight points by a
// variance model, sd = a + b |U_z| fitted to the own errors of the points a law is fitted to (their
// shape only) and evaluated at the law's fitted |U_z| (not each point's own noisy value), and take
// the scale from the fit's residuals: every t and F test on them has its
// stated size for normal errors of that shape. Lack of power is "inconclusive", never "differs".
//
// Kinds and how each decides:
//   sign              every point of `sweeps` moves the way `expect` says ("rise", "sink", or
//                     "against_Omega": rises for Omega < 0, sinks for Omega > 0): a point holds
//                     when its beds show that sign (core/aggregate.h BedsSign at 95 %: their summed
//                     drift, censored beds at their bound, clear of 0 by the measured beds' own
//                     errors, and no bed the other way; K = 1: the run's own interval). The claim
//                     holds when every point of the sweeps holds; differs when some point's beds
//                     show the other sign at the family-wise level (Bonferroni over the m points
//                     with evidence: BedsSign at 0.025 / m); else inconclusive.
//   saturation        per branch of `sweep` (rising Omega < 0, sinking Omega > 0), on its measured
//                     points and its censored points whose beds show the branch's sign (at their
//                     lower estimate: low where the point is fast, which on a law that grows is at
//                     large |Omega|, against "grows"), y = |U_z| the paper's way against x = log2
//                     |Omega| (the sweep doubles |Omega|), weighted least squares as above, at least
//                     `min_points` (default 4):
//                     "grows": the slope of y on x, its 95 % t interval (n - 2 dof) above 0 holds,
//                     below 0 differs (a flat law holds at most 2.5 % of the time);
//                     "the growth flattens" (needs 5 points): y = a + b x + d (x - x_m)+, a hinge
//                     at the middle point x_m of those above, censored points only up to x_m (past
//                     it a low value would fake the flattening; measured points past it: at least
//                     one); d's 95 % interval (n - 3 dof) below 0, with "grows"
//                     holding, holds; above 0 (growth speeding up: e.g. U_z linear in |Omega|)
//                     differs; a law that keeps growing as log |Omega| has d = 0, so holds at most
//                     2.5 % of the time. Eq. 8's C1, C2 and the |Omega| at which it reaches
//                     `reached_fraction` of C1 are shown as figures; the decision does not rest on
//                     them. And "beyond": the runs past |Omega| = `beyond_abs_Omega` reach the
//                     surface (rising) or the floor (sinking): holds when every one did, differs
//                     when one ran at least `min_duration_s` without, inconclusive when one stopped
//                     earlier (a precision target) or did not finish.
//   linear_in_A       eq. 9 per branch of `sweep`, on measured points, weighted as above, at least 4.
//                     The line through the origin is tested against U_z = a + b A + c A^2 by an F
//                     test (2 and n - 3 dof) on the larger model's residuals; p < 0.01 differs (a
//                     true line is refused 1 % of the time). Rising: holds when C3's 95 % interval
//                     (n - 1 dof) is above 0, the F test's p >= 0.05 and the intercept of a + b A is
//                     shown (95 % interval) within +- `intercept_tolerance` (default 0.5) times C3 at
//                     the smallest A: an affine law is not eq. 9. Sinking, when
//                     `sinking_linear_to_A` is set: the same on the points up to it; past it +
//                     `break_tolerance_m`, d = the points' departure from that line as a fraction
//                     of a plateau's from the break (0: on the line, 1: a plateau), by least
//                     squares, its error from the line's residual variance (or the points' own
//                     errors where larger) and C3's; d's 95 % interval above 0 holds (they leave the
//                     line), below 0.5 differs (they stay nearer the line than a plateau), else
//                     inconclusive. C3's interval holding 0: inconclusive.
//   interior_maximum  the rising branch (Omega < 0) of `sweep` against f, every point measured, with
//                     the errors of the scatter model above. An interior maximum is established when
//                     T = the largest interior U_z minus the larger edge value is improbable under
//                     equal rates at every f (the least favourable law without one): p = P(T* >= T)
//                     over 4,000 draws of that law with the points' errors, below 0.025 (the errors
//                     are estimates; at 0.05 the size was 5.5-6 %). The peak is the f of the largest
//                     U_z, refined where interior by the vertex of the parabola through it and its
//                     neighbours; its 95 % interval is a parametric bootstrap (4,000 draws around the
//                     data, the peak located in each alike: the 2.5 and 97.5 % quantiles, not
//                     clipped). Draws use a fixed seed: a verdict is the same each time. Holds when
//                     an interior maximum is established and the interval meets `f_c_hz` +-
//                     `f_c_tolerance_hz` (the paper read f_c off its grid of f); differs when an
//                     interior maximum is established and the interval lies apart from that, or when
//                     an edge's rate is established above every interior one by the same test the
//                     other way (p = P(T* <= T) below 0.025: "no interior maximum in the swept
//                     range"); else inconclusive (an interval away from f_c without either is a
//                     lack of power, not a refutation).
//   grain_count       the beds' grains against the paper's `paper_grains` in `paper_bed_m3`: each
//                     prepared bed's solid fraction (its grains' volume over the box below its
//                     surface, the SO's volume taken out; the surface at the highest grain centre
//                     + d/2, +- d) and the count that fraction gives in the paper's volume; holds
//                     when `paper_grains` lies within that interval widened by `tolerance_rel`,
//                     differs when outside, inconclusive with no prepared bed.
//   modes             Sec. 3.1 (Fig. 2): parts "rises" (sign rule, expect rise, on `rises`),
//                     "fastest" (`fastest`'s U_z above each of `fastest_among` by more than the
//                     combined half-widths, Bonferroni over them for differs; a censored point
//                     enters one-sided with its lower estimate of |U_z| (core/aggregate.h uz_low),
//                     spread by the measured beds' errors and the scale's bed prior: a rising one
//                     can show it is faster, never slower, so a censored fastest mode can hold and
//                     a censored rival can refute; no bed prior at the scale: it compares with
//                     nothing), "stays near x"
//                     (the mean x drift of `fastest` over its K beds, its 95 % t interval from the
//                     beds' scatter, within +- `x_within_m` holds, wholly beyond differs; one bed
//                     gives no error: inconclusive), "z oscillates
//                     with an x component" (the smallest z amplitude at f of `z_osc_with` runs is
//                     at least `osc_ratio` times the largest of `z_osc_without`; differs when the
//                     largest without is at least `osc_ratio` times the smallest with (the
//                     amplitudes have no error: as much margin either way); a run whose window held
//                     no whole period has no amplitude
//                     and leaves the part inconclusive), "x oscillates with a z component"
//                     (inconclusive: the run analysis does not measure x's amplitude at f).
// Every verdict names the scale it was decided at (ClaimVerdict::scale, "holds at smoke"): a
// verdict at smoke is a statement about the smoke box.
//
// Every verdict and part may also carry its rule's error rates at the campaign run's design
// (ClaimRates, filled by core/claim_rates.h from the committed calibration of the truth engine):
// "false holds <= x %, false differs <= y %, power z % at this design", or "not calibrated at
// this design". kClaimRulesVersion names the rules above: a change to any rule's decision bumps it,
// which makes every calibration table made with the old rules stale (tests/truth/ checks it).
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_CLAIMS_H_
#define SANDSWIM_CORE_CLAIMS_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/fit.h"
#include "core/job_state.h"
#include "core/point.h"
#include "core/status.h"

namespace sandswim {

struct Claim {
  std::string id;        // "F1": 1 to 100 of A-Z a-z 0-9 . _ -, unique in the campaign
  std::string title;     // what the paper finds, in a line
  std::string source;    // where: "Sec. 3.2, Fig. 4"
  nlohmann::json paper;  // what the paper reports: {"text": ..., numbers or strings}
  nlohmann::json rule;   // {"kind": ..., its parameters}, validated
  std::string kind() const { return rule.is_object() ? rule.value("kind", "") : std::string(); }
};

// The rule kinds, in the order above, and the parameters a kind takes (or requires).
std::vector<std::string> ClaimKinds();
std::vector<std::string> ClaimRuleParams(const std::string& kind, bool required_only = false);

// `j`: the campaign's "claims" array. Field paths are relative to it ("[1].rule.sweep").
Result<std::vector<Claim>> ParseClaims(const nlohmann::json& j, const std::vector<std::string>& sweep_names);
nlohmann::json ClaimToJson(const Claim& c);  // as written

// ---- What a campaign run gives the claims -------------------------------------------------------

// One run of a sweep (a point on one replicate bed), finished or not.
struct ClaimRun {
  int64_t run_id = 0;
  Point point;
  int replicate = 0;
  JobState state = JobState::kQueued;
  std::optional<api::RunResult> result;  // done runs
  std::string failure;                   // failed runs: the last error ("deck_error: ...")
};

struct ClaimSweep {
  std::string name;
  std::vector<SweepSample> samples;  // one per point with a finished run, over its beds (AnalyzeSweep)
  SweepFits fits;                    // of the samples (AnalyzeSweep)
  std::vector<ClaimRun> runs;        // every run of the sweep, on every bed
};

struct ClaimBed {
  int64_t id = 0;
  int replicate = 0;
  JobState state = JobState::kQueued;  // never cancelled
  std::optional<int64_t> grains;     // prepared beds
  std::optional<double> bed_height;  // m, highest grain centre above the floor
};

struct ClaimInput {
  std::string scale;  // a FindScale() name: the box of the beds
  std::vector<ClaimSweep> sweeps;
  std::vector<ClaimBed> beds;  // the beds the campaign run's runs use
};

// ---- Verdicts -----------------------------------------------------------------------------------

enum class Verdict { kHolds, kDiffers, kInconclusive };
const char* VerdictName(Verdict v);  // "holds", "differs", "inconclusive"

// One number behind a verdict, with its uncertainty.
struct ClaimFigure {
  std::string name;  // "U_z at Omega = -80 rad/s (baseline)"
  std::optional<double> value;
  std::optional<double> se;        // its standard error
  std::optional<double> lo, hi;    // the 95 % interval (or the range stated in `note`)
  std::string unit;                // "m/s", "Hz", ...
  std::optional<Verdict> verdict;  // this figure's own, where it has one
  std::string note;
  // A point whose runs were cut short at the surface or the floor (censored): no value, a sign and
  // `bound`, a lower bound on |U_z| (lo = bound, hi = infinity rising; lo = -infinity, hi = -bound
  // sinking); `note` says how the bound was made.
  bool censored = false;
  std::optional<double> bound;
};

// What the truth engine's calibration says of a rule's verdicts at a design (core/claim_rates.h).
struct RateEstimate {
  int64_t count = 0, n = 0;  // verdicts of that kind in n simulated campaigns
  double rate = 0, lo = 0, hi = 1;  // count / n and its 95 % (Wilson) interval
  std::string law;                  // the truth engine's law it was measured under
};
struct ClaimRates {
  bool calibrated = false;
  std::string design;  // "paper-58 at smoke, K = 1 bed(s), rules 4, analysis 3"
  std::string table;   // the calibration file the rates come from (calibrated only)
  // Calibrated: the worst false holds over the laws that make the part false, the worst false
  // differs over the laws that make it true (upper bounds quoted), the power under the law that
  // makes every claim true (estimate and interval quoted). A rate no law measured stays absent.
  std::optional<RateEstimate> false_holds, false_differs, power;
  bool low_power = false;  // power below 50 % at this design
  // "false holds <= 1.2 %, false differs <= 1.0 %, power 69 % [63, 74] at this design (300
  // campaigns a law)", or "not calibrated at this design (...): calibrate with ...".
  std::string text;
  std::string advice;  // low power or no calibration: what would help
};

struct ClaimPart {
  std::string name;
  Verdict verdict = Verdict::kInconclusive;
  std::string reason;  // why this verdict, in a sentence with its numbers
  std::vector<ClaimFigure> figures;
  std::optional<ClaimRates> rates;  // attached by AttachClaimRates (core/claim_rates.h)
};

// A point without a conclusive U_z, and why.
struct ClaimMissing {
  std::string sweep;
  Point point;
  std::vector<int64_t> run_ids;
  std::string why;  // "run 12 failed (deck_error: ...)", "run 13 inconclusive: ...", "run 14 queued"
};

struct ClaimVerdict {
  Claim claim;
  Verdict verdict = Verdict::kInconclusive;  // differs if a part differs, holds if all hold
  std::string reason;
  std::vector<ClaimPart> parts;
  std::vector<ClaimMissing> missing;
  std::string scale;  // the scale it was decided at (ClaimInput::scale): "holds at smoke"
  std::optional<ClaimRates> rates;  // of the claim as a whole (core/claim_rates.h)
};

// The version of the rules above. Bump it with any change to what a rule decides: the committed
// calibration tables (templates/calibration/) record it, and a table of another version is not
// quoted. 1: the rules' first version; 2: the variance model at the fitted |U_z|,
// F5's x drift tested with its error over the beds; 3: a point over its K beds by the stated rule
// of core/aggregate.h (the sign from the beds' summed drift, censored beds counted; censored points'
// lower estimates in F2's growth and, up to the hinge, its flattening); 4: censored points enter
// F5's "fastest" one-sided with their lower estimate.
inline constexpr int kClaimRulesVersion = 4;

// One verdict per claim, in the claims' order.
std::vector<ClaimVerdict> EvaluateClaims(const std::vector<Claim>& claims, const ClaimInput& input);

// What one bed's run gives a claim, as EvaluateClaims reads it (and the adaptive planner,
// core/adaptive.h, reads it the same way): measured = conclusive with a finite U_z, a positive
// standard error and 95 % half-width; the boundary it reached = +1 when the run ended (or its
// window closed) at the surface, -1 at the floor, 0 neither.
bool MeasuredRun(const api::RunResult& r);
int BoundaryReached(const api::RunResult& r);

// {"id","title","source","paper","rule","verdict","scale","verdict_text" ("holds at smoke"),"reason",
//  "parts":[{"name","verdict","reason","figures":[{"name","value"?,"stderr"?,"lo"?,"hi"?,"unit",
//  "verdict"?,"note","censored"?,"bound"?}],"rates"?}],"rates"? (ClaimRatesToJson),
//  "missing":[{"sweep","point","run_ids","why"}]}
nlohmann::json ClaimVerdictToJson(const ClaimVerdict& v);
// {"calibrated","design","table"?,"text","advice","low_power","false_holds"?,"false_differs"?,"power"?}
// each rate {"count","n","rate","lo","hi","law"}.
nlohmann::json ClaimRatesToJson(const ClaimRates& r);
// "holds at smoke": the verdict and the scale it was decided at (the verdict alone without one).
std::string VerdictAtScale(const ClaimVerdict& v);
// How many verdicts hold, differ and are inconclusive.
struct VerdictCounts {
  int holds = 0, differs = 0, inconclusive = 0;
};
VerdictCounts CountVerdicts(const std::vector<ClaimVerdict>& verdicts);
// "0.0123 ± 0.0011 m/s [0.0101, 0.0145]", or "–" without a value.
std::string DescribeFigure(const ClaimFigure& f);
// A point as the claims name it ("Omega = 160", "vibration+rotation about x"): in the missing list.
std::string DescribeClaimPoint(const Point& point);
// The numbers of a claim's "paper" object beside its text, in key order (a JSON object keeps no
// other): "A_m = 0.03; Omega_rad_s = -80, 80" ("" when it has none).
std::string DescribePaperNumbers(const nlohmann::json& paper);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_CLAIMS_H_
