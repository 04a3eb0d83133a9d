// Claim-driven rounds: a campaign with claims run in rounds, each planned from the
// claims still undecided, until every claim is decided, the budget is spent or the look schedule
// ends. This file is the decision core; it runs nothing (the caller runs a round's orders and hands
// back what they gave, as ClaimRuns).
//
// THE FIRST ROUND (FirstRound) is the campaign's own fixed design at one bed: every declared point
// once, at the scale's precision target. Why: it is the design the claims' rules are calibrated at
// (templates/calibration/*.K1.json), it decides the sign and growth claims with power near 100 %
// there, and a second bed everywhere (K = 2) doubles the cost of points whose claims one bed
// already settles; replicates are then added where an undecided claim needs them.
//
// A LATER ROUND (PlanNextRound) looks at each claim still undecided that runs can decide (a rule
// with sweeps: not grain_count) and builds candidate actions for it, each a set of run orders:
//   replicate  one more bed at the claim's points that are not yet clear (a point is clear when
//              every bed is measured and, for a sign, its interval is clear of 0), or at all of them;
//   longer     the run of such a point run again twice as long with a target half as wide (a run
//              that ended at the surface or the floor is not: time cannot add periods to it),
//              at most `max_duration_factor` times the scale's target's maximum;
//   new point  interior_maximum: f halfway between the observed peak and each neighbour, on the
//              beds the peak ran on; only strictly inside the sweep's declared range of f, through
//              Validate and FitsScale like any point.
// Each candidate is scored by its EXPECTED GAIN, the drop in P(the claim stays inconclusive), per
// core-hour. The gain is estimated by simulation from the current estimates (a preposterior
// draw): `draws` times, the candidate's runs are given results drawn from what the runs so far
// say (a point's mean; a new bed off it by the between-bed scatter, measured with K >= 2, else the
// scale's bed prior; a run's error from the pooled per-period scatter of every measured run, over
// the periods its target and length allow; a point that reached a boundary on any bed reaches it
// again; a new point interpolated from its neighbours), the claim is evaluated on the data so far
// plus the draw by the claims' own code (EvaluateClaims), and the gain is the fraction of draws
// that decide it. A candidate is drawn only when a first, noiseless draw (every new value at its
// estimate) decides the claim: a claim held open by a point no run can measure (one that reaches
// the surface first in this box) stays open whatever is added, and is not drawn for (the price:
// an action that could decide only by luck is not seen). The claims' rules are never changed. Candidates are picked greedily, best gain
// per core-hour first, at most one per claim, while they fit the round's budget (what is left over
// the rounds left in the look schedule, and at least the cheapest candidate); each carries its
// reason ("F4: the peak lies between 4 and 6 Hz; adding f = 4.5, 5.5 on 1 bed: +0.48 core-h").
// A candidate is charged its runs at their maximum length and any new bed, so a round never spends
// more than it was given, even when no run stops early.
//
// HONEST SEQUENTIAL DECISIONS. Every look at the verdicts is a chance for a wrong one. A claim's
// verdict is FROZEN at the first look that decides it (FreezeDecisions): it is never re-examined,
// and the procedure's error rate is the chance that some look decides wrongly. The looks are a
// fixed schedule: at most `max_rounds` rounds (the first included), the budget spread evenly over
// them. The error rates of the whole procedure are measured on the truth engine
// (tests/bench/bench_adaptive.cc, tests/truth/adaptive_campaign.h), never assumed from the rules'.
//
// BUDGET. In core-hours of engine time (the cost model, core/cost.h: a run's particles times its
// steps times the rate, a bed's grains times the bed rate). ValidateAdaptiveBudget refuses one
// that cannot pay for the first round (no claim can be decided without its points) and names what
// it would need.
//
// Thread safety: pure functions and values.
#ifndef SANDSWIM_CORE_ADAPTIVE_H_
#define SANDSWIM_CORE_ADAPTIVE_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/claims.h"
#include "core/cost.h"
#include "core/point.h"
#include "core/precision.h"
#include "core/scale.h"
#include "core/status.h"
#include "core/sweep.h"

namespace sandswim {

// A sweep's declared points (ExpandSweep): a new point is allowed only inside their range.
struct AdaptiveSweep {
  std::string name;
  std::vector<Point> points;
};

// What engine work costs (core/cost.h), at one scale.
struct AdaptiveCost {
  const Scale* scale = nullptr;  // REQUIRED
  EngineRate run_rate = DefaultRate();
  EngineRate bed_rate = DefaultBedRate();
  // Core-hours of a run of `p` lasting at most `max_duration_s` on a bed of the scale's estimated
  // grains (plus the SO), at p's materials' time step.
  double RunCoreHours(const Point& p, double max_duration_s) const;
  double BedCoreHours(const Point& p) const;
};

enum class ActionKind { kFirstRound, kReplicate, kLonger, kNewPoint };
const char* ActionKindName(ActionKind kind);  // "first round", "replicate", "longer", "new point"

// One run a round asks for.
struct RunOrder {
  std::string sweep;  // the sweep the point belongs to (a new point: the sweep it joins)
  Point point;        // duration_s: max_duration_s
  int replicate = 0;  // the bed: 0 .. K-1; a replicate past the campaign run's beds is a new bed
  double max_duration_s = 0;
  std::optional<PrecisionTarget> precision;
  bool replaces = false;  // longer: this run replaces the point's run on that bed
};

struct AdaptiveAction {
  ActionKind kind = ActionKind::kReplicate;
  std::string claim;  // the claim it is for ("" for the first round)
  std::vector<RunOrder> runs;
  int new_beds = 0;   // beds it pours
  double core_h = 0;  // at most: its runs at their maximum length, its new beds
  double sim_s = 0;   // its runs' maximum simulated time
  double gain = 0;    // expected drop in P(the claim stays inconclusive), in [0, 1]
  int draws = 0;      // the draws the gain rests on
  std::string reason;
};

struct AdaptiveRound {
  int round = 0;  // 1: the first
  std::vector<AdaptiveAction> actions;
  std::vector<AdaptiveAction> considered;  // every candidate scored (those with no gain included)
  double core_h = 0, sim_s = 0;  // at most
  bool stop = false;             // nothing to run: the campaign stops before this round
  std::string stop_reason;
};

struct AdaptiveOptions {
  int max_rounds = 4;               // the look schedule: rounds in all, the first included
  int draws = 8;                    // preposterior draws per candidate
  uint64_t seed = 0x5eed;           // of the draws (a plan is the same each time)
  int max_beds = 4;                 // at a point
  double max_duration_factor = 4;   // times the scale's precision target's maximum
};

// A look at a campaign run's claims: the claims it is judged by and what its stored runs say, as
// the claims read them (server/analysis/claim_check.h LookAtClaims).
struct ClaimLook {
  std::vector<Claim> claims;
  ClaimInput input;
};

// What the campaign run knows before a round.
struct AdaptiveState {
  std::vector<Claim> claims;
  std::vector<AdaptiveSweep> sweeps;  // declared
  ClaimInput input;                   // the results so far, as the claims read them
  int rounds_done = 0;
  double spent_core_h = 0;
  std::map<std::string, Verdict> frozen;  // claims decided at an earlier look (FreezeDecisions)
};

// The first round's orders: every declared point once (a point two sweeps share once, under the
// first), on bed 0, at the scale's precision target (or its duration without one).
AdaptiveRound FirstRound(const std::vector<AdaptiveSweep>& sweeps, const AdaptiveCost& cost);

// A campaign's declared sweeps as the planner takes them (ExpandSweep; a sweep that does not expand
// has no points), at the scale its SweepSpecs name.
std::vector<AdaptiveSweep> AdaptiveSweepsOf(const std::vector<SweepSpec>& sweeps);

// An adaptive campaign's budget (Campaign::adaptive) against its first round at `scale` and the
// cost model's rates in `cost`: ValidateAdaptiveBudget's refusal on "adaptive.budget_core_h",
// saying the rates it was costed at. Ok for a campaign that is not adaptive.
Status CheckAdaptiveBudget(const Campaign& campaign, const std::string& scale, const AdaptiveCost& cost);

// Refuses (InvalidArgument "budget_core_h") a budget that is not finite and positive, or smaller
// than the first round: "... needs at least X core-h (the first round: N runs and 1 bed; the
// cheapest run alone: Y core-h)".
Status ValidateAdaptiveBudget(double budget_core_h, const AdaptiveRound& first_round);

// Freezes every claim the verdicts decide that is not frozen yet; returns the claims it froze.
std::vector<std::string> FreezeDecisions(const std::vector<ClaimVerdict>& verdicts,
                                         std::map<std::string, Verdict>& frozen);

// Claims that runs can decide (a rule naming sweeps) and that are not frozen, in the claims' order.
std::vector<std::string> OpenClaims(const AdaptiveState& state);

// The next round, or one with stop = true and why (every claim decided, the look schedule's last
// round done, the budget spent, or no action expected to decide a claim left).
AdaptiveRound PlanNextRound(const AdaptiveState& state, double budget_core_h, const AdaptiveCost& cost,
                            const AdaptiveOptions& options = {});

// "round 2: F4: the peak lies ...; F5: ... (+1.2 core-h, 3.4 core-h left)"
std::string DescribeRound(const AdaptiveRound& round, double left_core_h);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_ADAPTIVE_H_
