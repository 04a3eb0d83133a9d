// Precision target: how tight a run's U_z interval must be before the run may end (SPEC.md
// "precision target"), and the rule a worker applies to the growing trajectory to end it.
//
// A run with a target lasts at most RunDuration() and ends earlier, cleanly (the deck reads a
// control file every chunk, core/deck.h), as soon as DecideStop() says so:
//   - "target": the steady window holds at least min_periods whole blocks (and at least the
//     blocks an error needs) and the 95 % interval's half-width is within the target,
//       ci95 <= max(uz_rel * |U_z|, uz_abs)
//     (uz_rel alone is unreachable for a rate near 0; uz_abs alone ignores the rate's size:
//     either may be 0, not both);
//   - "window": the window has closed -- the SO came within the clearance of the bed surface or
//     the floor (core/trajectory.h WindowRule), so no later sample can tighten the interval.
// Without a target a run lasts its whole duration (or until the SO is at a boundary).
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_PRECISION_H_
#define SANDSWIM_CORE_PRECISION_H_

#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "core/point.h"
#include "core/status.h"

namespace sandswim {
namespace api {
struct RunResult;  // core/api.h, which carries a target in its lease grant
}  // namespace api

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
// target's maximum, but never shorter than the start-up transient plus min_periods whole blocks
// (else the target could never be met), and never longer than the duration asked.
double RunDuration(const Point& p, const std::optional<PrecisionTarget>& target);

// Whether the interval of `r` meets the target (false when r has fewer blocks than min_periods
// or no interval).
bool TargetMet(const api::RunResult& r, const PrecisionTarget& t);

// What the worker does with a run it follows, from the analysis of the trajectory so far.
enum class StopVerdict { kContinue, kTargetMet, kWindowClosed };
StopVerdict DecideStop(const api::RunResult& so_far, const PrecisionTarget& t);

// One sentence on why a run ended, for its result: the engine's stop reason ("duration",
// "surface", "floor", "target", "window") with the figures behind it.
std::string DescribeStop(const api::RunResult& r, const std::optional<PrecisionTarget>& t);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_PRECISION_H_
