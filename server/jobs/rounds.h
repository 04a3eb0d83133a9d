// RoundDriver: runs adaptive campaign runs (a campaign with "adaptive", core/sweep.h
// AdaptiveSettings) in rounds, on the daemon's scheduler tick. The decisions are core/adaptive.h's;
// this is the part that reads the store and writes to it.
//
// A campaign run is submitted as usual (server/jobs/submission.h): its runs are round 1, every
// declared point on one bed (core/adaptive.h FirstRound; the campaign's budget was checked against
// it at PUT and at submission). On each tick, for every adaptive campaign run that has not
// stopped (server/store/rounds.h OpenAdaptiveCampaignRuns):
//   1. round 1's row is stored if it is not yet (what was submitted, and its planned cost);
//   2. a campaign run with a cancelled sweep stops (cancelling is how its owner stops it; no run of
//      it need end cancelled). Else, while any run or bed of it is queued or running (one cheap
//      query, server/store/rounds.h BusyJobs), nothing more happens: nothing is analysed;
//   3. else the longer runs of the last round that failed (or were cancelled) give their points'
//      places back to the runs they replaced (server/store/rounds.h SettleReplacements: a failed
//      longer run never costs a point its earlier measurement); the attempts to charge are read
//      (server/store/rounds.h UnchargedAttempts: every lease of its runs and beds that closed and
//      is not charged yet), then the claims are looked at (`look`: server/analysis/claim_check.h
//      LookAtClaims, the data the verdicts shown are decided on), the verdicts each decides are
//      frozen (FreezeDecisions: never looked at again) with the look's own verdict, every attempt
//      is priced (Price in rounds.cc: a run attempt the simulated time it reached, recorded when
//      its lease closed -- the result's when done, else the last heartbeat's, else its planned
//      length; a bed attempt the bed's cost) at the rates its round was planned at, and the budget
//      left is the budget less the ledger: at 0 the rounds stop, else PlanNextRound plans the next
//      round within it (at the rates now, stored with it) or says why none follows (every claim
//      decided, max_rounds rounds run, nothing left that could decide);
//   4. in ONE transaction, which first reads again whether any run or bed of it is busy and which
//      attempts are uncharged (changed since they were read: nothing is written, and the next tick
//      looks again): the charges, the round's look (finished_at, core-h charged at it, the
//      claims' states after it, the stop reason), the verdicts frozen at it, the next round's row
//      and its runs (added to the campaign run's sweeps: a new bed is the next replicate index, a
//      new point joins its sweep, a longer run takes its point's place on that bed in the campaign
//      run's sweeps, recorded as a replacement until it is settled at the next look). A charge is
//      never deleted: a run that a longer one replaced, and a failed longer run, stay charged.
//      The analysis itself runs outside the write: the writer's transaction is shared with every
//      heartbeat and completion (group commit), which must not wait seconds for a look.
// Restart-safe: everything it knows is in the store. A daemon stopped anywhere in a pass either
// committed the round or did not; the next pass (of this daemon or the next) continues from what
// is stored. Two passes that plan the same round from the same store cannot both store it (the
// round's look is taken once: server/store/rounds.h FinishRound), so no round is stored twice.
// A campaign run some of whose runs or sweeps were cancelled stops, saying so.
//
// A rerun of an adaptive campaign (the nightly scheduler's) has rounds of its own, planned again
// from round 1; the runs it orders again are found stored by key and cost it nothing (their
// attempts were leased before it was submitted), so it replays the earlier rounds at no cost and
// spends where claims are open. A run the night before's campaign run still runs when the rerun
// starts is that campaign run's to pay (leased before the rerun), and so is an attempt leased
// later while the earlier campaign run has not stopped (the earliest live adaptive campaign run
// that holds a job pays for its attempts): each attempt is charged once across campaign runs.
//
// Left for later: a rerun's round 1 does not take in the earlier nights' later rounds directly;
// the planner may order again a longer run that failed; a longer run starts from its beginning
// (continuing from the restart written at the end of the shorter one is not done).
//
// Thread safety: Tick() from one thread at a time (the scheduler's); the Store is thread-safe.
#ifndef SANDSWIM_SERVER_JOBS_ROUNDS_H_
#define SANDSWIM_SERVER_JOBS_ROUNDS_H_

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/adaptive.h"
#include "core/status.h"
#include "server/jobs/submission.h"
#include "server/store/store.h"

namespace sandswim {

// How a campaign run's claims are looked at (the daemon: LookAtClaims). Injected, because the
// jobs room does not see the analysis room (docs/development/architecture.md).
using ClaimLookFn = std::function<Result<ClaimLook>(Store&, const CampaignRunInfo&)>;

// What one pass did for one campaign run.
struct RoundStep {
  int64_t campaign_run_id = 0;
  int round = 0;  // the round planned (or, stopped: the last one run)
  bool stopped = false;
  std::string text;  // "campaign run 7: round 2: F4: ... (+0.4 core-h, 3.1 core-h left)" / "... stops: ..."
};

struct RoundDriverOptions {
  std::string engine_version;  // enters the keys of the runs it adds
  int64_t max_queued_runs = kMaxQueuedRuns;
  AdaptiveOptions adaptive;  // max_rounds is each campaign's own
};

class RoundDriver {
 public:
  RoundDriver(Store* store, ClaimLookFn look, RoundDriverOptions options);

  // One pass over every adaptive campaign run that has not stopped. A campaign run whose pass
  // fails is left as it was (logged by the caller from `errors`) and tried again next time.
  struct Pass {
    std::vector<RoundStep> steps;
    std::vector<std::pair<int64_t, Status>> errors;
  };
  Result<Pass> Tick(double now);

  // The same for one campaign run: nullopt when there is nothing to do yet (its runs are not all
  // finished, it is not adaptive, or it has stopped).
  Result<std::optional<RoundStep>> Step(int64_t campaign_run_id, double now);

 private:
  Store* store_;
  ClaimLookFn look_;
  RoundDriverOptions options_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_JOBS_ROUNDS_H_
