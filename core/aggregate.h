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
// the surface or the floor first), so it is shown, never used as the point's value by fits or
// claims (core/claims.h states what a claim does with the other beds).
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

#include "core/point.h"

namespace sandswim {

// One replicate of a point: its run, its bed, and the run's U_z as the run's result states it.
struct ReplicateValue {
  int64_t run_id = 0;
  int replicate = 0;  // the bed's replicate index (0 .. K-1)
  int64_t bed_id = 0;
  std::string state;                // the run's state: queued | running | done | failed | cancelled
  bool conclusive = false;          // its result's own verdict (false: no result yet)
  std::optional<double> uz;         // m/s
  std::optional<double> uz_stderr;  // m/s, its own standard error
  std::optional<double> uz_ci95;    // m/s, its own 95 % half-width
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
};

// `bed_sd_rel` (the scale's Scale::bed_sd_rel, 0: none): a point run on one bed only (K = 1) gets
// the bed-to-bed scatter added to its run's own error, se^2 + (bed_sd_rel U)^2, and to its 95 %
// half-width, ci^2 + (1.96 bed_sd_rel U)^2: one bed's interval says nothing of the bed it happened
// to be (on the truth engine such intervals held the true U_z 71 % of the time). With K >= 2 the
// beds' own scatter is measured and used instead.
ReplicateAggregate AggregateReplicates(std::vector<ReplicateValue> values, double bed_sd_rel = 0);

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
