// The rounds of adaptive campaign runs (schema/015_campaign_rounds.sql): one row per
// round (what it added and why, core-hours planned and spent, the rates it was planned at, the
// claims' states after it, why the campaign run stopped) and the verdicts frozen at their first
// deciding look with that look's verdict; and what the campaign run has spent, a ledger of charged
// attempts at its runs and beds (schema/016_campaign_run_charges.sql, 018_attempt_charges.sql). The driver that
// writes them is server/jobs/rounds.h; GET /api/v1/campaign-runs/{id} and `sandswim status cr:ID`
// read them.
//
// Writes take the caller's transaction, so that a round's row, the look that finishes the round
// before it, its frozen verdicts and its runs are stored together or not at all. InsertRound
// refuses (kConflict) a round already stored and FinishRound one already finished: a second
// driver (or a daemon started again) that planned the same round from the same store loses its
// transaction instead of storing a duplicate.
//
// Thread safety: as Store (each call is one transaction, or runs in the caller's).
#ifndef SANDSWIM_SERVER_STORE_ROUNDS_H_
#define SANDSWIM_SERVER_STORE_ROUNDS_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/adaptive.h"
#include "core/status.h"
#include "server/store/database.h"
#include "server/store/store.h"

namespace sandswim::rounds {

struct RoundRow {
  int64_t campaign_run_id = 0;
  int round = 0;
  double planned_at = 0;
  std::optional<double> finished_at;
  double core_h_planned = 0;
  std::optional<double> core_h_spent;
  nlohmann::json actions = nlohmann::json::array();  // ActionToJson of each
  nlohmann::json verdicts_after;                      // null until its look
  std::optional<std::string> stop_reason;
  // The cost model's rates it was planned at (core/cost.h EngineRate::s_per_unit: runs per
  // particle-step, beds per grain); unset for rounds planned before migration 18.
  std::optional<double> run_s_per_unit;
  std::optional<double> bed_s_per_unit;
};

struct FrozenVerdict {
  Verdict verdict = Verdict::kInconclusive;
  int round = 0;
  double frozen_at = 0;
  // The deciding look's verdict (core/claims.h ClaimVerdictToJson of the claims' own evaluation
  // then: its parts, numbers and reason); null for verdicts frozen before migration 18.
  nlohmann::json decided_by;
};

// {"kind","claim","reason","core_h","sim_s","gain","draws","new_beds","runs":[{"sweep","point",
//  "replicate","max_duration_s","replaces"}]}
nlohmann::json ActionToJson(const AdaptiveAction& a);

// The rounds as GET /api/v1/campaign-runs/{id} shows them, `budget_core_h` the campaign's:
// [{"round","planned_at","finished_at","core_h_planned","core_h_spent","budget_left_core_h"
//   (after it: the budget less every round's spending so far; null until its look),
//   "actions":[{"kind","claim","reason","core_h","runs" (how many)}],"claims_after":[{"claim",
//   "verdict","frozen_at_round"?}] (null until its look),"stop_reason","rates":{"run_s_per_unit",
//   "bed_s_per_unit"} (what it was planned and is charged at; null before migration 18)}]
nlohmann::json RoundsToJson(const std::vector<RoundRow>& rows, double budget_core_h);

// The rounds of a campaign run, in order (none: not adaptive, or its first look is to come).
Result<std::vector<RoundRow>> ListRounds(Transaction& t, int64_t campaign_run_id);
Result<std::vector<RoundRow>> ListRounds(Store& store, int64_t campaign_run_id);
Result<std::map<std::string, FrozenVerdict>> FrozenVerdicts(Transaction& t, int64_t campaign_run_id);
Result<std::map<std::string, FrozenVerdict>> FrozenVerdicts(Store& store, int64_t campaign_run_id);

// Campaign runs whose recorded definition is adaptive and that have not stopped, oldest first.
Result<std::vector<int64_t>> OpenAdaptiveCampaignRuns(Store& store);

// The cost model's rates now (server/store/cost_model.h ReadCostModel: the pooled run rate and the
// one-rank bed rate) at `scale`, as the planner costs rounds and the budget check prices round 1.
// InvalidArgument "scale" for an unknown scale.
Result<AdaptiveCost> AdaptiveCostNow(Store& store, const std::string& scale, double now);

// kConflict when the round is stored already.
Status InsertRound(Transaction& t, const RoundRow& row);
// The look after a round: kConflict when it was taken already (finished_at set).
Status FinishRound(Transaction& t, int64_t campaign_run_id, int round, double now, double core_h_spent,
                   const nlohmann::json& verdicts_after, const std::optional<std::string>& stop_reason);
// Stores the verdicts `frozen` holds that are not stored yet, as frozen at `round`, each with the
// look's verdict that decided it (`decided_by`, by claim: ClaimVerdictToJson).
Status FreezeVerdicts(Transaction& t, int64_t campaign_run_id, int round, double now,
                      const std::map<std::string, Verdict>& frozen,
                      const std::map<std::string, nlohmann::json>& decided_by);

// ---- What a campaign run spent: the ledger ---------------------------------------------------

// An attempt at a run or bed of the campaign run (a member of its sweeps, or a run a longer one
// replaced there): a lease that has closed (completed, failed, expired, handed back, taken back
// unreceived; schema/018) and is not charged yet. A lease granted before a look of the old,
// per-ending ledger (rows without a lease token, before migration 18) counts as charged by it.
struct ClosedAttempt {
  std::string kind;  // "run" | "bed"
  int64_t id = 0;
  std::string lease_token;
  double granted_at = 0;
  double ended_at = 0;   // the lease's closed_at (its completed_at, or its grant, before 18)
  std::string outcome;   // the lease's: done | failed | queued | cancelled | expired | released | unreceived
  std::optional<double> sim_time_s;  // runs: what the attempt reached (done: its result's); NULL: none known
  double run_duration_s = 0;         // runs: its planned length at the scale
  Point point;                       // a run's point; a bed's: the point of one of its runs here
  // Who pays for it in full. `payer_decided` (leases granted from migration 19 on): the campaign
  // run its grant chose (DecideLeasePayer; unset: none held the job then). Before 19, as the
  // ledger decides at the look: the earliest other adaptive campaign run that holds the job in
  // its sweeps now and had not stopped when it was leased, else this one.
  std::optional<int64_t> payer;
  bool payer_decided = false;
};
Result<std::vector<ClosedAttempt>> UnchargedAttempts(Transaction& t, int64_t campaign_run_id);
Result<std::vector<ClosedAttempt>> UnchargedAttempts(Store& store, int64_t campaign_run_id);

struct Charge {
  std::string kind;  // "run" | "bed"
  int64_t id = 0;
  double ended_at = 0;
  std::string state;  // the lease's outcome (per ending, before 18: the job's state)
  std::optional<double> sim_time_s;
  // "result", "heartbeat", "planned length", "never ran", "bed", "leased before", "paid by campaign
  // run N", "leased for no campaign run" (no adaptive campaign run held it at the grant); before 18
  // also "stored before"
  std::string priced_by;
  double core_h = 0;
  std::string lease_token;  // the attempt charged ("": a charge per ending, as before migration 18)
};
// Stores the charges at the look after `round`; an attempt (or, without a token, an ending)
// charged already is not charged again. Returns the core-hours newly charged.
Result<double> AddCharges(Transaction& t, int64_t campaign_run_id, int round, double now,
                          const std::vector<Charge>& charges);
// The sum of the campaign run's charges: what it has spent (0 with none).
Result<double> ChargedCoreHours(Transaction& t, int64_t campaign_run_id);
Result<double> ChargedCoreHours(Store& store, int64_t campaign_run_id);

// The cost model's rates a round was planned at (RoundRow's), else `now`'s: what its attempts are
// charged at.
AdaptiveCost RoundRates(const RoundRow& round, AdaptiveCost now);

// Who pays for an attempt, decided once by its grant, in the grant's transaction (schema/019):
// the earliest adaptive campaign run, its rounds not stopped and none of its sweeps cancelled,
// that holds the leased run (a bed: one of its runs), by the ledger's own definition of its runs
// (its sweeps' members and the runs of its replacements). None: the payer stays NULL.
// The lease `token` (kind, job_id) is stored already.
Status DecideLeasePayer(Transaction& t, const std::string& token, api::JobKind kind, int64_t job_id);

// How many of the campaign run's runs (its sweeps' members and the runs of its replacements), and
// beds under them, are queued or running: a look waits for 0 (one cheap query, before anything is analysed; again inside its write).
Result<int64_t> BusyJobs(Transaction& t, int64_t campaign_run_id);
Result<int64_t> BusyJobs(Store& store, int64_t campaign_run_id);

// The campaign run's sweeps by name, and each one's next membership position.
struct SweepSlot {
  int64_t id = 0;
  int64_t next_position = 0;
};
Result<std::map<std::string, SweepSlot>> CampaignRunSweeps(Transaction& t, int64_t campaign_run_id);
// How many of the campaign run's sweeps are cancelled (cancelling is how its owner stops it: its
// runs may all have finished, or be shared with another campaign run's live sweep, so no run of
// it need end `cancelled`).
Result<int64_t> CancelledSweeps(Transaction& t, int64_t campaign_run_id);
Result<int64_t> CancelledSweeps(Store& store, int64_t campaign_run_id);
// A longer run (its key `new_run_key`, written already) takes `old_run_id`'s place in the campaign
// run's sweep named `sweep` (the one the longer run joined): that membership of the old run is
// recorded as a replacement of the round (schema/016: campaign_run_replacements) and removed (the
// run and its result stay, in the campaign run's other sweeps, any other sweep that has it, and
// in the ledger). Returns the memberships replaced (0 or 1).
Result<int64_t> ReplaceInCampaignRunSweeps(Transaction& t, int64_t campaign_run_id, int round, int64_t old_run_id,
                                           const std::string& new_run_key, const std::string& sweep);
// Settles the replacements whose longer run has ended: done, it stands; failed or cancelled, the
// replaced run goes back to its place and the longer one leaves the sweep, so the point keeps its
// earlier measurement. The sweeps' counts are redone. Returns how many were put back. Once each.
Result<int64_t> SettleReplacements(Transaction& t, int64_t campaign_run_id, double now);

// Whether a campaign run runs in rounds: its recorded definition has an "adaptive" object. The
// claims shown (server/analysis/claim_check.h) and the live feed (server/dashboard) ask it.
bool RunsInRounds(const CampaignRunInfo& campaign_run);

// An adaptive campaign run's settings as its definition states them, with the defaults filled in
// (core/sweep.h AdaptiveSettings): {"budget_core_h","max_rounds"}; null for a fixed design.
nlohmann::json AdaptiveSettingsJson(const CampaignRunInfo& campaign_run);

// What GET /api/v1/campaign-runs/{id} and the report show of a campaign run's rounds:
// {"adaptive": AdaptiveSettingsJson, "rounds": RoundsToJson (the campaign's budget; [] for a
// fixed design)}.
Result<nlohmann::json> RoundsReply(Store& store, const CampaignRunInfo& campaign_run);

}  // namespace sandswim::rounds

#endif  // SANDSWIM_SERVER_STORE_ROUNDS_H_
