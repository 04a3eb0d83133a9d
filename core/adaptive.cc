#include "core/adaptive.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "core/job_state.h"
#include "core/branch.h"
#include "core/materials.h"
#include "core/text.h"
#include "core/trajectory.h"

namespace sandswim {

double AdaptiveCost::RunCoreHours(const Point& p, double max_duration_s) const {
  const double steps = std::ceil(max_duration_s / DriveStep(p));
  return steps * (EstimatedGrains(*scale, p.materials) + 1) * run_rate.s_per_unit / 3600;
}

double AdaptiveCost::BedCoreHours(const Point& p) const {
  return EstimatedGrains(*scale, p.materials) * (kMaterials.dt / TimeStep(p.materials)) * bed_rate.s_per_unit / 3600;
}

const char* ActionKindName(ActionKind kind) {
  switch (kind) {
    case ActionKind::kFirstRound: return "first round";
    case ActionKind::kReplicate: return "replicate";
    case ActionKind::kLonger: return "longer";
    case ActionKind::kNewPoint: return "new point";
  }
  return "?";
}

namespace {

bool IsRising(const Point& p) { return BranchOf(p) == Branch::kRising; }

double BaseMaxDuration(const Point& p, const Scale& scale) { return RunDuration(p, scale.default_precision); }

std::string Join(const std::vector<std::string>& v, const std::string& sep) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) s += (i ? sep : "") + v[i];
  return s;
}

std::string CoreH(double h) { return Num(h, h < 10 ? 2 : 3) + " core-h"; }

// Adds the orders' runs and beds to an action's cost.
void Cost(AdaptiveAction& a, const AdaptiveCost& cost, int beds_now) {
  a.core_h = a.sim_s = 0;
  a.new_beds = 0;
  std::set<int> new_beds;
  for (const RunOrder& o : a.runs) {
    a.core_h += cost.RunCoreHours(o.point, o.max_duration_s);
    a.sim_s += o.max_duration_s;
    if (o.replicate >= beds_now && new_beds.insert(o.replicate).second) a.core_h += cost.BedCoreHours(o.point);
  }
  a.new_beds = static_cast<int>(new_beds.size());
}


// The sweeps a claim's rule names: every string (or string in an array) of the rule that is a
// declared sweep's name.
std::vector<std::string> SweepsOfClaim(const Claim& c, const std::vector<AdaptiveSweep>& sweeps) {
  std::vector<std::string> out;
  auto consider = [&](const nlohmann::json& v) {
    if (!v.is_string()) return;
    const std::string s = v.get<std::string>();
    for (const AdaptiveSweep& sw : sweeps)
      if (sw.name == s && std::find(out.begin(), out.end(), s) == out.end()) out.push_back(s);
  };
  if (!c.rule.is_object()) return out;
  for (const auto& [key, v] : c.rule.items()) {
    if (key == "kind") continue;
    if (v.is_array())
      for (const nlohmann::json& e : v) consider(e);
    else
      consider(v);
  }
  return out;
}

// One point of the claim's sweeps with its runs (one per bed) and what they say.
struct PointInfo {
  std::string sweep;
  Point point;
  std::vector<const ClaimRun*> runs;  // one per replicate
  int beds() const {
    int k = 0;
    for (const ClaimRun* r : runs) k = std::max(k, r->replicate + 1);
    return k;
  }
  bool all_measured = true;
  int measured = 0;
  double mean = 0, bed_sd = 0;  // over measured runs; bed_sd 0: not measured (K < 2)
  double mean_se = 0;           // of the measured runs' own errors, rms
  const ClaimRun* boundary = nullptr;  // a run that reached the surface or the floor unmeasured
  double z_amp = 0;
  std::optional<double> x_amp;
  double x_drift = 0, x_drift_sd = 0;
};

std::vector<PointInfo> PointsOf(const ClaimInput& in, const std::vector<std::string>& sweeps) {
  std::vector<PointInfo> out;
  std::map<DriveId, size_t> index;
  for (const std::string& name : sweeps) {
    for (const ClaimSweep& s : in.sweeps) {
      if (s.name != name) continue;
      for (const ClaimRun& r : s.runs) {
        auto [it, inserted] = index.emplace(DriveIdOf(r.point), out.size());
        if (inserted) {
          PointInfo p;
          p.sweep = name;
          p.point = r.point;
          out.push_back(std::move(p));
        }
        PointInfo& p = out[it->second];
        bool seen = false;
        for (const ClaimRun* q : p.runs) seen = seen || q->replicate == r.replicate;
        if (!seen) p.runs.push_back(&r);
      }
    }
  }
  for (PointInfo& p : out) {
    double sum = 0, ss = 0, se2 = 0, xd = 0, xd2 = 0, amp = 0, xamp = 0;
    int namp = 0, nx = 0, nxd = 0;
    for (const ClaimRun* r : p.runs) {
      if (r->state != JobState::kDone || !r->result) {
        p.all_measured = false;
        continue;
      }
      const api::RunResult& res = *r->result;
      if (MeasuredRun(res)) {
        ++p.measured;
        sum += *res.uz;
        ss += *res.uz * *res.uz;
        se2 += *res.uz_stderr * *res.uz_stderr;
      } else {
        p.all_measured = false;
        if (BoundaryReached(res) != 0 && p.boundary == nullptr) p.boundary = r;
      }
      if (res.z_osc_amplitude > 0) amp += res.z_osc_amplitude, ++namp;
      if (res.x_osc_amplitude) xamp += *res.x_osc_amplitude, ++nx;
      xd += res.x_drift, xd2 += res.x_drift * res.x_drift, ++nxd;
    }
    if (p.measured > 0) {
      const double n = p.measured;
      p.mean = sum / n;
      p.mean_se = std::sqrt(se2 / n);
      if (p.measured >= 2) p.bed_sd = std::sqrt(std::max(0.0, (ss - n * p.mean * p.mean) / (n - 1)));
    } else {
      // No rate: the runs' drift over their time, for a direction and a size.
      double s = 0;
      int k = 0;
      for (const ClaimRun* r : p.runs)
        if (r->result && r->result->sim_time_s > 0) s += r->result->dz / r->result->sim_time_s, ++k;
      p.mean = k ? s / k : 0;
    }
    if (namp) p.z_amp = amp / namp;
    if (nx) p.x_amp = xamp / nx;
    if (nxd) {
      p.x_drift = xd / nxd;
      if (nxd >= 2) p.x_drift_sd = std::sqrt(std::max(0.0, (xd2 - nxd * p.x_drift * p.x_drift) / (nxd - 1)));
    }
  }
  return out;
}

// What the measured runs say of a period's scatter: relative to |U_z| (the median over runs of
// se sqrt(blocks) / |U_z|, runs with |U_z| >= 0.02 m/s) with an absolute floor (the smallest
// se sqrt(blocks)); and how far a run moved before a boundary stopped it (the least |dz| of runs
// that reached one: infinity when none did).
struct Scatter {
  double rel = 0.2, abs = 0.002;
  double room = std::numeric_limits<double>::infinity();
};
Scatter ScatterOf(const ClaimInput& in) {
  std::vector<double> rel;
  double abs = std::numeric_limits<double>::infinity();
  Scatter s;
  for (const ClaimSweep& sw : in.sweeps)
    for (const ClaimRun& r : sw.runs) {
      if (!r.result) continue;
      if (MeasuredRun(*r.result) && r.result->uz_blocks >= 2) {
        const double sd = *r.result->uz_stderr * std::sqrt(static_cast<double>(r.result->uz_blocks));
        abs = std::min(abs, sd);
        if (std::abs(*r.result->uz) >= 0.02) rel.push_back(sd / std::abs(*r.result->uz));
      } else if (BoundaryReached(*r.result) != 0) {
        s.room = std::min(s.room, std::abs(r.result->dz));
      }
    }
  if (!rel.empty()) {
    std::nth_element(rel.begin(), rel.begin() + static_cast<long>(rel.size() / 2), rel.end());
    s.rel = rel[rel.size() / 2];
  }
  if (std::isfinite(abs)) s.abs = abs;
  return s;
}

// A result drawn for one order from what the runs so far say (the header's "preposterior draw").
api::RunResult DrawResult(const RunOrder& o, const PointInfo& info, const ClaimRun* old,
                          const Scatter& sc, double bed_prior, std::mt19937_64& rng, double noise) {
  std::normal_distribution<double> unit(0, 1);
  auto z = [&](std::mt19937_64& g) { return noise * unit(g); };
  // A point that reached a boundary on a bed reaches it again on a new bed.
  if (!o.replaces && info.boundary != nullptr) return *info.boundary->result;
  const double block = o.point.f > 0 ? 1 / o.point.f : 0.25;
  const double transient = std::max(block, 0.25);
  const int max_blocks = static_cast<int>(std::floor((o.max_duration_s - transient) / block + 1e-9));
  double truth;
  if (o.replaces && old != nullptr && old->result && MeasuredRun(*old->result)) {
    truth = *old->result->uz;  // the same bed: its first periods again, then more
  } else {
    const double bed_sd = info.bed_sd > 0 ? info.bed_sd : bed_prior * std::abs(info.mean);
    truth = info.mean + z(rng) * std::sqrt(bed_sd * bed_sd + (info.measured ? info.mean_se * info.mean_se : 0.0));
  }
  api::RunResult r;
  r.z_osc_amplitude = info.z_amp;
  r.x_osc_amplitude = info.x_amp;
  r.x_drift = info.x_drift + z(rng) * std::max(info.x_drift_sd, 0.5 * std::abs(info.x_drift));
  r.block_s = block;
  r.window_t0 = transient;
  // Time to the boundary at this rate, when the runs so far show how far that is.
  const double to_boundary = std::isfinite(sc.room) && truth != 0 ? sc.room / std::abs(truth) : 1e9;
  if (to_boundary < o.max_duration_s && (to_boundary - transient) / block < 3) {
    r.stop_reason = truth > 0 ? "surface" : "floor";
    r.sim_time_s = to_boundary;
    r.dz = truth > 0 ? sc.room : -sc.room;
    r.conclusive = false;
    r.inconclusive_reason = "too few whole periods before the boundary";
    return r;
  }
  // In double: with no boundary seen, to_boundary is 1e9 s, past an int's range in periods.
  const int blocks_possible =
      static_cast<int>(std::max(0.0, std::min<double>(max_blocks, std::floor((to_boundary - transient) / block))));
  if (blocks_possible < 2) {
    r.stop_reason = "duration";
    r.sim_time_s = o.max_duration_s;
    r.dz = truth * o.max_duration_s;
    r.uz_blocks = blocks_possible;
    r.conclusive = false;
    r.inconclusive_reason = "too few whole periods";
    return r;
  }
  const double sd_block = std::max(sc.rel * std::abs(truth), sc.abs);
  int n = blocks_possible;
  if (o.precision) {
    const double width = std::max(o.precision->uz_rel * std::abs(truth), o.precision->uz_abs);
    const double need = std::ceil(std::pow(2.2 * sd_block / std::max(width, 1e-9), 2));
    n = std::clamp(static_cast<int>(need), std::min(n, o.precision->min_periods + kMinBlocksAfterPilot), n);
  }
  const double se = sd_block / std::sqrt(static_cast<double>(n));
  r.uz = truth + z(rng) * se;
  r.uz_stderr = se;
  r.uz_ci95 = StudentT95(n - 1) * se;
  r.uz_blocks = n;
  r.conclusive = true;
  r.window_t1 = transient + n * block;
  r.sim_time_s = r.window_t1;
  r.window_end = "run_end";
  r.stop_reason = n < max_blocks ? "target" : "duration";
  r.dz = *r.uz * r.sim_time_s;
  r.dz_rate = *r.uz;
  return r;
}

// The input with an action's runs given drawn results.
// `noise` 0: every drawn value at its estimate (the screening draw below).
ClaimInput WithDraw(const ClaimInput& in, const AdaptiveAction& a, const std::vector<PointInfo>& points,
                    const Scatter& sc, double bed_prior, std::mt19937_64& rng, double noise = 1) {
  ClaimInput out = in;
  int64_t next_id = 1'000'000'000;
  for (const RunOrder& o : a.runs) {
    const DriveId id = DriveIdOf(o.point);
    PointInfo info;
    info.point = o.point;
    bool known = false;
    for (const PointInfo& p : points)
      if (DriveIdOf(p.point) == id) info = p, known = true;
    if (!known) {
      // A new point: its neighbours' values along the swept f, interpolated.
      const PointInfo *lo = nullptr, *hi = nullptr;
      for (const PointInfo& p : points) {
        if (p.measured == 0 || IsRising(p.point) != IsRising(o.point) || p.point.mode != o.point.mode) continue;
        if (p.point.f < o.point.f && (!lo || p.point.f > lo->point.f)) lo = &p;
        if (p.point.f > o.point.f && (!hi || p.point.f < hi->point.f)) hi = &p;
      }
      if (lo && hi) {
        const double w = (o.point.f - lo->point.f) / (hi->point.f - lo->point.f);
        info = *lo;
        info.point = o.point;
        info.runs.clear();
        info.boundary = lo->boundary && hi->boundary ? lo->boundary : nullptr;
        info.mean = lo->mean + w * (hi->mean - lo->mean);
        info.bed_sd = std::max(lo->bed_sd, hi->bed_sd);
        info.mean_se = std::max(lo->mean_se, hi->mean_se) + std::abs(hi->mean - lo->mean) / 4;
      }
    }
    const ClaimRun* old = nullptr;
    for (const ClaimRun* r : info.runs)
      if (r->replicate == o.replicate) old = r;
    const api::RunResult drawn = DrawResult(o, info, old, sc, bed_prior, rng, noise);
    const int64_t run_id = next_id++;
    for (ClaimSweep& s : out.sweeps) {
      bool has_point = false;
      for (ClaimRun& r : s.runs) {
        if (DriveIdOf(r.point) != id) continue;
        has_point = true;
        if (o.replaces && r.replicate == o.replicate) r.result = drawn, r.state = JobState::kDone;
      }
      if (o.replaces || (!has_point && s.name != o.sweep)) continue;
      ClaimRun r;
      r.run_id = run_id;
      r.point = o.point;
      r.replicate = o.replicate;
      r.state = JobState::kDone;
      r.result = drawn;
      s.runs.push_back(std::move(r));
    }
  }
  return out;
}

bool IsSignKind(const std::string& kind) { return kind == "sign" || kind == "modes"; }

// Clear: measured on every bed and, for a sign, its beds' mean clear of 0 by its error.
bool Clear(const PointInfo& p, const std::string& kind) {
  if (IsSignKind(kind)) {
    if (p.runs.empty()) return false;
    if (!p.all_measured) {
      // Censored beds give a sign: clear when every bed is measured or at a boundary.
      for (const ClaimRun* r : p.runs)
        if (!r->result || (!MeasuredRun(*r->result) && BoundaryReached(*r->result) == 0)) return false;
      return true;
    }
    for (const ClaimRun* r : p.runs)
      if (std::abs(*r->result->uz) <= *r->result->uz_ci95) return false;
    return true;
  }
  return !p.runs.empty() && p.all_measured;
}

std::string PointList(const std::vector<const PointInfo*>& pts, size_t most = 4) {
  std::string s;
  for (size_t i = 0; i < pts.size() && i < most; ++i) s += (i ? ", " : "") + DescribeClaimPoint(pts[i]->point);
  if (pts.size() > most) s += ", ...";
  return s;
}

// An order at a point on bed `replicate` lasting at most `next` s, its target's widths over
// sqrt(next / base) (as much tighter as more periods make an interval).
RunOrder LongOrder(const PointInfo& p, int replicate, double next, double base, const Scale& scale, bool replaces) {
  RunOrder o;
  o.sweep = p.sweep;
  o.point = p.point;
  o.point.duration_s = next;
  o.replicate = replicate;
  o.max_duration_s = next;
  o.replaces = replaces;
  if (scale.default_precision) {
    PrecisionTarget t = *scale.default_precision;
    const double k = std::sqrt(next / base);
    t.uz_rel /= k;
    t.uz_abs /= k;
    t.max_duration_s = next;
    o.precision = t;
  }
  return o;
}

// The candidate actions for one open claim (the header's list), not yet costed nor scored.
std::vector<AdaptiveAction> Candidates(const AdaptiveState& state, const Claim& claim, const AdaptiveCost& cost,
                                       const AdaptiveOptions& options) {
  std::vector<AdaptiveAction> out;
  const std::vector<std::string> sweeps = SweepsOfClaim(claim, state.sweeps);
  const std::vector<PointInfo> points = PointsOf(state.input, sweeps);
  if (points.empty()) return out;
  const Scale& scale = *cost.scale;
  std::vector<const PointInfo*> needy, all;
  for (const PointInfo& p : points) {
    all.push_back(&p);
    if (!Clear(p, claim.kind())) needy.push_back(&p);
  }
  const bool all_clear = needy.empty();
  const std::vector<std::vector<const PointInfo*>> sets =
      all_clear ? std::vector<std::vector<const PointInfo*>>{all}
                : (needy.size() == all.size() ? std::vector<std::vector<const PointInfo*>>{needy}
                                              : std::vector<std::vector<const PointInfo*>>{needy, all});
  const std::string why = all_clear ? "every point is measured, the claim is still open"
                                    : std::to_string(needy.size()) + " of " + std::to_string(all.size()) +
                                          " points not yet clear (" + PointList(needy) + ")";
  for (const auto& set : sets) {
    const std::string which = &set == &sets.front() && !all_clear ? "at each" : "at every point";
    // One or two more beds, at the scale's target or as long as allowed (then with the point's
    // runs so far as long too).
    for (int add = 1; add <= 2; ++add) {
      for (int long_runs = 0; long_runs < 2; ++long_runs) {
        AdaptiveAction rep;
        rep.kind = ActionKind::kReplicate;
        rep.claim = claim.id;
        double len = 0;
        for (const PointInfo* p : set) {
          if (p->beds() + add > options.max_beds || p->boundary != nullptr) continue;
          const double base = BaseMaxDuration(p->point, scale);
          const double next = long_runs ? options.max_duration_factor * base : base;
          len = std::max(len, next);
          for (int j = 0; j < add; ++j) rep.runs.push_back(LongOrder(*p, p->beds() + j, next, base, scale, false));
          if (!long_runs) continue;
          for (const ClaimRun* r : p->runs)
            if (r->result && BoundaryReached(*r->result) == 0 && r->result->sim_time_s < next / 1.5)
              rep.runs.push_back(LongOrder(*p, r->replicate, next, base, scale, true));
        }
        if (rep.runs.empty()) continue;
        rep.reason = claim.id + ": " + why + "; " + (add == 1 ? "one more bed " : "two more beds ") + which +
                     (long_runs ? ", every run there as long as allowed (" + Num(len, 3) + " s)" : "") + ": " +
                     std::to_string(rep.runs.size()) + " runs";
        out.push_back(std::move(rep));
      }
    }
    // Longer (twice, and the most allowed), with a target as much tighter.
    for (int most = 0; most < 2; ++most) {
      AdaptiveAction longer;
      longer.kind = ActionKind::kLonger;
      longer.claim = claim.id;
      double longest = 0;
      for (const PointInfo* p : set) {
        const double base = BaseMaxDuration(p->point, scale);
        for (const ClaimRun* r : p->runs) {
          if (!r->result || BoundaryReached(*r->result) != 0) continue;
          const double now = std::max(base, r->result->sim_time_s);
          const double next = most ? options.max_duration_factor * base : 2 * std::ceil(now * 2 - 1e-9) / 2;
          if (next > options.max_duration_factor * base + 1e-9 || next < now * 1.5) continue;
          longer.runs.push_back(LongOrder(*p, r->replicate, next, base, scale, true));
          longest = std::max(longest, next);
        }
      }
      if (!longer.runs.empty()) {
        longer.reason = claim.id + ": " + why + "; each run " + which + " again " +
                        (most ? "as long as allowed" : "twice as long") + " (up to " + Num(longest, 3) +
                        " s, its target's width / sqrt of the factor): " + std::to_string(longer.runs.size()) + " runs";
        out.push_back(std::move(longer));
      }
    }
  }
  // A new f between the observed peak and each neighbour (interior_maximum).
  if (claim.kind() == "interior_maximum") {
    std::vector<const PointInfo*> rising;
    for (const PointInfo& p : points)
      if (IsRising(p.point) && p.measured > 0) rising.push_back(&p);
    std::vector<double> declared;
    for (const AdaptiveSweep& s : state.sweeps)
      if (std::find(sweeps.begin(), sweeps.end(), s.name) != sweeps.end())
        for (const Point& p : s.points)
          if (IsRising(p)) declared.push_back(p.f);
    if (rising.size() >= 3 && !declared.empty()) {
      const double f_min = *std::min_element(declared.begin(), declared.end());
      const double f_max = *std::max_element(declared.begin(), declared.end());
      const PointInfo* peak = *std::max_element(rising.begin(), rising.end(),
                                                [](const PointInfo* a, const PointInfo* b) { return a->mean < b->mean; });
      std::vector<double> fs;
      for (const PointInfo& p : points)
        if (IsRising(p.point)) fs.push_back(p.point.f);
      std::sort(fs.begin(), fs.end());
      auto it = std::lower_bound(fs.begin(), fs.end(), peak->point.f);
      std::vector<double> new_f;
      if (it != fs.begin()) new_f.push_back(std::round((*(it - 1) + peak->point.f) / 2 * 100) / 100);
      if (it + 1 != fs.end()) new_f.push_back(std::round((*(it + 1) + peak->point.f) / 2 * 100) / 100);
      AdaptiveAction np;
      np.kind = ActionKind::kNewPoint;
      np.claim = claim.id;
      std::string listed;
      for (double f : new_f) {
        if (!(f > f_min && f < f_max) || std::find(fs.begin(), fs.end(), f) != fs.end()) continue;
        Point p = peak->point;
        p.f = f;
        p.duration_s = BaseMaxDuration(p, scale);
        if (!Validate(p).ok() || !FitsScale(p, scale).ok()) continue;
        listed += (listed.empty() ? "" : ", ") + Num(f, 4);
        for (int bed = 0; bed < peak->beds(); ++bed) {
          RunOrder o;
          o.sweep = peak->sweep;
          o.point = p;
          o.replicate = bed;
          o.max_duration_s = p.duration_s;
          o.precision = scale.default_precision;
          np.runs.push_back(o);
        }
      }
      if (!np.runs.empty()) {
        const double lo = it != fs.begin() ? *(it - 1) : peak->point.f;
        const double hi = it + 1 != fs.end() ? *(it + 1) : peak->point.f;
        np.reason = claim.id + ": the peak lies between " + Num(lo, 4) + " and " + Num(hi, 4) + " Hz; adding f = " +
                    listed + " on " + std::to_string(peak->beds()) + " bed(s)";
        out.push_back(std::move(np));
      }
    }
  }
  for (AdaptiveAction& a : out) Cost(a, cost, static_cast<int>(state.input.beds.size()));
  return out;
}

bool PointsInRange(const AdaptiveAction& a) { return !a.runs.empty(); }

}  // namespace

AdaptiveRound FirstRound(const std::vector<AdaptiveSweep>& sweeps, const AdaptiveCost& cost) {
  AdaptiveRound round;
  round.round = 1;
  AdaptiveAction a;
  a.kind = ActionKind::kFirstRound;
  std::set<DriveId> seen;
  for (const AdaptiveSweep& s : sweeps)
    for (const Point& p : s.points) {
      if (!seen.insert(DriveIdOf(p)).second) continue;
      RunOrder o;
      o.sweep = s.name;
      o.point = p;
      o.max_duration_s = RunDuration(p, cost.scale->default_precision);
      o.precision = cost.scale->default_precision;
      a.runs.push_back(o);
    }
  Cost(a, cost, 0);
  a.reason = "every declared point once, on one bed, at the scale's precision target (the calibrated design): " +
             std::to_string(a.runs.size()) + " runs and 1 bed";
  round.core_h = a.core_h;
  round.sim_s = a.sim_s;
  round.actions.push_back(std::move(a));
  return round;
}

std::vector<AdaptiveSweep> AdaptiveSweepsOf(const std::vector<SweepSpec>& sweeps) {
  std::vector<AdaptiveSweep> out;
  for (const SweepSpec& s : sweeps) {
    Result<std::vector<Point>> points = ExpandSweep(s);
    out.push_back({s.name, points.ok() ? *points : std::vector<Point>{}});
  }
  return out;
}

Status CheckAdaptiveBudget(const Campaign& campaign, const std::string& scale, const AdaptiveCost& cost) {
  if (!campaign.adaptive) return Status::Ok();
  AdaptiveCost at = cost;
  at.scale = FindScale(scale);
  if (at.scale == nullptr) return Status::InvalidArgument("scale", "must be one of paper, mini, smoke");
  std::vector<SweepSpec> sweeps = campaign.sweeps;
  for (SweepSpec& s : sweeps) s.scale = scale;
  const Status s = ValidateAdaptiveBudget(campaign.adaptive->budget_core_h, FirstRound(AdaptiveSweepsOf(sweeps), at));
  if (s.ok()) return s;
  auto rate = [](const EngineRate& r) {
    return Num(r.s_per_unit, 3) + " s" + (r.samples > 0 ? " from " + std::to_string(r.samples) + " measured" : " (a default)");
  };
  return Status(s.code(),
                s.reason() + " at " + scale + ", at the cost model's rates now (runs " + rate(cost.run_rate) +
                    " per particle-step, beds " + rate(cost.bed_rate) + " per grain; GET /api/v1/cost-model)",
                "adaptive." + s.field());
}

Status ValidateAdaptiveBudget(double budget_core_h, const AdaptiveRound& first) {
  double cheapest = std::numeric_limits<double>::infinity();
  size_t runs = 0;
  for (const AdaptiveAction& a : first.actions) runs += a.runs.size();
  for (const AdaptiveAction& a : first.actions)
    for (const RunOrder& o : a.runs) cheapest = std::min(cheapest, o.max_duration_s);
  const std::string need = "needs at least " + CoreH(first.core_h) + " (the first round: " + std::to_string(runs) +
                           " runs and 1 bed, each run at most its target's " +
                           (std::isfinite(cheapest) ? Num(cheapest, 3) + " s" : std::string("length")) +
                           "); no claim can be decided before each of its points has run once";
  if (!std::isfinite(budget_core_h) || budget_core_h <= 0)
    return Status::InvalidArgument("budget_core_h", "must be a positive number of core-hours: the campaign " + need);
  if (budget_core_h < first.core_h)
    return Status::InvalidArgument("budget_core_h", Num(budget_core_h, 4) + " core-h cannot decide anything: the campaign " + need);
  return Status::Ok();
}

std::vector<std::string> FreezeDecisions(const std::vector<ClaimVerdict>& verdicts, std::map<std::string, Verdict>& frozen) {
  std::vector<std::string> out;
  for (const ClaimVerdict& v : verdicts) {
    if (v.verdict == Verdict::kInconclusive || frozen.count(v.claim.id)) continue;
    frozen[v.claim.id] = v.verdict;
    out.push_back(v.claim.id);
  }
  return out;
}

std::vector<std::string> OpenClaims(const AdaptiveState& state) {
  std::vector<std::string> out;
  for (const Claim& c : state.claims)
    if (!state.frozen.count(c.id) && !SweepsOfClaim(c, state.sweeps).empty()) out.push_back(c.id);
  return out;
}

AdaptiveRound PlanNextRound(const AdaptiveState& state, double budget_core_h, const AdaptiveCost& cost,
                            const AdaptiveOptions& options) {
  AdaptiveRound round;
  round.round = state.rounds_done + 1;
  const std::vector<std::string> open = OpenClaims(state);
  const double left = budget_core_h - state.spent_core_h;
  if (open.empty()) {
    round.stop = true;
    round.stop_reason = "every claim runs can decide is decided";
    return round;
  }
  const std::string open_text = Join(open, ", ");
  if (state.rounds_done >= options.max_rounds) {
    round.stop = true;
    round.stop_reason = "the look schedule's " + std::to_string(options.max_rounds) + " rounds are done; " +
                        open_text + " stay inconclusive";
    return round;
  }
  const double bed_prior = cost.scale->bed_sd_rel.value_or(0.2);
  const Scatter sc = ScatterOf(state.input);
  std::vector<AdaptiveAction> cands;
  for (size_t ci = 0; ci < state.claims.size(); ++ci) {
    const Claim& claim = state.claims[ci];
    if (std::find(open.begin(), open.end(), claim.id) == open.end()) continue;
    std::vector<AdaptiveAction> mine = Candidates(state, claim, cost, options);
    const std::vector<PointInfo> points = PointsOf(state.input, SweepsOfClaim(claim, state.sweeps));
    for (size_t k = 0; k < mine.size(); ++k) {
      AdaptiveAction& a = mine[k];
      if (!PointsInRange(a) || a.core_h > left) continue;
      std::mt19937_64 rng(options.seed ^ (ci * 0x9e3779b97f4a7c15ULL) ^ (k + 1) * 0xbf58476d1ce4e5b9ULL);
      int decided = 0;
      // Screening: with every new value at its estimate (no scatter), an action that does not
      // decide the claim is not drawn further (a claim held open by a point no run can measure,
      // e.g. one that reaches the surface first at this box, stays open whatever is added).
      const ClaimInput best = WithDraw(state.input, a, points, sc, bed_prior, rng, 0);
      const bool can_decide = EvaluateClaims({claim}, best)[0].verdict != Verdict::kInconclusive;
      for (int d = 0; can_decide && d < options.draws; ++d) {
        const ClaimInput hyp = WithDraw(state.input, a, points, sc, bed_prior, rng);
        if (EvaluateClaims({claim}, hyp)[0].verdict != Verdict::kInconclusive) ++decided;
      }
      a.draws = options.draws;
      a.gain = options.draws ? static_cast<double>(decided) / options.draws : 0;
      round.considered.push_back(a);
      if (a.gain > 0) cands.push_back(std::move(a));
    }
  }
  if (cands.empty()) {
    round.stop = true;
    round.stop_reason = "no action within the " + CoreH(std::max(left, 0.0)) + " left is expected to decide " +
                        open_text + " (none decides it even with every new value at its estimate, or in any of " +
                        std::to_string(options.draws) + " draws): they stay inconclusive";
    return round;
  }
  const int rounds_left = std::max(1, options.max_rounds - state.rounds_done);
  double cheapest = std::numeric_limits<double>::infinity();
  for (const AdaptiveAction& a : cands) cheapest = std::min(cheapest, a.core_h);
  const double round_budget = std::min(left, std::max(left / rounds_left, cheapest));
  std::stable_sort(cands.begin(), cands.end(), [](const AdaptiveAction& a, const AdaptiveAction& b) {
    return a.gain / std::max(a.core_h, 1e-9) > b.gain / std::max(b.core_h, 1e-9);
  });
  std::set<std::string> served;
  std::set<std::pair<DriveId, int>> ordered;
  for (AdaptiveAction& a : cands) {
    if (served.count(a.claim)) continue;
    // Runs another action of this round already orders are not ordered twice.
    std::vector<RunOrder> keep;
    for (const RunOrder& o : a.runs)
      if (!ordered.count({DriveIdOf(o.point), o.replicate})) keep.push_back(o);
    if (keep.empty()) continue;
    a.runs = keep;
    Cost(a, cost, static_cast<int>(state.input.beds.size()));
    if (round.core_h + a.core_h > round_budget + 1e-12) continue;
    for (const RunOrder& o : a.runs) ordered.insert({DriveIdOf(o.point), o.replicate});
    served.insert(a.claim);
    a.reason += ": +" + CoreH(a.core_h) + " (decides it in " + std::to_string(static_cast<int>(std::lround(a.gain * a.draws))) +
                " of " + std::to_string(a.draws) + " draws from the estimates so far)";
    round.core_h += a.core_h;
    round.sim_s += a.sim_s;
    round.actions.push_back(std::move(a));
  }
  if (round.actions.empty()) {
    round.stop = true;
    round.stop_reason = "the budget is spent: " + CoreH(std::max(left, 0.0)) + " left, the cheapest useful action needs " +
                        CoreH(cheapest) + "; " + open_text + " stay inconclusive";
  }
  return round;
}

std::string DescribeRound(const AdaptiveRound& round, double left_core_h) {
  std::string s = "round " + std::to_string(round.round) + ": ";
  if (round.stop) return s + "stop: " + round.stop_reason;
  for (size_t i = 0; i < round.actions.size(); ++i) s += (i ? "; " : "") + round.actions[i].reason;
  return s + " (round +" + CoreH(round.core_h) + ", " + CoreH(std::max(0.0, left_core_h - round.core_h)) + " left after it)";
}

}  // namespace sandswim
