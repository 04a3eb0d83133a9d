#include "core/convergence.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include <gsl/gsl_cdf.h>

#include "core/aggregate.h"
#include "core/text.h"

namespace sandswim {
namespace {

// The drive without its step: what pairs a run with its reference.
DriveId DriveWithoutStep(const Point& p) {
  DriveId id = DriveIdOf(p);
  std::get<7>(id) = 0;
  return id;
}

struct Measured {
  const ClaimRun* run = nullptr;
  double uz = 0, se = 0, dof = 0, z_osc = 0;
};

// A run measured as the claims take it (core/claims.h MeasuredRun), or why not.
std::optional<Measured> MeasuredOf(const ClaimRun& r, std::string& why) {
  if (r.state != JobState::kDone || !r.result) {
    why = "run " + std::to_string(r.run_id) + " " + ToString(r.state);
    return std::nullopt;
  }
  if (!MeasuredRun(*r.result)) {
    why = "run " + std::to_string(r.run_id) + " has no measured U_z" +
          (r.result->inconclusive_reason.empty() ? "" : " (" + r.result->inconclusive_reason + ")");
    return std::nullopt;
  }
  return Measured{&r, *r.result->uz, *r.result->uz_stderr, DofOfInterval(*r.result->uz_stderr, *r.result->uz_ci95),
                  r.result->z_osc_amplitude};
}

std::string Label(const Point& p) {
  Point q = p;
  q.dt_s.reset();
  return DescribeClaimPoint(q);
}

double Tq(double q, double dof) { return gsl_cdf_tdist_Pinv(q, std::max(dof, 0.5)); }

struct PointAtStep {
  Point point;
  std::vector<std::pair<Measured, Measured>> pairs;  // (at the step, reference), by bed
  std::string why;                                   // not every bed paired: why
};

}  // namespace

void EvaluateConvergence(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  const double margin_rel = c.rule.value("margin_rel", kDefaultMarginRel);
  const double margin_abs = c.rule.value("margin_abs_mps", kDefaultMarginAbsMps);
  auto names = [&](const char* key) {
    std::vector<std::string> out;
    if (c.rule.contains(key) && c.rule[key].is_array())
      for (const auto& s : c.rule[key]) out.push_back(s.get<std::string>());
    return out;
  };
  auto sweep_named = [&](const std::string& name) -> const ClaimSweep* {
    for (const ClaimSweep& s : in.sweeps)
      if (s.name == name) return &s;
    return nullptr;
  };
  // The reference runs by (drive without step, replicate).
  std::map<std::pair<DriveId, int>, const ClaimRun*> reference;
  for (const std::string& name : names("reference"))
    if (const ClaimSweep* s = sweep_named(name))
      for (const ClaimRun& r : s->runs) reference.emplace(std::make_pair(DriveWithoutStep(r.point), r.replicate), &r);

  // Points of each step (a step's sweeps together), in the order the sweeps name them.
  std::map<double, std::vector<PointAtStep>> steps;
  std::map<double, std::vector<std::string>> step_sweeps;
  for (const std::string& name : names("sweeps")) {
    const ClaimSweep* s = sweep_named(name);
    if (s == nullptr) continue;
    std::map<DriveId, PointAtStep> by_point;
    std::vector<DriveId> order;
    for (const ClaimRun& r : s->runs) {
      const DriveId id = DriveIdOf(r.point);
      auto [it, inserted] = by_point.emplace(id, PointAtStep{r.point, {}, ""});
      if (inserted) order.push_back(id);
      PointAtStep& p = it->second;
      std::string why;
      std::optional<Measured> at = MeasuredOf(r, why);
      auto ref = reference.find({DriveWithoutStep(r.point), r.replicate});
      std::optional<Measured> base;
      if (ref == reference.end()) {
        why = "no reference run on bed " + std::to_string(r.replicate);
      } else if (at) {
        base = MeasuredOf(*ref->second, why);
      }
      if (at && base) {
        p.pairs.push_back({*at, *base});
      } else if (p.why.empty()) {
        p.why = why;
      }
    }
    const double dt = by_point.empty() ? 0 : DriveStep(by_point.begin()->second.point);
    step_sweeps[dt].push_back(name);
    for (const DriveId& id : order) steps[dt].push_back(std::move(by_point[id]));
  }

  for (auto& [dt, points] : steps) {
    ClaimPart part;
    std::string sweeps_at_step;
    for (const std::string& n : step_sweeps[dt]) sweeps_at_step += (sweeps_at_step.empty() ? "" : ", ") + n;
    part.name = "dt = " + Num(dt) + " s (" + sweeps_at_step + ")";
    int equivalent = 0, differs = 0, undecided = 0;
    for (const PointAtStep& p : points) {
      if (!p.why.empty() || p.pairs.empty()) {
        ClaimMissing m;
        m.sweep = part.name;
        m.point = p.point;
        for (const auto& pair : p.pairs) m.run_ids.push_back(pair.first.run->run_id);
        m.why = p.why.empty() ? "no paired run" : p.why;
        v.missing.push_back(std::move(m));
        ++undecided;
        continue;
      }
      const double k = static_cast<double>(p.pairs.size());
      double d = 0, ref = 0, osc = 0, osc_ref = 0, var_runs = 0, ws_den = 0;
      for (const auto& [a, b] : p.pairs) {
        d += (a.uz - b.uz) / k;
        ref += b.uz / k;
        osc += a.z_osc / k;
        osc_ref += b.z_osc / k;
        const double va = a.se * a.se / (k * k), vb = b.se * b.se / (k * k);
        var_runs += va + vb;
        ws_den += va * va / a.dof + vb * vb / b.dof;
      }
      double se = std::sqrt(var_runs), dof = ws_den > 0 ? var_runs * var_runs / ws_den : 1e7;
      std::string rests = "the runs' own errors";
      if (p.pairs.size() >= 2) {
        double ss = 0;
        for (const auto& [a, b] : p.pairs) ss += std::pow(a.uz - b.uz - d, 2);
        const double se_scatter = std::sqrt(ss / (k - 1) / k);
        if (se_scatter > se) {
          se = se_scatter;
          dof = k - 1;
          rests = "the pairs' scatter";
        }
      }
      const double delta = std::max(margin_rel * std::fabs(ref), margin_abs);
      const double h90 = Tq(0.95, dof) * se, h95 = Tq(0.975, dof) * se;
      ClaimFigure f;
      f.name = "U_z(dt) - U_z(ref) at " + Label(p.point);
      f.value = d;
      f.se = se;
      f.lo = d - h90;
      f.hi = d + h90;
      f.unit = "m/s";
      if (d - h90 > -delta && d + h90 < delta) {
        f.verdict = Verdict::kHolds;
        ++equivalent;
      } else if (d - h95 > delta || d + h95 < -delta) {
        f.verdict = Verdict::kDiffers;
        ++differs;
      } else {
        f.verdict = Verdict::kInconclusive;
        ++undecided;
      }
      f.note = "90 % interval (two one-sided tests at 5 %) against the margin +-" + Num(delta, 3) + " m/s (max(" +
               Num(100 * margin_rel) + " % of |U_z(ref)| = " + Num(std::fabs(ref), 3) + ", " + Num(margin_abs) +
               ")); " + std::to_string(p.pairs.size()) + " bed(s) paired, error from " + rests + " (" +
               Num(dof, 3) + " dof); z amplitude at f " + Num(1000 * osc, 3) + " mm against " +
               Num(1000 * osc_ref, 3) + " mm (no error: shown, not tested)";
      part.figures.push_back(std::move(f));
    }
    const int n = static_cast<int>(points.size());
    if (differs > 0) {
      part.verdict = Verdict::kDiffers;
      part.reason = std::to_string(differs) + " of " + std::to_string(n) +
                    " point(s) move U_z by more than the margin at this step (95 % interval outside it)";
    } else if (equivalent == n && n > 0) {
      part.verdict = Verdict::kHolds;
      part.reason = "equivalent to the reference step at every one of its " + std::to_string(n) +
                    " point(s) (90 % interval of the paired difference inside the margin)";
    } else {
      part.verdict = Verdict::kInconclusive;
      part.reason = std::to_string(equivalent) + " of " + std::to_string(n) + " point(s) shown equivalent, " +
                    std::to_string(undecided) + " undecided (too wide an interval or no paired runs)";
    }
    v.parts.push_back(std::move(part));
  }
}

std::string ConvergedUpTo(const ClaimVerdict& v) {
  // Parts are in ascending step order (EvaluateConvergence): the longest step before the first
  // that does not hold.
  std::string up_to;
  for (const ClaimPart& p : v.parts) {
    if (p.verdict != Verdict::kHolds) break;
    up_to = p.name.substr(5, p.name.find(" s") - 5);
  }
  return up_to.empty() ? "no longer step shown equivalent to the reference"
                       : "converged up to dt = " + up_to + " s";
}

}  // namespace sandswim
