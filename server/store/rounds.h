// The rounds of adaptive campaign runs (schema/015_campaign_rounds.sql): one row per
// round (what it added and why, core-hours planned and spent, the claims' states after it, why
// the campaign run stopped) and the verdicts frozen at their first deciding look; and what the
// campaign run has spent, a ledger of charged runs and beds (schema/016_campaign_run_charges.sql). The driver that
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
};

struct FrozenVerdict {
  Verdict verdict = Verdict::kInconclusive;
  int round = 0;
  double frozen_at = 0;
};

// {"kind","claim","reason","core_h","sim_s","gain","draws","new_beds","runs":[{"sweep","point",
//  "replicate","max_duration_s","replaces"}]}
nlohmann::json ActionToJson(const AdaptiveAction& a);

// The rounds as GET /api/v1/campaign-runs/{id} shows them, `budget_core_h` the campaign's:
// [{"round","planned_at","finished_at","core_h_planned","core_h_spent","budget_left_core_h"
//   (after it: the budget less every round's spending so far; null until its look),
//   "actions":[{"kind","claim","reason","core_h","runs" (how many)}],"claims_after":[{"claim",
//   "verdict","frozen_at_round"?}] (null until its look),"stop_reason"}]
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
// Stores the verdicts `frozen` holds that are not stored yet, as frozen at `round`.
Status FreezeVerdicts(Transaction& t, int64_t campaign_run_id, int round, double now,
                      const std::map<std::string, Verdict>& frozen);

// ---- What a campaign run spent: the ledger ---------------------------------------------------

// A run or bed of the campaign run (a member of its sweeps, or a run a longer one replaced there)
// that has ended and whose ending is not charged yet: what pricing it needs.
struct EndedJob {
  std::string kind;   // "run" | "bed"
  int64_t id = 0;
  double ended_at = 0;  // its finished_at (0 when none was recorded)
  JobState state = JobState::kDone;  // done | failed | cancelled
  int attempts = 0;     // runs: leases it was granted (0: it never ran)
  std::optional<double> sim_time_s;  // runs: done, its result's; else its last heartbeat's (NULL: none)
  double run_duration_s = 0;         // runs: its planned length at the scale
  Point point;                       // a run's point; a bed's: the point of one of its runs here
};
Result<std::vector<EndedJob>> UnchargedEndedJobs(Transaction& t, int64_t campaign_run_id);
Result<std::vector<EndedJob>> UnchargedEndedJobs(Store& store, int64_t campaign_run_id);

struct Charge {
  std::string kind;  // "run" | "bed"
  int64_t id = 0;
  double ended_at = 0;
  JobState state = JobState::kDone;
  std::optional<double> sim_time_s;
  std::string priced_by;  // "result", "heartbeat", "planned length", "never ran", "bed", "stored before"
  double core_h = 0;
};
// Stores the charges at the look after `round`; an ending charged already is not charged again.
// Returns the core-hours newly charged.
Result<double> AddCharges(Transaction& t, int64_t campaign_run_id, int round, double now,
                          const std::vector<Charge>& charges);
// The sum of the campaign run's charges: what it has spent (0 with none).
Result<double> ChargedCoreHours(Transaction& t, int64_t campaign_run_id);
Result<double> ChargedCoreHours(Store& store, int64_t campaign_run_id);

// How many runs of the campaign run's sweeps, and beds under them, are queued or running: a look
// waits for 0 (one cheap query, before anything is analysed).
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
