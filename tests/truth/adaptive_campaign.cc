#include "tests/truth/adaptive_campaign.h"

#include <set>

namespace sandswim::truth {

std::vector<AdaptiveSweep> DeclaredSweeps(const Calibrator& cal) { return AdaptiveSweepsOf(cal.campaign().sweeps); }

double SpentCoreHours(const SimCampaign& c, const AdaptiveCost& cost) {
  double h = 0;
  std::set<int> beds;
  for (const SimRun& r : c.runs) {
    h += cost.RunCoreHours(r.point, r.simulated_s);
    if (beds.insert(r.replicate).second) h += cost.BedCoreHours(r.point);
  }
  return h;
}

namespace {

// Puts a run's outcome where the claims read it: in every sweep that has its point (a new point:
// in the order's sweep), replacing the run of that point on that bed for a longer run.
void Place(ClaimInput& input, const RunOrder& o, const ClaimRun& run) {
  const DriveId id = DriveIdOf(o.point);
  for (ClaimSweep& s : input.sweeps) {
    bool has_point = false;
    for (ClaimRun& r : s.runs) {
      if (DriveIdOf(r.point) != id) continue;
      has_point = true;
      if (o.replaces && r.replicate == o.replicate) {
        const int64_t keep = r.run_id;
        r = run;
        r.run_id = keep;
      }
    }
    if (o.replaces || (!has_point && s.name != o.sweep)) continue;
    s.runs.push_back(run);
  }
}

}  // namespace

AdaptiveOutcome SimulateAdaptive(const Calibrator& cal, const Law& law, const Noise& noise, uint64_t world,
                                 double budget_core_h, const AdaptiveOptions& options) {
  AdaptiveOutcome out;
  AdaptiveCost cost;
  cost.scale = &cal.scale();
  AdaptiveState state;
  state.claims = cal.claims();
  state.sweeps = DeclaredSweeps(cal);
  AdaptiveRound first = FirstRound(state.sweeps, cost);
  out.planned_core_h += first.core_h;
  out.rounds.push_back(first);
  SimCampaign c = cal.Simulate(law, noise, world);
  state.input.scale = cal.design().scale;
  state.input.sweeps = std::move(c.sweeps);
  state.input.beds = std::move(c.beds);
  out.core_h = SpentCoreHours(c, cost);
  for (const SimRun& r : c.runs) out.sim_s += r.simulated_s;
  out.runs = static_cast<int>(c.runs.size());
  out.beds = static_cast<int>(state.input.beds.size());
  state.rounds_done = 1;
  state.spent_core_h = out.core_h;
  for (const std::string& id : FreezeDecisions(c.verdicts, state.frozen)) out.decided_at[id] = 1;
  out.last = c.verdicts;
  std::vector<Bed> beds;
  for (int b = 0; b < out.beds; ++b) beds.push_back(MakeBed(world, b, noise, cal.scale()));
  int64_t next_id = 100000;
  for (;;) {
    AdaptiveRound round = PlanNextRound(state, budget_core_h, cost, options);
    out.rounds.push_back(round);
    if (round.stop) break;
    out.planned_core_h += round.core_h;
    for (const AdaptiveAction& a : round.actions) {
      for (const RunOrder& o : a.runs) {
        while (static_cast<int>(beds.size()) <= o.replicate) {
          beds.push_back(MakeBed(world, static_cast<int>(beds.size()), noise, cal.scale()));
          ClaimBed b;
          b.id = static_cast<int64_t>(beds.size());
          b.replicate = beds.back().replicate;
          b.state = JobState::kDone;
          b.grains = beds.back().grains;
          b.bed_height = beds.back().surface - cal.scale().z_floor;
          state.input.beds.push_back(b);
          out.core_h += cost.BedCoreHours(o.point);
        }
        const SimRun sim = cal.RunOne(law, noise, beds[static_cast<size_t>(o.replicate)], o.point, o.max_duration_s,
                                      o.precision, world, 0, ++next_id);
        ClaimRun run;
        run.run_id = next_id;
        run.point = o.point;
        run.replicate = o.replicate;
        run.state = sim.result ? JobState::kDone : JobState::kFailed;
        run.result = sim.result;
        run.failure = sim.failure;
        Place(state.input, o, run);
        out.sim_s += sim.simulated_s;
        out.core_h += cost.RunCoreHours(o.point, sim.simulated_s);
        ++out.runs;
      }
    }
    state.rounds_done += 1;
    state.spent_core_h = out.core_h;
    out.last = EvaluateClaims(state.claims, state.input);
    for (const std::string& id : FreezeDecisions(out.last, state.frozen)) out.decided_at[id] = state.rounds_done;
  }
  out.beds = static_cast<int>(beds.size());
  out.frozen = state.frozen;
  return out;
}

}  // namespace sandswim::truth
