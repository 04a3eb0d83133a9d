// Precision target: how tight a run's U_z interval must be before the run may end (SPEC.md
// "precision target"), and the rule a worker applies to the growing trajectory to end it.
//
// A run with a target lasts at most RunDuration() and ends earlier, cleanly (the deck reads a
// control file every chunk, core/deck.h), when DecideStop() says so. The rule is two-stage (after
// Stein, 1945), because stopping as soon as the interval *looks* narrow enough is optional
// stopping: with 2-4 degrees of freedom an interval looks narrow mostly when its blocks happened to
// scatter little. Stopped that way, runs whose target was tight for their scatter held the truth in
// their 95 % interval 61 % and 83 % of the time (tests/bench/bench_precision_coverage.cc: per-period
// scatter 20 % and 38 % of the rate, uz_rel 0.1 and 0.25; 69 and 206 stopped runs). Instead:
//   - pilot: once the steady window holds n0 = min_periods whole blocks, their block rates give a
//     rate u0 and a scatter s0 (n0 - 1 degrees of freedom), which fix the half-width the target
//     asks for,
//       h = max(uz_rel * |u0|, uz_abs)
//     (uz_rel alone is unreachable for a rate near 0; uz_abs alone ignores the rate's size: either
//     may be 0, not both), and the whole blocks the run holds in all,
//       N = n0 + max(3, ceil((t(0.975, n0 - 1) * s0 / h)^2)).
//   - "target": the window holds at least N whole blocks.
//   - "window": the window has closed -- the SO came within the clearance of the bed surface or
//     the floor (core/trajectory.h WindowRule), so no later sample can tighten the interval.
// A run that stopped for its target (core/trajectory.h AnalyzeRun) takes U_z, its standard error
// and its 95 % interval from the m >= 3 blocks after its pilot alone. The pilot only plans: it
// decided how many more blocks to run, so a run stopped early is one whose pilot came out calm (or
// fast); its own scatter or rate in the estimate would carry that luck into the interval. The
// blocks after it are chosen by the pilot's numbers only, so their t interval (m - 1 degrees of
// freedom) holds the truth 95 % of the time whatever m came out, early stop or not, when block
// rates are independent and normal. Their interval meets h on average, not always: precision_met
// says whether it did.
// A larger pilot costs fewer blocks after it (t(0.975, 2) = 4.30, t(0.975, 4) = 2.78):
// min_periods is the user's trade between the two.
// Without a target a run lasts its whole duration (or until the SO is at a boundary).
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_PRECISION_H_
#define SANDSWIM_CORE_PRECISION_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/point.h"
#include "core/status.h"

namespace sandswim {
namespace api {
struct RunResult;  // core/api.h, which carries a target in its lease grant
}  // namespace api
struct SoSample;  // core/trajectory.h

// Caps stated in every refusal.
inline constexpr int kMinPrecisionPeriods = 3;  // an interval needs three blocks (trajectory.h)
inline constexpr int kMaxPrecisionPeriods = 10000;
inline constexpr double kMaxPrecisionRel = 10.0;
inline constexpr double kMaxPrecisionAbs = 10.0;  // m/s

struct PrecisionTarget {
  double uz_rel = 0;                       // the interval's half-width relative to |U_z|
  double uz_abs = 0;                       // m/s, the half-width in absolute terms
  int min_periods = kMinPrecisionPeriods;  // whole blocks the window holds before it may end
  double max_duration_s = 0;               // s of physical time at most (see RunDuration)
};
bool operator==(const PrecisionTarget& a, const PrecisionTarget& b);
inline bool operator!=(const PrecisionTarget& a, const PrecisionTarget& b) { return !(a == b); }

// Finite, in range, and not both thresholds 0. Errors name the field ("uz_rel", ...).
Status Validate(const PrecisionTarget& t);

// JSON as a sweep writes it: {"uz_rel", "uz_abs", "min_periods", "max_duration_s"}, every key
// present (the stored form is the same).
nlohmann::json PrecisionToJson(const PrecisionTarget& t);
// Unknown keys, wrong types and bad values are refused naming the key. Absent keys take the
// defaults above, except max_duration_s, which is required.
Result<PrecisionTarget> PrecisionFromJson(const nlohmann::json& j);

// A target as the database stores it (JSON text, absent: none): Corruption naming the column when
// it no longer parses.
Result<std::optional<PrecisionTarget>> StoredPrecision(const std::optional<std::string>& json_text);

// A target that meets both (a point two sweeps share runs once, to both): key by key the smaller
// threshold (0 being the strictest: it adds nothing to the max), the more periods, the longer
// maximum. nullopt when both thresholds come out 0 (one sweep asked only for a relative width,
// the other only for an absolute one): no target can say both, so the run lasts its duration.
std::optional<PrecisionTarget> Tightest(const PrecisionTarget& a, const PrecisionTarget& b);

// Physical time a run of `p` lasts at most. Without a target: the duration asked. With one: the
// target's maximum, but never shorter than the start-up transient plus min_periods whole blocks,
// and never longer than the duration asked. (A maximum that leaves no room for the three blocks
// after the pilot lets the run last it: a run of fixed length, whose interval needs no correction.
// Unchanged by the two-stage rule, so that no deck or run key changed with it.)
double RunDuration(const Point& p, const std::optional<PrecisionTarget>& target);

// The earliest physical time a run of `p` can end for its target: the start-up transient, the
// pilot's min_periods blocks and the three blocks the two-stage rule asks after it at least
// (kMinBlocksAfterPilot; PlanStop). Never later than RunDuration. A "window" stop at a boundary
// may come sooner, as it may for a run without a target.
inline constexpr int kMinBlocksAfterPilot = 3;
double EarliestTargetStopS(const Point& p, const PrecisionTarget& t);

// Whether the interval of `r` meets the target's half-width at r's own rate (false when r has
// fewer blocks than min_periods or no interval): what a result reports as precision_met.
bool TargetMet(const api::RunResult& r, const PrecisionTarget& t);

// The two-stage plan a run's pilot fixes (see above).
struct StopPlan {
  int pilot_blocks = 0;    // n0
  double pilot_rate = 0;   // m/s, u0
  double pilot_sd = 0;     // m/s, s0: the pilot's block rates' standard deviation
  double half_width = 0;   // m/s, h
  int64_t blocks_needed = 0;  // N, the pilot's included (at most n0 + kMaxPrecisionPeriods + 1: unreachable)
};
// The plan of a run analysed so far (`so_far` = AnalyzeRun of `samples`): nullopt until its
// window holds min_periods whole blocks.
std::optional<StopPlan> PlanStop(const std::vector<SoSample>& samples, const api::RunResult& so_far,
                                 const PrecisionTarget& t);
// What the worker does with a run it follows, from the analysis of the trajectory so far and its
// plan (nullopt before the pilot is complete).
enum class StopVerdict { kContinue, kTargetMet, kWindowClosed };
StopVerdict DecideStop(const api::RunResult& so_far, const std::optional<StopPlan>& plan);

// One sentence on why a run ended, for its result: the engine's stop reason ("duration",
// "surface", "floor", "target", "window") with the figures behind it.
// `plan`, when given, adds the two-stage numbers.
std::string DescribeStop(const api::RunResult& r, const std::optional<PrecisionTarget>& t,
                         const std::optional<StopPlan>& plan = std::nullopt);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_PRECISION_H_
