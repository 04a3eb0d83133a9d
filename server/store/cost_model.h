// The cost model's readings (core/cost.h) from the daemon's database: the engine rates measured so
// far and the ETA of a sweep or a campaign run.
//
// Rates are measured, never configured: a done run's result holds its steps, grains, wall time,
// host and rank count; a running run's row holds the step it reached at its last heartbeat; a done
// bed holds its grains, its start and end and the ranks it ran on (NULL for beds prepared before
// migration 14: counted as one rank, and the basis says how many). ReadCostModel groups the runs'
// rates by host and rank count and the beds' by rank count (a bed on 2 ranks takes about 0.7x the
// time of one on 1 rank: pooled, it made the next one-rank bed look up to 30 % shorter), which is
// what `GET /api/v1/cost-model` and `sandswim expand --cost` show, and pools the newest
// kRateWindow results with the running runs' progress for the ETA, so the estimate follows the
// machine's load as it is now and exists from a run's first heartbeats. ReadEta adds up what is
// left of a sweep's or a campaign run's runs and beds (core/cost.h EstimateEta).
//
// Thread safety: as Store (each call is one read transaction).
#ifndef SANDSWIM_SERVER_STORE_COST_MODEL_H_
#define SANDSWIM_SERVER_STORE_COST_MODEL_H_

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/cost.h"
#include "core/status.h"
#include "server/store/store.h"

namespace sandswim {

// Results pooled for the ETA's rate: the newest this many (older ones may be another load).
inline constexpr int kRateWindow = 50;
// A running run counts once it has run this long (before, its wall time is mostly the engine's start).
inline constexpr double kMinProgressSampleS = 20;
// A running job (run or bed) counts as an engine while it heartbeats: its last heartbeat (before
// its first, its grant) at most this old. A worker heartbeats every 5 s (at most a third of the
// lease's TTL, 60 s by default), so 12 beats missed; a job whose worker died keeps its lease
// longer after a daemon restart (the outage does not count against it: LeaseQueue::
// ExtendLeasesAfterRestart) and counted as an engine before this rule ("4 engines" on 2 slots).
inline constexpr double kLiveEngineS = 60;

struct HostRate {
  std::string host;
  int ranks = 1;
  EngineRate rate;  // per particle-step
};

struct CostModelView {
  std::vector<HostRate> hosts;  // done runs, per host and rank count, by host then ranks
  EngineRate run_rate;          // pooled for the ETA (see above), per particle-step
  EngineRate bed_rate;          // done beds on one rank, per grain (BedRateOnRanks(bed_rates, 1))
  std::vector<RankRate> bed_rates;  // done beds, per rank count, by ranks
  int engines_in_flight = 0;    // runs and beds running now that heartbeat (kLiveEngineS)
  int silent_jobs = 0;          // running ones that do not (their leases not yet expired)
  // The live running runs' rate over the last kShareWindowS against run_rate (core/cost.h
  // CurrentShare, from their progress marks: job_table.h RecordProgress). The ETA's rates are
  // AtShare(run_rate, share) and AtShare(bed_rate, share): the machine's share as it is now.
  Share share;
};
// {"run_rate":{...},"bed_rate":{...},"bed_rates":[{"ranks",...rate}],"hosts":[{"host","ranks",...rate}],
//  "engines_in_flight","engines_silent","share":{"measured","factor","factor_before"?,"rel_error","engines",
//  "window_s"}}; a rate: {"s_per_unit","rel_error","samples","basis"}.
void to_json(nlohmann::json& j, const CostModelView& v);
void to_json(nlohmann::json& j, const EngineRate& r);

Result<CostModelView> ReadCostModel(Store& store, double now);

// Inside a transaction: the pooled run rate (per particle-step); the newest kRateWindow done beds'
// rates (per grain) per rank count; the bed rate on `ranks` ranks (core/cost.h BedRateOnRanks).
Result<EngineRate> PooledRunRate(Transaction& t);
Result<std::vector<RankRate>> BedRatesByRanks(Transaction& t);
Result<EngineRate> BedRate(Transaction& t, int ranks = 1);

// A lease's wall budget when the operator sets none (sandswimd --wall-budget 0): this multiple of
// the cost model's prediction, plus a margin for the engine's start and a slow first rate. At the
// default rate a smoke run of 2 s (200,000 steps of 6,683 particles) is predicted 869 s: its
// budget is 4 x 869 + 600 = 4,076 s; a smoke bed 768 s: 3,673 s. A host 4x slower than its
// measured rate still finishes; a hung engine is stopped sooner by the worker's --stall-after.
inline constexpr double kWallBudgetMultiple = 4;
inline constexpr double kWallBudgetMarginS = 600;
// The budget of a lease on bed `bed_id` (bed = true: at the one-rank bed rate, since a worker may or
// may not widen it) or of a run of `steps` steps on it.
Result<double> WallBudget(Transaction& t, bool bed, int64_t bed_id, int64_t steps);

enum class EtaScope { kSweep, kCampaignRun };
// The ETA of what is left of a sweep or a campaign run, over max(engines in flight, min_slots)
// engines (sandswimd passes its local workers; a running job counts only while it heartbeats),
// at the cost model's rates scaled to the current share (CostModelView::share). nullopt when
// nothing is left.
Result<std::optional<Eta>> ReadEta(Store& store, EtaScope scope, int64_t id, double now, int min_slots);

// {"s","rel_error","low_s","high_s","basis"} (a 1-sigma band on a log scale: low_s = s / e^rel_error,
// high_s = s * e^rel_error), or null.
nlohmann::json EtaJson(const std::optional<Eta>& eta);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_COST_MODEL_H_
