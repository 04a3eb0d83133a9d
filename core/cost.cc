#include "core/cost.h"

#include <algorithm>
#include <cmath>

namespace sandswim {
EngineRate DefaultRate() {
  return {kDefaultSecondsPerParticleStep, kDefaultRateRelError, 0,
          "default rate (1.5e6 particle-steps/s, one core of a 2-core machine), no run measured yet"};
}

EngineRate DefaultBedRate() {
  return {kDefaultBedSecondsPerGrain, kDefaultRateRelError, 0,
          "default bed rate (a smoke bed in 12.8 minutes on one core), no bed measured yet"};
}

EngineRate FitRate(const std::vector<RateSample>& samples, const EngineRate& fallback, const std::string& basis) {
  double work = 0, wall = 0;
  std::vector<double> logs;
  for (const RateSample& s : samples) {
    if (!(s.work > 0) || !(s.wall_s > 0) || !std::isfinite(s.work) || !std::isfinite(s.wall_s)) continue;
    work += s.work;
    wall += s.wall_s;
    logs.push_back(std::log(s.wall_s / s.work));
  }
  if (logs.empty()) return fallback;
  EngineRate r;
  r.s_per_unit = wall / work;
  r.samples = static_cast<int>(logs.size());
  r.basis = basis;
  if (logs.size() == 1) {
    r.rel_error = std::max(kMinRateRelError, fallback.rel_error / 2);
    return r;
  }
  double mean = 0;
  for (double l : logs) mean += l;
  mean /= static_cast<double>(logs.size());
  double ss = 0;
  for (double l : logs) ss += (l - mean) * (l - mean);
  const double sd = std::sqrt(ss / static_cast<double>(logs.size() - 1));  // of log rate: relative
  r.rel_error = std::max(kMinRateRelError, sd / std::sqrt(static_cast<double>(logs.size())));
  return r;
}

double PlanCost::WallSeconds(int slots) const {
  slots = std::max(slots, 1);
  // Beds share the slots with each other first; their runs then share every slot.
  const double beds_s = std::max(longest_bed_s, bed_core_s / slots);
  const double runs_s = run_core_s / slots;
  return std::max(beds_s + runs_s, longest_bed_s + longest_run_s);
}

PlanCost CostOfPlan(const Plan& plan, const std::vector<std::optional<double>>& known_grains,
                    const EngineRate& run_rate, const EngineRate& bed_rate) {
  const Scale& scale = FindScale(plan.scale) ? *FindScale(plan.scale) : *FindScale("smoke");
  const double estimate = EstimatedGrains(scale);
  std::vector<double> bed_grains;
  // A bed's preparation takes as many more steps as its step is shorter than Table 1's (the bed
  // rate is per grain of a Table 1 bed); its runs' steps are in their step counts already.
  std::vector<double> bed_step_factor;
  for (size_t i = 0; i < plan.beds.size(); ++i) {
    const Materials& m = plan.beds[i].materials;
    bed_grains.push_back(i < known_grains.size() && known_grains[i] ? *known_grains[i] : EstimatedGrains(scale, m));
    bed_step_factor.push_back(kMaterials.dt / TimeStep(m));
  }
  PlanCost c;
  c.runs = static_cast<int64_t>(plan.runs.size());
  c.beds = static_cast<int64_t>(bed_grains.size());
  for (const PlannedRun& r : plan.runs) {
    const size_t bed = static_cast<size_t>(r.bed);
    const double particles = (bed < bed_grains.size() ? bed_grains[bed] : estimate) + 1;
    const double ps = static_cast<double>(r.steps) * particles;
    c.particle_steps += ps;
    c.longest_run_s = std::max(c.longest_run_s, ps * run_rate.s_per_unit);
  }
  c.run_core_s = c.particle_steps * run_rate.s_per_unit;
  for (size_t i = 0; i < bed_grains.size(); ++i) {
    const double s = bed_grains[i] * bed_step_factor[i] * bed_rate.s_per_unit;
    c.bed_core_s += s;
    c.longest_bed_s = std::max(c.longest_bed_s, s);
  }
  // The two rates' errors weighted by the share of time each accounts for (each is one
  // systematic error over all its items: a host's rate does not average out over runs).
  const double total = c.run_core_s + c.bed_core_s;
  if (total > 0)
    c.rel_error = std::hypot(run_rate.rel_error * c.run_core_s, bed_rate.rel_error * c.bed_core_s) / total;
  return c;
}

std::optional<Eta> EstimateEta(const std::vector<WorkLeft>& left, const EngineRate& run_rate,
                               const EngineRate& bed_rate, double expected_fraction, double fraction_rel_error,
                               int slots) {
  if (left.empty()) return std::nullopt;
  slots = std::max(slots, 1);
  expected_fraction = std::clamp(std::isfinite(expected_fraction) ? expected_fraction : 1.0, 0.0, 1.0);
  double run_s = 0, bed_s = 0, longest_run = 0, longest_bed = 0;
  for (const WorkLeft& w : left) {
    double s = 0;
    if (w.kind == WorkLeft::Kind::kBed) {
      s = std::max(0.0, w.particles * bed_rate.s_per_unit - (w.running ? w.elapsed_s : 0.0));
      bed_s += s;
      longest_bed = std::max(longest_bed, s);
    } else {
      const double expected_steps = std::max(static_cast<double>(w.steps) * expected_fraction,
                                             static_cast<double>(w.steps_done));
      const double steps_left = std::max(0.0, std::min(static_cast<double>(w.steps), expected_steps) -
                                                  static_cast<double>(w.steps_done));
      s = steps_left * w.particles * run_rate.s_per_unit;
      run_s += s;
      longest_run = std::max(longest_run, s);
    }
  }
  Eta eta;
  // As PlanCost::WallSeconds: the beds first (runs wait for theirs), then the runs over every slot.
  eta.seconds = std::max(std::max(bed_s / slots, longest_bed) + run_s / slots, longest_bed + longest_run);
  const double total = run_s + bed_s;
  const double rate_error =
      total > 0 ? std::hypot(run_rate.rel_error * run_s, bed_rate.rel_error * bed_s) / total : run_rate.rel_error;
  eta.rel_error = std::hypot(rate_error, total > 0 ? fraction_rel_error * run_s / total : 0.0);
  eta.basis = run_rate.basis;
  if (bed_s > 0) eta.basis += "; beds: " + bed_rate.basis;
  if (expected_fraction < 1) {
    eta.basis += "; queued runs expected to use " + std::to_string(static_cast<int>(std::lround(expected_fraction * 100))) +
                 " % of their steps, as the done ones did";
  } else {
    eta.basis += "; queued runs counted to their deck's end";
  }
  return eta;
}

}  // namespace sandswim
