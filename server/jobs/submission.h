// Submission: turns a request (sweeps, or a campaign by name) into rows — one bed per scale,
// one run per distinct content key, the sweeps and their membership — in ONE transaction, so a
// refused submission leaves the database exactly as it was.
//
// Planning is core/sweep.h's PlanSweeps(): all sweeps of one submission that share a scale are
// planned together (a point shared by several sweeps runs once and belongs to each). Sweeps of
// different scales in one request are planned per scale.
//
// Content-key reuse: runs are keyed by RunKey (rendered deck + bed key + template and engine
// version); the runs table holds one row per key, so a run is done once:
//   - a new key                     -> a new queued run;
//   - an existing queued/running run -> shared, unchanged;
//   - an existing done run          -> reused (its result serves the new sweep), unless `force`:
//                                      then it is re-queued (attempts reset); its old result row
//                                      stays readable until the new completion replaces it;
//   - an existing failed/cancelled run -> re-queued (attempts reset): asking again is a retry.
// Beds follow the same rule by BedKey (a failed bed is re-queued; a done bed is reused, force
// or not: force re-runs drives, not bed preparation).
//
// Idempotency: with an idempotency_key, the first submission stores the key with a fingerprint
// of the (parsed, normalised) request. The same key with the same request later returns the
// same ids (replayed = true) and inserts nothing; the same key with a different request is
// kConflict naming "Idempotency-Key". A scheduled campaign run (trigger "schedule") is unique
// per (campaign, due_time): submitting it again returns the existing one (replayed = true).
//
// Queue cap: a submission after which more than `max_queued_runs` runs would be queued or running
// (all sweeps together) is kUnavailable, saying how many are and the cap, and stores nothing.
//
// Thread safety: a free function over a thread-safe Store.
#ifndef SANDSWIM_SERVER_SUBMISSION_H_
#define SANDSWIM_SERVER_SUBMISSION_H_

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "core/sweep.h"
#include "server/store/store.h"

namespace sandswim {

// Runs queued or running across all sweeps that a daemon holds by default (sandswimd
// --max-queued-runs): two paper-58 campaigns at full replication are under a thousand; 200,000
// is days of engine time on a cluster and a few hundred MB of rows.
inline constexpr int64_t kMaxQueuedRuns = 200000;

struct SubmitRequest {
  // Exactly one of: sweeps (non-empty), or campaign (a name: a campaign stored with
  // PutCampaign (campaigns.h), else a builtin one such as "paper-58").
  std::vector<SweepSpec> sweeps;
  std::optional<std::string> campaign;
  std::optional<std::string> scale;  // campaign only: overrides the campaign's default scale
  bool force = false;
  std::optional<std::string> idempotency_key;  // 1..200 printable ASCII characters
  std::string trigger = "manual";              // "manual" | "schedule" (campaigns)
  std::optional<double> due_time;              // schedule trigger: the slot it fills
  size_t max_runs = kMaxRunsPerSubmission;
  int64_t max_queued_runs = kMaxQueuedRuns;  // the daemon's queue cap (see above)
};

struct SubmitResult {
  std::vector<int64_t> sweep_ids;          // in request order (campaign: its sweeps' order)
  std::optional<int64_t> campaign_run_id;  // campaign submissions
  bool replayed = false;                   // an earlier identical submission answered
  int64_t runs = 0;                        // distinct runs the submission needs
  int64_t runs_new = 0;                    // rows created
  int64_t runs_reused = 0;                 // done runs whose results are reused
  int64_t runs_requeued = 0;               // done (force) / failed / cancelled runs queued again
  int64_t runs_shared = 0;                 // already queued or running for another sweep
  int64_t runs_failed_bed = 0;             // of those queued, failed at once: their bed failed for good
};
// {"ids":[...], "id": first id, "campaign_run_id"?, "replayed", "runs", "runs_new",
//  "runs_reused", "runs_requeued", "runs_shared", "runs_failed_bed"}
void to_json(nlohmann::json& j, const SubmitResult& r);

// Parses a POST /api/v1/sweeps body: a sweep object (ParseSweep), {"sweeps": [sweep, ...]},
// or {"campaign": "name", "scale"?: "mini"}; any of them with "force": bool. Errors name the
// field ("sweeps[1].base.A"). The idempotency key comes from the header, not the body.
Result<SubmitRequest> ParseSubmitRequest(const nlohmann::json& body);

// REQUIRES: `engine_version` is what workers' LIGGGHTS reports (it enters every key); `now` is
// the submission time (Clock::Now()).
Result<SubmitResult> Submit(Store& store, const SubmitRequest& request, const std::string& engine_version, double now);

// Runs added to sweeps that exist (the rounds of an adaptive campaign run, server/jobs/rounds.h),
// in the caller's transaction `t`, by the same rules as a submission's (beds and runs by key: a
// new one queued, a done one reused, a failed one queued again; membership at `next_position`,
// each sweep's next position, advanced). `g.plan.runs[i].sweeps` name sweeps of `sweep_ids`.
// Counted in `out`. Then FinishAddedRuns: the queue cap (as Submit's: kUnavailable, and the
// caller's transaction is to be dropped) and the sweeps' counts.
Status AddPlannedRuns(Transaction& t, const ScalePlan& g, const std::string& engine_version, double now,
                      const std::map<std::string, int64_t>& sweep_ids, std::map<int64_t, int64_t>& next_position,
                      SubmitResult& out);
Status FinishAddedRuns(Transaction& t, const std::vector<int64_t>& sweep_ids, int64_t max_queued_runs,
                       const SubmitResult& out);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_SUBMISSION_H_
