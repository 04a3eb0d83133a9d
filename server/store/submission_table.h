// Submission table: the rows a sweep submission writes (jobs/submission.h decides what to write)
// -- tables submissions, campaign_runs, sweeps, beds, runs, sweep_runs and sweep_counts -- read and
// written inside the caller's Transaction, each statement named after what it does. A refused
// submission rolls the caller's transaction back, so nothing here is ever half-stored.
//
// Nothing here commits or logs events: the caller's transaction does.
//
// Thread safety: free functions and a statement holder over a Transaction, which holds the
// database's lock. A RunRows lives no longer than its Transaction.
#ifndef SANDSWIM_SERVER_STORE_SUBMISSION_TABLE_H_
#define SANDSWIM_SERVER_STORE_SUBMISSION_TABLE_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/status.h"
#include "core/sweep.h"
#include "server/store/database.h"

namespace sandswim::submissions {

// ---- Submissions (idempotency) -------------------------------------------------------------------

struct StoredSubmission {
  std::string fingerprint;  // of the request that stored it
  std::string response;     // the answer it gave (JSON text)
};
// The submission stored under an idempotency key, if any.
Result<std::optional<StoredSubmission>> FindByIdempotencyKey(Transaction& t, const std::string& key);
// The answer the submission of a scheduled campaign run gave, when (campaign, due_time) has one;
// kCorruption when that campaign run has no sweeps.
Result<std::optional<std::string>> ScheduledRunResponse(Transaction& t, const std::string& campaign,
                                                        double due_time);
// A new submission (its response "{}" until SetResponse); returns its id.
Result<int64_t> Insert(Transaction& t, const std::optional<std::string>& idempotency_key,
                       const std::string& fingerprint, double now);
Status SetResponse(Transaction& t, int64_t submission_id, const std::string& response);

// ---- Campaign runs and sweeps --------------------------------------------------------------------

struct NewCampaignRun {
  std::string campaign;
  std::string scale;
  std::string trigger;  // "manual" | "schedule"
  std::optional<double> due_time;
  int campaign_version = 0;       // 0: the built-in definition
  std::string definition;         // the resolved definition it runs (JSON text)
  std::string definition_sha256;  // DefinitionSha256 of it
};
// Returns the new campaign run's id.
Result<int64_t> InsertCampaignRun(Transaction& t, const NewCampaignRun& run, double now);

struct NewSweep {
  std::string name;
  std::string scale;
  std::string spec;  // the sweep as submitted (JSON text)
  std::optional<int64_t> campaign_run_id;
  int64_t submission_id = 0;
  bool force = false;
};
// Returns the new sweep's id.
Result<int64_t> InsertSweep(Transaction& t, const NewSweep& sweep, double now);
// Sets each sweep's counts by state (sweep_counts, schema/003_perf.sql) from its membership rows:
// one aggregate per sweep after its runs are written.
Status RecountSweeps(Transaction& t, const std::vector<int64_t>& sweep_ids);

// ---- Beds ----------------------------------------------------------------------------------------

// A queued bed row for `bed` unless its key has one (then only a missing engine_version is set).
Status InsertBedIfNew(Transaction& t, const std::string& scale, const PlannedBed& bed,
                      const std::string& engine_version, double now);
struct BedByKey {
  int64_t id = 0;
  JobState state = JobState::kQueued;
  std::string last_error_kind;  // "" when none
  std::string last_error;       // "" when none
};
// kInternal when no bed has that key (InsertBedIfNew first).
Result<BedByKey> FindBed(Transaction& t, const std::string& key);
// A failed bed queued again from scratch (attempts, lease and error cleared).
Status RequeueFailedBed(Transaction& t, int64_t bed_id);

// ---- Runs ----------------------------------------------------------------------------------------

// The statements a submission writes its runs with, prepared once and reused for every row (a
// 100,000-run sweep is written in one transaction).
class RunRows {
 public:
  explicit RunRows(Transaction& t);

  // A queued run row for `run` on bed `bed_id`; its id, or nullopt when its key has a row.
  Result<std::optional<int64_t>> InsertIfNew(const PlannedRun& run, int64_t bed_id, double now);
  struct Existing {
    int64_t id = 0;
    JobState state = JobState::kQueued;
  };
  // The run row with `key`; kInternal when there is none.
  Result<Existing> Find(const std::string& key);
  // Makes the run a member of the sweep at `position` (once).
  Status AddToSweep(int64_t sweep_id, int64_t run_id, int64_t position);

 private:
  Transaction& t_;
  Statement insert_;
  Statement find_;
  Statement member_;
};
// A run queued again from scratch (attempts, lease, progress, times and error cleared; queued at
// `now`). Its old result row stays until a new completion replaces it.
Status RequeueRun(Transaction& t, int64_t run_id, double now);
// How many runs are queued or running, in every sweep.
Result<int64_t> CountQueuedOrRunning(Transaction& t);

}  // namespace sandswim::submissions

#endif  // SANDSWIM_SERVER_STORE_SUBMISSION_TABLE_H_
