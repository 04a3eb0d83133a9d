#include "server/jobs/rounds.h"

#include <algorithm>
#include <map>
#include <set>
#include <tuple>
#include <utility>

#include "core/scale.h"
#include "core/text.h"
#include "server/store/rounds.h"

namespace sandswim {
namespace {

using nlohmann::json;

std::string CoreHText(double h) { return Num(h, 3) + " core-h"; }

// What an attempt (a closed lease) at a run or bed of the campaign run (its id, created at `created_at`)
// is charged, at the rates in `cost` (those its round was planned at): a bed attempt the bed's
// cost (however far it got: nothing says); a run attempt the simulated time it reached (done: its
// result's; else its last heartbeat's). A run attempt with no positive simulated time (no
// heartbeat, or a heartbeat that carried none: core/api.h's sim_time_s defaults to 0) is charged
// its whole planned length, the most it can have simulated; one taken back unreceived never ran
// and costs nothing. Each attempt is charged, so a retried run pays for every attempt and the
// ledger is complete. (The wall time a lease allowed is no price: it is wall time, not simulated
// time, and a lease is mostly unused.) An attempt is charged in full by one campaign run only, its
// payer (decided at the grant, server/store/rounds.h DecideLeasePayer): the others that hold the
// job record it at 0, as do those that were submitted after it was leased (a nightly rerun that
// finds the night before's run still running: that night's campaign run pays).
rounds::Charge Price(const rounds::ClosedAttempt& a, const AdaptiveCost& cost, int64_t campaign_run_id,
                     double created_at) {
  rounds::Charge c;
  c.kind = a.kind;
  c.id = a.id;
  c.ended_at = a.ended_at;
  c.state = a.outcome;
  c.lease_token = a.lease_token;
  const bool run = a.kind == "run";
  const bool ours = a.payer == campaign_run_id;
  if (a.granted_at < created_at || !ours || a.outcome == "unreceived") {
    c.priced_by = a.granted_at < created_at ? "leased before"
                  : !ours ? (a.payer ? "paid by campaign run " + std::to_string(*a.payer) : "leased for no campaign run")
                          : "never ran";
    c.core_h = 0;
    if (run) c.sim_time_s = 0.0;
    return c;
  }
  if (!run) {
    c.priced_by = "bed";
    c.core_h = cost.BedCoreHours(a.point);
    return c;
  }
  if (a.sim_time_s && *a.sim_time_s > 0) {
    c.priced_by = a.outcome == "done" ? "result" : "heartbeat";
    c.sim_time_s = *a.sim_time_s;
  } else {
    c.priced_by = "planned length";
    c.sim_time_s = a.run_duration_s;
  }
  c.core_h = *c.sim_time_s > 0 ? cost.RunCoreHours(a.point, *c.sim_time_s) : 0.0;
  return c;
}

// The attempts a look charges, with what priced each (who pays, how far it got, how it ended):
// what its write checks it still finds.
using PricedAttempt = std::tuple<std::string, std::optional<int64_t>, std::optional<double>, std::string>;
std::set<PricedAttempt> PricedOf(const std::vector<rounds::ClosedAttempt>& attempts) {
  std::set<PricedAttempt> out;
  for (const rounds::ClosedAttempt& a : attempts) out.emplace(a.lease_token, a.payer, a.sim_time_s, a.outcome);
  return out;
}

// The claims' states after a look: a frozen one as it was decided (and at which round), an open
// one inconclusive.
json StatesAfter(const std::vector<Claim>& claims, const std::map<std::string, Verdict>& frozen,
                 const std::map<std::string, int>& frozen_round) {
  json out = json::array();
  for (const Claim& c : claims) {
    json j{{"claim", c.id}};
    if (auto it = frozen.find(c.id); it != frozen.end()) {
      j["verdict"] = VerdictName(it->second);
      j["frozen_at_round"] = frozen_round.at(c.id);
    } else {
      j["verdict"] = VerdictName(Verdict::kInconclusive);
    }
    out.push_back(std::move(j));
  }
  return out;
}

json ActionsJson(const AdaptiveRound& round) {
  json out = json::array();
  for (const AdaptiveAction& a : round.actions) out.push_back(rounds::ActionToJson(a));
  return out;
}

// One order as a plan of the run it asks for: its point on its replicate bed (only that bed), in
// its sweep, as the submission plans any run (core/sweep.h PlanSweeps: the same keys and decks).
Result<ScalePlan> PlanOrder(const RunOrder& o, const std::string& scale, const std::vector<SweepSpec>& declared,
                            const std::string& engine_version) {
  const Scale* sc = FindScale(scale);
  if (sc == nullptr) return Status::InvalidArgument("scale", "unknown scale \"" + scale + "\"");
  SweepSpec spec;
  spec.name = o.sweep;
  spec.scale = scale;
  spec.base = o.point;
  spec.base.duration_s = o.max_duration_s;
  spec.precision = o.precision;
  spec.replicates = o.replicate + 1;
  for (const SweepSpec& d : declared)
    if (d.name == o.sweep) spec.snapshots = d.snapshots;
  Result<Plan> plan = PlanSweeps({spec}, *sc, engine_version);
  if (!plan.ok()) return plan.status();
  ScalePlan out;
  out.scale = scale;
  out.plan.scale = plan->scale;
  std::map<int, int> bed_index;
  for (PlannedRun& r : plan->runs) {
    if (r.replicate != o.replicate) continue;
    auto [it, inserted] = bed_index.emplace(r.bed, static_cast<int>(out.plan.beds.size()));
    if (inserted) out.plan.beds.push_back(plan->beds[static_cast<size_t>(r.bed)]);
    r.bed = it->second;
    out.plan.runs.push_back(std::move(r));
  }
  if (out.plan.runs.empty()) return Status::Internal("the order of " + o.sweep + " planned no run");
  return out;
}

// The run a longer order replaces: the point's run on that bed in the order's sweep (the longer
// run joins only that sweep).
std::optional<int64_t> ReplacedRun(const ClaimInput& input, const RunOrder& o) {
  const DriveId id = DriveIdOf(o.point);
  for (const ClaimSweep& s : input.sweeps)
    if (s.name == o.sweep)
      for (const ClaimRun& r : s.runs)
        if (r.replicate == o.replicate && DriveIdOf(r.point) == id) return r.run_id;
  return std::nullopt;
}

}  // namespace

RoundDriver::RoundDriver(Store* store, ClaimLookFn look, RoundDriverOptions options)
    : store_(store), look_(std::move(look)), options_(std::move(options)) {}

Result<RoundDriver::Pass> RoundDriver::Tick(double now) {
  Result<std::vector<int64_t>> open = rounds::OpenAdaptiveCampaignRuns(*store_);
  if (!open.ok()) return open.status();
  Pass pass;
  for (int64_t id : *open) {
    Result<std::optional<RoundStep>> step = Step(id, now);
    if (!step.ok()) {
      pass.errors.emplace_back(id, step.status());
    } else if (*step) {
      pass.steps.push_back(std::move(**step));
    }
  }
  return pass;
}

Result<std::optional<RoundStep>> RoundDriver::Step(int64_t campaign_run_id, double now) {
  using Out = std::optional<RoundStep>;
  Result<CampaignRunInfo> info = store_->GetCampaignRun(campaign_run_id);
  if (!info.ok()) return info.status();
  Result<Campaign> campaign = ParseCampaign(info->definition);
  if (!campaign.ok() || !campaign->adaptive) return Out();
  const AdaptiveSettings& settings = *campaign->adaptive;
  std::vector<SweepSpec> declared = campaign->sweeps;
  for (SweepSpec& s : declared) s.scale = info->scale;
  Result<std::vector<rounds::RoundRow>> stored = rounds::ListRounds(*store_, campaign_run_id);
  if (!stored.ok()) return stored.status();
  if (stored->empty()) {
    // Round 1 is what was submitted: its row says so and what it was planned to cost.
    Result<AdaptiveCost> cost = rounds::AdaptiveCostNow(*store_, info->scale, now);
    if (!cost.ok()) return cost.status();
    const AdaptiveRound first = FirstRound(AdaptiveSweepsOf(declared), *cost);
    rounds::RoundRow row;
    row.campaign_run_id = campaign_run_id;
    row.round = 1;
    row.planned_at = info->created_at;
    row.core_h_planned = first.core_h;
    row.actions = ActionsJson(first);
    row.run_s_per_unit = cost->run_rate.s_per_unit;
    row.bed_s_per_unit = cost->bed_rate.s_per_unit;
    Status s = store_->db().Write([&](Transaction& t) { return rounds::InsertRound(t, row); });
    if (!s.ok() && s.code() != StatusCode::kConflict) return s;
    stored->push_back(row);
  }
  const rounds::RoundRow& last = stored->back();
  if (last.stop_reason || last.finished_at) return Out();

  // Cheap check before anything is analysed: the look waits until none of its runs or beds is
  // queued or running, a cancelled sweep's too, so that the last look charges every run that ran
  // (a run still running when its sweep was cancelled would otherwise never be charged; the
  // cancel check inside the write below keeps runs from being added meanwhile).
  Result<int64_t> busy = rounds::BusyJobs(*store_, campaign_run_id);
  if (!busy.ok()) return busy.status();
  if (*busy > 0) return Out();
  Result<int64_t> cancelled_sweeps = rounds::CancelledSweeps(*store_, campaign_run_id);
  if (!cancelled_sweeps.ok()) return cancelled_sweeps.status();
  Result<AdaptiveCost> cost = rounds::AdaptiveCostNow(*store_, info->scale, now);
  if (!cost.ok()) return cost.status();

  // Longer runs that ended: a failed one gives its point's place back to the earlier run, before
  // the claims are looked at (stored at once: the look below reads the sweeps as they are now).
  SANDSWIM_RETURN_IF_ERROR(store_->db().Write(
      [&](Transaction& t) { return rounds::SettleReplacements(t, campaign_run_id, now).status(); }));

  // The ledger's reads come before the look, and its write (below) reads them again inside its
  // transaction: an attempt that closed meanwhile (a forced rerun of a shared run, say) is neither
  // missed nor charged twice; the look is taken again at the next tick instead.
  Result<std::vector<rounds::ClosedAttempt>> attempts = rounds::UnchargedAttempts(*store_, campaign_run_id);
  if (!attempts.ok()) return attempts.status();
  Result<double> charged_before = rounds::ChargedCoreHours(*store_, campaign_run_id);
  if (!charged_before.ok()) return charged_before.status();

  Result<ClaimLook> look = look_(*store_, *info);
  if (!look.ok()) return look.status();
  int cancelled = 0;
  for (const ClaimSweep& s : look->input.sweeps)
    for (const ClaimRun& r : s.runs) cancelled += r.state == JobState::kCancelled;

  // The ledger: each attempt closed since the last look is charged once, at the rates its round
  // was planned at; the budget left is the budget less every charge so far (a replaced or failed
  // run stays charged).
  const AdaptiveCost round_cost = rounds::RoundRates(last, *cost);
  std::vector<rounds::Charge> charges;
  double charging = 0;
  for (const rounds::ClosedAttempt& a : *attempts) {
    charges.push_back(Price(a, round_cost, campaign_run_id, info->created_at));
    charging += charges.back().core_h;
  }
  const std::set<PricedAttempt> priced = PricedOf(*attempts);

  // The look after round `last.round`.
  Result<std::map<std::string, rounds::FrozenVerdict>> frozen_rows = rounds::FrozenVerdicts(*store_, campaign_run_id);
  if (!frozen_rows.ok()) return frozen_rows.status();
  AdaptiveState state;
  std::map<std::string, int> frozen_round;
  for (const auto& [claim, f] : *frozen_rows) {
    state.frozen[claim] = f.verdict;
    frozen_round[claim] = f.round;
  }
  const std::vector<ClaimVerdict> verdicts = EvaluateClaims(look->claims, look->input);
  std::map<std::string, json> decided_by;  // the verdicts this look decides, as it reads them
  for (const std::string& claim : FreezeDecisions(verdicts, state.frozen)) {
    frozen_round[claim] = last.round;
    for (const ClaimVerdict& v : verdicts)
      if (v.claim.id == claim) decided_by[claim] = ClaimVerdictToJson(v);
  }
  state.claims = look->claims;
  state.sweeps = AdaptiveSweepsOf(declared);
  state.input = look->input;
  state.rounds_done = last.round;
  state.spent_core_h = *charged_before + charging;

  AdaptiveOptions options = options_.adaptive;
  options.max_rounds = settings.max_rounds;
  AdaptiveRound next;
  next.round = last.round + 1;
  if (*cancelled_sweeps > 0 || cancelled > 0) {
    next.stop = true;
    next.stop_reason = (*cancelled_sweeps > 0 ? std::to_string(*cancelled_sweeps) + " of its sweeps"
                                              : std::to_string(cancelled) + " of its runs") +
                       " were cancelled: its rounds stop there (submit the campaign again to start anew)";
  } else if (state.spent_core_h >= settings.budget_core_h) {
    next.stop = true;
    next.stop_reason = "the budget is spent: its runs and beds were charged " + CoreHText(state.spent_core_h) +
                       " of the " + CoreHText(settings.budget_core_h) + " budgeted";
  } else {
    next = PlanNextRound(state, settings.budget_core_h, *cost, options);
    // The planner keeps within what is left; a round that would not is refused here too.
    if (!next.stop && next.core_h > settings.budget_core_h - state.spent_core_h + 1e-12) {
      next.stop = true;
      next.stop_reason = "the budget is spent: round " + std::to_string(next.round) + " would need " +
                         CoreHText(next.core_h) + " and " + CoreHText(settings.budget_core_h - state.spent_core_h) +
                         " is left";
      next.actions.clear();
    }
  }
  const json after = StatesAfter(look->claims, state.frozen, frozen_round);
  const double left = settings.budget_core_h - state.spent_core_h;

  // Plans of the next round's runs, before the transaction (nothing to refuse inside it but the cap).
  std::vector<ScalePlan> plans;
  std::vector<std::optional<int64_t>> replaced;
  std::vector<std::string> order_sweep;
  if (!next.stop) {
    for (const AdaptiveAction& a : next.actions)
      for (const RunOrder& o : a.runs) {
        Result<ScalePlan> plan = PlanOrder(o, info->scale, declared, options_.engine_version);
        if (!plan.ok()) return plan.status().WithFieldPrefix("round " + std::to_string(next.round) + " (" + a.claim + ")");
        plans.push_back(std::move(plan).value());
        replaced.push_back(o.replaces ? ReplacedRun(look->input, o) : std::nullopt);
        order_sweep.push_back(o.sweep);
      }
  }

  Status written = store_->db().Write([&](Transaction& t) -> Status {
    // What the look read is what is charged: none of its runs or beds was queued again, and the
    // attempts to charge are the ones priced.
    Result<int64_t> busy_now = rounds::BusyJobs(t, campaign_run_id);
    if (!busy_now.ok()) return busy_now.status();
    Result<std::vector<rounds::ClosedAttempt>> attempts_now = rounds::UnchargedAttempts(t, campaign_run_id);
    if (!attempts_now.ok()) return attempts_now.status();
    if (*busy_now > 0 || PricedOf(*attempts_now) != priced) {
      return Status(StatusCode::kConflict, "its runs changed while it was looked at; it is looked at again", "look");
    }
    // A cancel between the look and this write stops the rounds too: nothing is added to a
    // cancelled sweep.
    if (!next.stop) {
      Result<int64_t> now_cancelled = rounds::CancelledSweeps(t, campaign_run_id);
      if (!now_cancelled.ok()) return now_cancelled.status();
      if (*now_cancelled > 0) {
        next.stop = true;
        next.stop_reason = std::to_string(*now_cancelled) +
                           " of its sweeps were cancelled: its rounds stop there (submit the campaign again to "
                           "start anew)";
      }
    }
    Result<double> spent_now = rounds::AddCharges(t, campaign_run_id, last.round, now, charges);
    if (!spent_now.ok()) return spent_now.status();
    SANDSWIM_RETURN_IF_ERROR(rounds::FinishRound(t, campaign_run_id, last.round, now, *spent_now, after,
                                                 next.stop ? std::optional<std::string>(next.stop_reason) : std::nullopt));
    SANDSWIM_RETURN_IF_ERROR(rounds::FreezeVerdicts(t, campaign_run_id, last.round, now, state.frozen, decided_by));
    if (next.stop) return Status::Ok();
    rounds::RoundRow row;
    row.campaign_run_id = campaign_run_id;
    row.round = next.round;
    row.planned_at = now;
    row.core_h_planned = next.core_h;
    row.actions = ActionsJson(next);
    row.run_s_per_unit = cost->run_rate.s_per_unit;  // planned at these: its attempts are charged at them
    row.bed_s_per_unit = cost->bed_rate.s_per_unit;
    SANDSWIM_RETURN_IF_ERROR(rounds::InsertRound(t, row));
    Result<std::map<std::string, rounds::SweepSlot>> slots = rounds::CampaignRunSweeps(t, campaign_run_id);
    if (!slots.ok()) return slots.status();
    std::map<std::string, int64_t> ids;
    std::map<int64_t, int64_t> next_position;
    std::vector<int64_t> sweep_ids;
    for (const auto& [name, slot] : *slots) {
      ids[name] = slot.id;
      next_position[slot.id] = slot.next_position;
      sweep_ids.push_back(slot.id);
    }
    SubmitResult added;
    for (size_t i = 0; i < plans.size(); ++i) {
      SANDSWIM_RETURN_IF_ERROR(
          AddPlannedRuns(t, plans[i], options_.engine_version, now, ids, next_position, added));
      if (replaced[i]) {
        Result<int64_t> n = rounds::ReplaceInCampaignRunSweeps(t, campaign_run_id, next.round, *replaced[i],
                                                               plans[i].plan.runs.front().key, order_sweep[i]);
        if (!n.ok()) return n.status();
      }
    }
    return FinishAddedRuns(t, sweep_ids, options_.max_queued_runs, added);
  });
  // Another pass took this look first (what it stored stands), or the runs changed since it read
  // them (the next tick looks again).
  if (written.code() == StatusCode::kConflict && (written.field() == "round" || written.field() == "look")) {
    return Out();
  }
  if (!written.ok()) return written;

  RoundStep step;
  step.campaign_run_id = campaign_run_id;
  step.stopped = next.stop;
  step.round = next.stop ? last.round : next.round;
  step.text = "campaign run " + std::to_string(campaign_run_id) + ": " +
              (next.stop ? "rounds stop after round " + std::to_string(last.round) + ": " + next.stop_reason
                         : DescribeRound(next, left));
  return Out(std::move(step));
}

}  // namespace sandswim
