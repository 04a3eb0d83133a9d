// Replicate beds: one point's U_z over the K beds it ran on (SPEC.md "replicates").
//
// A point of a sweep with `replicates: K` runs once on each of K beds poured from K insertion
// seeds (core/deck.h BedSeedsFor). Its aggregate is taken over the replicates whose own U_z is
// conclusive (core/trajectory.h); inconclusive and unfinished ones are listed, not averaged:
//   - n >= 2: mean = the mean of the n rates; between-bed standard deviation s = sd(U_i) (n - 1
//     in the denominator); standard error s / sqrt(n).
//     Each U_i carries its bed and its own run's noise, so this error covers both; but it is never
//     smaller than the runs' own errors propagated to the mean, sqrt(sum se_i^2) / n (two or three
//     beds may agree by chance far more closely than their runs are precise; `note` says when
//     that floor was taken). The 95 % interval is t(0.975, n - 1) times the standard error.
//   - n == 1: the one run's U_z and its own error (within-run only): the scatter between beds is
//     not known, and `note` says so.
//   - n == 0: no value; inconclusive, `note` says why.
// The point is conclusive (`complete`) only when all K of its replicates are: a mean over the
// conclusive ones alone leans towards the beds that happened to run long enough (the fast ones meet
// the surface or the floor first), so it is never used as the point's value by fits or claims.
//
// The point as EVIDENCE over its K beds (the rule the claims use, core/claims.h "Points"). Each bed
// is one of
//   measured   conclusive, U_i with its own standard error and 95 % half-width;
//   censored   cut short at the surface (`censored` = +1) or the floor (-1) before enough whole
//              periods (the caller decides which runs are: core/claims.cc), with `bound`, a lower
//              bound on its |U_z| from distance over time;
//   open       anything else: failed, cancelled, queued, running, or done with neither.
// and the point is
//   measured   every bed measured: the value above (mean, between-bed error);
//   censored   every bed measured or censored, one at least censored. Nothing is dropped: its
//              `sign` is BedsSign's (below), and
//              `bound` the smallest of its censored beds' bounds; `uz_low` (with a
//              sign only) the mean over all K beds of the measured U_i and the censored beds'
//              sign * bound: each term is at most its bed's |U_z| in expectation, so |uz_low| is a
//              LOWER estimate of the point's |U_z| (for rules that can use one: a rule it would
//              favour must not take it);
//   open       a bed open: no evidence at all, whatever the other beds say (a failed or unfinished
//              bed keeps the point from deciding).
// `sign` is given for measured points too, by the same rule:
//   the SIGN of a point's beds (BedsSign) is +1 / -1 when their summed drift, the measured beds'
//   U_i plus each censored bed's boundary sign * bound, is clear of 0 by the measured beds' own
//   errors (sqrt(sum se_i^2), Student's t at the one-sided level with Welch-Satterthwaite's
//   degrees of freedom from each run's own) -- every censored term is at most its bed's |U_z|, so a
//   censored bed can only make the sign harder to show -- and no bed shows the other sign (a
//   measured bed by its own 95 % interval, a censored one by its boundary: beds that disagree
//   clearly say the sign is not the drive's); every bed censored at one boundary shows that one.
//   It is a statement about the K beds the point ran on (their own noise), not about beds never
//   poured: the scatter between beds moves a rate, rarely its sign, and a bed that differs in sign
//   stops it. With K = 1 it is the run's own 95 % interval.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_AGGREGATE_H_
#define SANDSWIM_CORE_AGGREGATE_H_

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/job_state.h"
#include "core/point.h"

namespace sandswim {

// One replicate of a point: its run, its bed, and the run's U_z as the run's result states it.
struct ReplicateValue {
  int64_t run_id = 0;
  int replicate = 0;  // the bed's replicate index (0 .. K-1)
  int64_t bed_id = 0;
  JobState state = JobState::kQueued;  // the run's state
  bool conclusive = false;          // its result's own verdict (false: no result yet)
  std::optional<double> uz;         // m/s
  std::optional<double> uz_stderr;  // m/s, its own standard error
  std::optional<double> uz_ci95;    // m/s, its own 95 % half-width
  // Not conclusive: cut short at the surface (+1) or the floor (-1), with `bound` (m/s), a lower
  // bound on its |U_z|; 0: not censored (the caller decides, see above).
  int censored = 0;
  double bound = 0;
};

struct ReplicateAggregate {
  int replicates = 0;                   // K: the replicates of the point (runs), finished or not
  int conclusive = 0;                   // n: those whose U_z is conclusive, which the aggregate is made of
  bool complete = false;                // n == K >= 1: the point is conclusive
  std::optional<double> uz_mean;        // m/s
  std::optional<double> uz_sd_between;  // m/s, n >= 2
  std::optional<double> uz_stderr;      // m/s: s / sqrt(n) or the runs' own (n >= 2), the run's own (n == 1)
  std::optional<double> uz_ci95;        // m/s, half-width
  std::string note;                     // what the aggregate rests on, when it is less than K beds
  bool bed_prior = false;               // K = 1: the error includes the scale's bed-to-bed prior
  std::vector<ReplicateValue> values;   // by replicate index
  // As evidence (the rule above).
  enum class Evidence { kMeasured, kCensored, kOpen };
  Evidence evidence = Evidence::kOpen;
  int censored_beds = 0;         // beds censored
  int open_beds = 0;             // beds that are neither measured nor censored
  int sign = 0;                  // +1 / -1: every bed shows it; 0: not every bed, or a bed open
  std::optional<double> bound;   // m/s, censored points: the smallest censored bed's bound on |U_z|
  std::optional<double> uz_low;  // m/s, censored points with a sign: the lower estimate of U_z
};

// The degrees of freedom a 95 % interval of half-width `ci95` around a value of standard error `se`
// was made with: ci95 / se = t(0.975, dof); 1e7 (normal) when the ratio is a normal quantile's or
// less, 0.5 when it is wider than t(0.975, 0.5)'s or not finite (se = 0, NaN): the fewest.
double DofOfInterval(double se, double ci95);

// DofOfInterval's answer and the t quantiles it evaluated to find it: a results page finds one for
// each of its runs (a page of 10,000), so the count is what its cost is held to (aggregate_test.cc).
struct DofSearch {
  double dof = 0;
  int quantiles = 0;
};
DofSearch SearchDofOfInterval(double se, double ci95);

// `bed_sd_rel` (the scale's Scale::bed_sd_rel, 0: none): a point run on one bed only (K = 1) gets
// the bed-to-bed scatter added to its run's own error, se^2 + (bed_sd_rel U)^2, and to its 95 %
// half-width, ci^2 + (1.96 bed_sd_rel U)^2: one bed's interval says nothing of the bed it happened
// to be (on the truth engine such intervals held the true U_z 71 % of the time). With K >= 2 the
// beds' own scatter is measured and used instead.
ReplicateAggregate AggregateReplicates(std::vector<ReplicateValue> values, double bed_sd_rel = 0);

// The sign the beds show at one-sided level `tail` (0.025: the 95 % rule above; the claims widen it
// to a family-wise level, 0.025 / m): +1, -1 or 0 (not shown, beds that disagree, or a bed open).
int BedsSign(const std::vector<ReplicateValue>& values, double tail);

// A sweep's runs grouped by point (SameDrive: a point's replicates differ only in their bed),
// each group aggregated, in the order the points first appear.
struct PointAggregate {
  Point point;
  ReplicateAggregate aggregate;
};
std::vector<PointAggregate> AggregateByPoint(const std::vector<std::pair<Point, ReplicateValue>>& runs);

// "0.052 ± 0.006 m/s, 3 of 3 beds (between-bed sd 0.01 m/s)" (± the standard error, as a run's
// DescribeUz); "0.0500 ± 0.0020 m/s, 1 of 2 beds: between-bed scatter unknown";
// "inconclusive (0 of 2 beds conclusive)". `with_units` = false leaves out " m/s".
std::string DescribeAggregate(const ReplicateAggregate& a, bool with_units = true);

// {"replicates","conclusive","uz_text","uz_mean"?,"uz_sd_between"?,"uz_stderr"?,"uz_ci95"?,"note",
//  "values":[{"run_id","replicate","bed_id","state","conclusive","uz"?,"uz_ci95"?}]}
nlohmann::json AggregateToJson(const ReplicateAggregate& a);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_AGGREGATE_H_
