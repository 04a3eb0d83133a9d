// Claims: the paper's findings a campaign tests (SPEC.md "claim", F1-F6), as data in the campaign
// file, and the verdict a campaign run's results give each: holds, differs or inconclusive.
//
// A claim is {"id","title","source","paper":{"text",...},"rule":{"kind",...params}}. The rule's kind
// is one of a few generic tests; its parameters (which sweeps, the paper's numbers it is compared
// with) are the campaign file's, never this code's. ParseClaims() validates them against the
// campaign's sweep names and names the bad field ("[2].rule.kind"; ParseCampaign prefixes
// "claims").
//
// Kinds and how each decides (every interval is a 95 % one; "the runs' own errors" are the U_z
// standard errors of core/trajectory.h, or over replicate beds, core/aggregate.h):
//   sign              every point of `sweeps` moves the way `expect` says ("rise", "sink", or
//                     "against_Omega": rises for Omega < 0, sinks for Omega > 0). A point holds
//                     when its U_z interval excludes 0 on that side. The claim holds when every
//                     point of the sweeps holds; differs when some point's interval excludes 0 on
//                     the other side at the family-wise level (Bonferroni over the m points: the
//                     interval widened to t(1 - 0.025/m) standard errors, so that one wrong sign
//                     among many points is not a chance of the 95 % level); else inconclusive.
//   saturation        eq. 8 per branch of `sweep` (SweepFits' fit, core/fit.h). Parts, per branch:
//                     "grows": C1's interval (t, n - 2 dof) above 0 holds, below 0 differs; and
//                     "saturates": |Omega| at which U_z reaches `reached_fraction` of C1,
//                     -ln(1 - fraction) / C2 with C2's interval, holds when the whole interval is
//                     inside the swept |Omega|, differs when all of it lies beyond. And "beyond":
//                     the runs past |Omega| = `beyond_abs_Omega` reach the surface (rising) or the
//                     floor (sinking): holds when every one did, differs when one ran at least
//                     `min_duration_s` without, inconclusive when one stopped earlier (a precision
//                     target) or did not finish. A branch with fewer than `min_points` conclusive
//                     points is inconclusive.
//   linear_in_A       eq. 9 per branch of `sweep`. Rising: the sweep's fit (core/fit.h: C3, and
//                     the range of A over which every point lies in the line's 3-sigma prediction
//                     band); holds when C3's interval (t, n - 1 dof) is above 0, every point is in
//                     the range and the points' chi^2 about the line (their own errors) has an
//                     upper tail >= 0.01; differs when C3's interval is below 0, a point leaves the
//                     band or chi^2 refuses the line. Sinking, when `sinking_linear_to_A` is set:
//                     the same law fitted to the points up to it; holds when they lie on their
//                     line (chi^2 tail >= 0.01) and the points past it + `break_tolerance_m` do
//                     not (chi^2 tail < 0.01 about the extrapolated line, its slope's error
//                     included); differs when the points up to it are not a line, or those past it
//                     stay on it. Inconclusive while C3's interval holds 0 (a line and a plateau
//                     cannot be told apart) or points are missing.
//   interior_maximum  the rising branch (Omega < 0) of `sweep` against f: the largest U_z must be
//                     at an interior f and above both edge values (their difference beyond the
//                     combined 95 % half-widths); then f_c (core/fit.h FitFastestRise) with its
//                     interval, f_c +- 1.96 stderr clipped to the neighbours' f, holds when it meets
//                     `f_c_hz` +- `f_c_tolerance_hz` (the paper read f_c off its grid of f), differs
//                     when not. The largest U_z at an edge, above its neighbour
//                     by more than their combined half-widths: differs ("no interior maximum in
//                     the swept range"). Otherwise inconclusive.
//   grain_count       the beds' grains against the paper's `paper_grains` in `paper_bed_m3`: each
//                     prepared bed's solid fraction (its grains' volume over the box below its
//                     surface, the SO's volume taken out; the surface at the highest grain centre
//                     + d/2, +- d) and the count that fraction gives in the paper's volume; holds
//                     when `paper_grains` lies within that interval widened by `tolerance_rel`,
//                     differs when outside, inconclusive with no prepared bed.
//   modes             Sec. 3.1 (Fig. 2): parts "rises" (sign rule, expect rise, on `rises`),
//                     "fastest" (`fastest`'s U_z above each of `fastest_among` by more than the
//                     combined half-widths, Bonferroni over them for differs), "stays near x"
//                     (every run of `fastest` drifts at most `x_within_m` in x), "z oscillates
//                     with an x component" (the smallest z amplitude at f of `z_osc_with` runs is
//                     at least `osc_ratio` times the largest of `z_osc_without`; differs when it is
//                     at most the largest), "x oscillates with a z component" (inconclusive: the
//                     run analysis does not measure x's amplitude at f).
// A point that has no conclusive U_z (its runs failed, are unfinished or inconclusive) is named
// with why in `missing`; a claim never holds with a point missing, and differs only on what the
// conclusive points show.
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
  std::string state;                     // queued | running | done | failed | cancelled
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
  std::string state;                 // queued | running | done | failed
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
};

struct ClaimPart {
  std::string name;
  Verdict verdict = Verdict::kInconclusive;
  std::string reason;  // why this verdict, in a sentence with its numbers
  std::vector<ClaimFigure> figures;
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
};

// One verdict per claim, in the claims' order.
std::vector<ClaimVerdict> EvaluateClaims(const std::vector<Claim>& claims, const ClaimInput& input);

// {"id","title","source","paper","rule","verdict","reason","parts":[{"name","verdict","reason",
//  "figures":[{"name","value"?,"stderr"?,"lo"?,"hi"?,"unit","verdict"?,"note"}]}],
//  "missing":[{"sweep","point","run_ids","why"}]}
nlohmann::json ClaimVerdictToJson(const ClaimVerdict& v);
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
