#include "core/cost.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace sandswim {
EngineRate DefaultRate() {
  return {kDefaultSecondsPerParticleStep, kDefaultRateRelError, 0,
          "default rate (1.5e6 particle-steps/s, one core of a 2-core machine), no run measured yet"};
}

EngineRate DefaultBedRate() {
  return {kDefaultBedSecondsPerGrain, kDefaultRateRelError, 0,
          "default bed rate (a smoke bed in 12.8 minutes on one core), no bed measured yet"};
}

EngineRate BedRateOnRanks(const std::vector<RankRate>& by_ranks, int ranks) {
  ranks = std::max(ranks, 1);
  EngineRate one = DefaultBedRate();
  for (const RankRate& r : by_ranks) {
    if (r.ranks == ranks) return r.rate;
    if (r.ranks == 1) one = r.rate;
  }
  if (ranks == 1) return one;
  const double speedup = std::pow(kDefaultTwoRankSpeedup, std::log2(static_cast<double>(ranks)));
  EngineRate r = one;
  r.s_per_unit = one.s_per_unit / speedup;
  r.rel_error = std::hypot(one.rel_error, kDefaultRateRelError);
  char guess[160];
  std::snprintf(guess, sizeof guess,
                "; on %d ranks %.3gx faster (no bed measured on %d ranks: %.3gx a doubling of ranks, a guess)", ranks,
                speedup, ranks, kDefaultTwoRankSpeedup);
  r.basis = one.basis + guess;
  return r;
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

namespace {

// Total wall over total work of the samples that did work; 0 when none did.
double PooledSecondsPerUnit(const std::vector<RateSample>& samples, double min_wall_s, int* used, double* longest) {
  double work = 0, wall = 0;
  for (const RateSample& s : samples) {
    if (!(s.work > 0) || !(s.wall_s >= min_wall_s) || !std::isfinite(s.work) || !std::isfinite(s.wall_s)) continue;
    work += s.work;
    wall += s.wall_s;
    if (used) ++*used;
    if (longest) *longest = std::max(*longest, s.wall_s);
  }
  return work > 0 ? wall / work : 0;
}

std::string Minutes(double s) {
  char out[32];
  std::snprintf(out, sizeof out, "%.0f min", std::max(1.0, std::round(s / 60)));
  return out;
}

}  // namespace

Share CurrentShare(const std::vector<RateSample>& recent, const std::vector<RateSample>& before,
                   const std::vector<RateSample>& so_far, const EngineRate& model, double window_s) {
  Share share;
  if (!(model.s_per_unit > 0)) return share;
  int engines = 0;
  double longest = 0;
  const double now = PooledSecondsPerUnit(recent, kMinShareStretchS, &engines, &longest);
  // A factor that is not a finite positive number (an overflowing or degenerate pool) is no share.
  if (!(now > 0) || !std::isfinite(now / model.s_per_unit)) return share;
  share.measured = true;
  share.factor = now / model.s_per_unit;
  share.scale = std::sqrt(share.factor);
  share.rel_error = std::abs(std::log(share.factor)) / 2;
  share.engines = engines;
  share.window_s = std::min(longest, window_s);
  double then = PooledSecondsPerUnit(before, kMinShareStretchS, nullptr, nullptr);
  share.before_basis = "the " + Minutes(window_s) + " before";
  if (!(then > 0)) {
    then = PooledSecondsPerUnit(so_far, 0, nullptr, nullptr);
    share.before_basis = "their attempts so far";
  }
  if (then > 0) {
    share.factor_before = then / model.s_per_unit;
    share.rel_error = std::hypot(share.rel_error, std::log(now / then));
  }
  return share;
}

EngineRate AtShare(const EngineRate& rate, const Share& share) {
  if (!share.measured) return rate;
  EngineRate r = rate;
  r.s_per_unit = rate.s_per_unit * share.scale;
  r.rel_error = std::hypot(rate.rel_error, share.rel_error);
  char text[200];
  std::snprintf(text, sizeof text, "; now %d engine%s at %.2f of that rate over the last %s", share.engines,
                share.engines == 1 ? "" : "s", 1 / share.factor, Minutes(share.window_s).c_str());
  r.basis += text;
  if (share.factor_before) {
    std::snprintf(text, sizeof text, " (%.2f over %s)", 1 / *share.factor_before, share.before_basis.c_str());
    r.basis += text;
  }
  std::snprintf(text, sizeof text, "; taken halfway: %.2f, ± %.0f %% for the share", 1 / share.scale,
                100 * share.rel_error);
  r.basis += text;
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
  c.run_rel_error = run_rate.rel_error;
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
    c.bed_work.push_back(bed_grains[i] * bed_step_factor[i]);
    const double s = c.bed_work.back() * bed_rate.s_per_unit;
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

std::vector<int> BedRanks(int beds, int slots, int max_ranks) {
  std::vector<int> ranks(static_cast<size_t>(std::max(beds, 0)), 1);
  if (beds >= 1 && beds <= slots) ranks.back() = std::clamp(slots - beds + 1, 1, std::max(max_ranks, 1));
  return ranks;
}

PlanWall PlanWallOn(const PlanCost& cost, int slots, int max_ranks, const std::vector<RankRate>& bed_rates) {
  slots = std::max(slots, 1);
  PlanWall w;
  w.bed_ranks = BedRanks(static_cast<int>(cost.bed_work.size()), slots, max_ranks);
  // Beds in one wave (as many as the slots) end with the slowest; more beds than slots share them.
  double beds_s = 0, bed_core_s = 0, longest_bed = 0, bed_sigma = 0;
  for (size_t i = 0; i < cost.bed_work.size(); ++i) {
    const EngineRate rate = BedRateOnRanks(bed_rates, w.bed_ranks[i]);
    const double s = cost.bed_work[i] * rate.s_per_unit;
    bed_core_s += s;
    if (s > longest_bed) {
      longest_bed = s;
      bed_sigma = rate.rel_error;
    }
  }
  beds_s = cost.bed_work.size() <= static_cast<size_t>(slots) ? longest_bed : std::max(longest_bed, bed_core_s / slots);
  const double runs_s = cost.run_core_s / slots;
  w.s = std::max(beds_s + runs_s, longest_bed + cost.longest_run_s);
  if (w.s > 0) w.rel_error = std::hypot(cost.run_rel_error * runs_s, bed_sigma * beds_s) / (beds_s + runs_s);
  return w;
}

std::optional<Eta> EstimateEta(const std::vector<WorkLeft>& left, const EngineRate& run_rate,
                               const EngineRate& bed_rate, const StepShare& share, int slots) {
  if (left.empty()) return std::nullopt;
  slots = std::max(slots, 1);
  const bool measured = share.done > 0 && std::isfinite(share.mean) && std::isfinite(share.sd);
  const double mean = measured ? std::clamp(share.mean, 0.0, 1.0) : 1.0;
  // A scatter measured on few runs is often too small (with 2 runs, it is below its true value
  // half the time by a factor of 1.5 or more): widened by Student's t at one sigma for done - 1
  // degrees of freedom (Cornish-Fisher to 1/dof^3: 1.81 for 1, 1.33 for 2, 1.05 for 10).
  const double dof = measured ? static_cast<double>(share.done - 1) : 0.0;
  const double t_one_sigma = dof >= 1 ? 1 + 0.5 / dof + 0.25 / (dof * dof) + 0.0625 / (dof * dof * dof) : 1.0;
  const double sd = measured ? std::max(0.0, share.sd) * t_one_sigma : 0.0;
  double run_s = 0, bed_s = 0, longest_run = 0, longest_bed = 0;
  double shared_sigma = 0;  // s: errors every run shares (summed), and each run's own (in quadrature)
  double own_var = 0;
  bool ranged = false;  // some run has a precision target
  for (const WorkLeft& w : left) {
    if (w.kind == WorkLeft::Kind::kBed) {
      const double s = std::max(0.0, w.particles * bed_rate.s_per_unit - (w.running ? w.elapsed_s : 0.0));
      bed_s += s;
      longest_bed = std::max(longest_bed, s);
      continue;
    }
    const double steps = static_cast<double>(w.steps), done = static_cast<double>(w.steps_done);
    const double s_per_step = w.particles * run_rate.s_per_unit;
    if (done >= steps) continue;
    ranged = ranged || w.min_steps > 0;
    // Where it may end: a target's range, or (share measured) anywhere from here on.
    const double lo = std::max(done, w.min_steps > 0 ? std::min(static_cast<double>(w.min_steps), steps)
                                                     : (measured ? done : steps));
    const double half_range = (steps - lo) / 2;
    double expected = steps, shared = 0, own = 0;
    if (!measured) {
      expected = lo + half_range;
      shared = 2 * half_range / std::sqrt(12.0);
    } else if (done > 0 && done >= steps * mean) {
      expected = lo + half_range;  // it outlived the share: somewhere in the rest of its range
      own = 2 * half_range / std::sqrt(12.0);
    } else {
      expected = std::clamp(steps * mean, lo, steps);
      own = std::min(sd * steps, half_range);
      shared = std::min(sd * steps / std::sqrt(static_cast<double>(share.done)), half_range);
    }
    const double s = (expected - done) * s_per_step;
    run_s += s;
    longest_run = std::max(longest_run, s);
    shared_sigma += shared * s_per_step;
    own_var += own * s_per_step * own * s_per_step;
  }
  Eta eta;
  // As PlanCost::WallSeconds: the beds first (runs wait for theirs), then the runs over every slot.
  eta.seconds = std::max(std::max(bed_s / slots, longest_bed) + run_s / slots, longest_bed + longest_run);
  const double total = run_s + bed_s;
  const double rate_error =
      total > 0 ? std::hypot(run_rate.rel_error * run_s, bed_rate.rel_error * bed_s) / total : run_rate.rel_error;
  const double length_sigma = std::hypot(shared_sigma, std::sqrt(own_var));  // core-s, of run_s
  eta.rel_error = std::hypot(rate_error, total > 0 ? length_sigma / total : 0.0);
  eta.basis = run_rate.basis;
  if (bed_s > 0) eta.basis += "; beds: " + bed_rate.basis;
  if (measured) {
    eta.basis += "; runs left expected to use " + std::to_string(static_cast<int>(std::lround(mean * 100))) +
                 " % of their steps, as the done ones did";
  } else if (ranged) {
    eta.basis += "; runs with a precision target expected halfway between their earliest stop and their deck's end";
  } else {
    eta.basis += "; queued runs counted to their deck's end";
  }
  return eta;
}

}  // namespace sandswim
