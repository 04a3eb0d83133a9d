#include "core/precision.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/api.h"
#include "core/text.h"
#include "core/trajectory.h"

namespace sandswim {
namespace {

using nlohmann::json;

Status CheckRange(const char* field, double v, double lo, double hi, const char* unit) {
  if (!std::isfinite(v) || v < lo || v > hi)
    return Status::InvalidArgument(
        field, "must be between " + Num(lo, 3) + " and " + Num(hi, 3) + unit + ", got " + Num(v, 3));
  return Status::Ok();
}

}  // namespace

bool operator==(const PrecisionTarget& a, const PrecisionTarget& b) {
  return a.uz_rel == b.uz_rel && a.uz_abs == b.uz_abs && a.min_periods == b.min_periods &&
         a.max_duration_s == b.max_duration_s;
}

Status Validate(const PrecisionTarget& t) {
  SANDSWIM_RETURN_IF_ERROR(CheckRange("uz_rel", t.uz_rel, 0, kMaxPrecisionRel, ""));
  SANDSWIM_RETURN_IF_ERROR(CheckRange("uz_abs", t.uz_abs, 0, kMaxPrecisionAbs, " m/s"));
  if (t.uz_rel == 0 && t.uz_abs == 0)
    return Status::InvalidArgument("uz_rel", "uz_rel and uz_abs cannot both be 0 (no interval is that narrow)");
  if (t.min_periods < kMinPrecisionPeriods || t.min_periods > kMaxPrecisionPeriods)
    return Status::InvalidArgument("min_periods", "must be an integer from " + std::to_string(kMinPrecisionPeriods) +
                                                      " (an interval needs three blocks) to " +
                                                      std::to_string(kMaxPrecisionPeriods) + ", got " +
                                                      std::to_string(t.min_periods));
  if (!std::isfinite(t.max_duration_s) || t.max_duration_s <= 0 || t.max_duration_s > kMaxDurationS)
    return Status::InvalidArgument(
        "max_duration_s", "must be > 0 s and <= " + Num(kMaxDurationS, 3) + " s, got " + Num(t.max_duration_s, 3));
  return Status::Ok();
}

json PrecisionToJson(const PrecisionTarget& t) {
  return {
      {"uz_rel", t.uz_rel}, {"uz_abs", t.uz_abs}, {"min_periods", t.min_periods}, {"max_duration_s", t.max_duration_s}};
}

Result<PrecisionTarget> PrecisionFromJson(const json& j) {
  if (!j.is_object()) return Status::InvalidArgument("", "must be an object");
  for (const auto& [key, value] : j.items()) {
    (void)value;
    if (key != "uz_rel" && key != "uz_abs" && key != "min_periods" && key != "max_duration_s")
      return Status::InvalidArgument(key.size() > 64 ? key.substr(0, 64) + "..." : key, "unknown field");
  }
  PrecisionTarget t;
  for (const char* key : {"uz_rel", "uz_abs", "max_duration_s"}) {
    auto it = j.find(key);
    if (it == j.end()) {
      if (std::string(key) == "max_duration_s") return Status::InvalidArgument(key, "is required");
      continue;
    }
    if (!it->is_number()) return Status::InvalidArgument(key, "must be a number");
    const double v = it->get<double>();
    if (std::string(key) == "uz_rel") t.uz_rel = v;
    if (std::string(key) == "uz_abs") t.uz_abs = v;
    if (std::string(key) == "max_duration_s") t.max_duration_s = v;
  }
  if (auto it = j.find("min_periods"); it != j.end()) {
    if (!it->is_number_integer()) return Status::InvalidArgument("min_periods", "must be an integer");
    const auto v = it->get<int64_t>();
    t.min_periods = static_cast<int>(std::clamp<int64_t>(v, -1, kMaxPrecisionPeriods + 1));
  }
  SANDSWIM_RETURN_IF_ERROR(Validate(t));
  return t;
}

Result<std::optional<PrecisionTarget>> StoredPrecision(const std::optional<std::string>& json_text) {
  if (!json_text) return std::optional<PrecisionTarget>();
  json j = json::parse(*json_text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return Status::Corruption("runs.precision: the stored precision target is not JSON");
  auto t = PrecisionFromJson(j);
  if (!t.ok()) return Status::Corruption("runs.precision: " + t.status().ToString());
  return std::optional<PrecisionTarget>(*t);
}

std::optional<PrecisionTarget> Tightest(const PrecisionTarget& a, const PrecisionTarget& b) {
  // A target is met when ci95 <= max(uz_rel |U_z|, uz_abs); a threshold of 0 adds nothing to the
  // max, so it is the strictest value. Key by key the smaller meets both targets:
  // max(min(r1, r2) |U|, min(a1, a2)) <= max(r_i |U|, a_i) for each i.
  PrecisionTarget t;
  t.uz_rel = std::min(a.uz_rel, b.uz_rel);
  t.uz_abs = std::min(a.uz_abs, b.uz_abs);
  t.min_periods = std::max(a.min_periods, b.min_periods);
  t.max_duration_s = std::max(a.max_duration_s, b.max_duration_s);
  if (t.uz_rel == 0 && t.uz_abs == 0) return std::nullopt;  // no interval is that narrow: run it whole
  return t;
}

double RunDuration(const Point& p, const std::optional<PrecisionTarget>& target) {
  if (!target) return p.duration_s;
  const WindowRule rule;
  const double block = p.has_vibration() ? 1.0 / p.f : rule.undriven_block_s;
  const double needed = TransientS(rule, block) + target->min_periods * block;
  return std::min(p.duration_s, std::max(target->max_duration_s, needed));
}

double EarliestTargetStopS(const Point& p, const PrecisionTarget& t) {
  const WindowRule rule;
  const double block = p.has_vibration() ? 1.0 / p.f : rule.undriven_block_s;
  const double earliest = TransientS(rule, block) + (t.min_periods + kMinBlocksAfterPilot) * block;
  return std::min(earliest, RunDuration(p, t));
}

bool TargetMet(const api::RunResult& r, const PrecisionTarget& t) {
  if (r.uz_blocks < t.min_periods || !r.uz || !r.uz_ci95) return false;
  const double allowed = std::max(t.uz_rel * std::fabs(*r.uz), t.uz_abs);
  return *r.uz_ci95 <= allowed;
}

std::optional<StopPlan> PlanStop(const std::vector<SoSample>& samples, const api::RunResult& so_far,
                                 const PrecisionTarget& t) {
  const int n0 = t.min_periods;
  if (n0 < 2 || so_far.uz_blocks < n0 || so_far.block_s <= 0 || samples.empty()) return std::nullopt;
  // The pilot: the window's first n0 blocks, which later samples never change.
  const BlockRate pilot = MeanBlockRate(samples, so_far.window_t0, so_far.block_s, n0, /*min_blocks_for_error=*/2);
  if (!pilot.se) return std::nullopt;
  StopPlan plan;
  plan.pilot_blocks = n0;
  plan.pilot_rate = pilot.rate;
  plan.pilot_sd = *pilot.se * std::sqrt(static_cast<double>(n0));
  plan.half_width = std::max(t.uz_rel * std::fabs(pilot.rate), t.uz_abs);
  // After the pilot: three blocks at least (an interval needs three), and as many as the pilot's
  // scatter asks for the half-width.
  constexpr int64_t kBeyond = kMaxPrecisionPeriods + 1;
  int64_t after = kBeyond;
  if (plan.half_width > 0) {
    const double needed = std::ceil(std::pow(StudentT95(n0 - 1) * plan.pilot_sd / plan.half_width, 2));
    after = needed >= static_cast<double>(kBeyond) ? kBeyond
                                                   : std::max<int64_t>(kMinBlocksAfterPilot, static_cast<int64_t>(needed));
  }
  plan.blocks_needed = n0 + after;
  return plan;
}

StopVerdict DecideStop(const api::RunResult& so_far, const std::optional<StopPlan>& plan) {
  if (plan && so_far.uz_blocks >= plan->blocks_needed) return StopVerdict::kTargetMet;
  if (so_far.window_end == "surface" || so_far.window_end == "floor") return StopVerdict::kWindowClosed;
  return StopVerdict::kContinue;
}

std::string DescribeStop(const api::RunResult& r, const std::optional<PrecisionTarget>& t,
                         const std::optional<StopPlan>& plan) {
  const std::string at = "at t = " + Num(r.sim_time_s, 3) + " s";
  // With a plan, the half-width its pilot asked for; else the target's at the result's rate.
  auto allowed_at = [&](double uz) {
    if (plan) return plan->half_width;
    return t ? std::max(t->uz_rel * std::fabs(uz), t->uz_abs) : 0.0;
  };
  auto interval = [&] {
    if (!r.uz_ci95 || !r.uz) return std::string("no interval yet");
    const double allowed = allowed_at(*r.uz);
    return "95 % interval +-" + Num(*r.uz_ci95, 3) + " m/s " + (*r.uz_ci95 <= allowed ? "<=" : ">") + " the target's " +
           Num(allowed, 3) + " m/s, " + std::to_string(r.uz_blocks) + " whole " + r.block_kind +
           (r.uz_blocks == 1 ? "" : "s");
  };
  // On the final analysis, which may hold more than the last look.
  const bool met = plan ? (r.uz_ci95 && *r.uz_ci95 <= plan->half_width) : (t && TargetMet(r, *t));
  if (r.stop_reason == "target") {
    std::string text = (met ? "precision target met " : "stopped for its precision target ") + at + ": " + interval();
    if (plan)
      text += " (two-stage: a pilot of " + std::to_string(plan->pilot_blocks) + " " + r.block_kind +
              "s, rate " + Num(plan->pilot_rate, 3) + " m/s, scatter " + Num(plan->pilot_sd, 3) + " m/s, asked " +
              std::to_string(plan->blocks_needed - plan->pilot_blocks) + " more for +-" + Num(plan->half_width, 3) +
              " m/s; U_z is theirs)";
    return text;
  }
  if (r.stop_reason == "window")
    return "stopped " + at + ": the steady window had closed (the SO came within the clearance of the " +
           (r.window_end.empty()        ? std::string("boundary")
            : r.window_end == "surface" ? "bed surface"
                                        : "floor") +
           "), so running on could not tighten U_z";
  if (r.stop_reason == "surface") return "the SO reached the bed surface " + at;
  if (r.stop_reason == "floor") return "the SO reached the floor " + at;
  if (t && met) return "ran to its maximum of " + Num(r.sim_time_s, 3) + " s, the precision target met: " + interval();
  if (t)
    return "ran to its maximum of " + Num(r.sim_time_s, 3) + " s without meeting the precision target: " + interval();
  return "ran its whole duration (" + Num(r.sim_time_s, 3) + " s)";
}

}  // namespace sandswim
