// Job table: the rows of the worker protocol -- beds and runs as jobs, and the leases granted on
// them (tables beds, runs, leases, results, trajectories, run_logs, snapshots, sweeps) -- read and
// written inside a caller's Transaction. The lease queue (server/jobs/lease_queue.h) decides what
// happens to a job (its state machine); the SQL of its statements lives here, each named after what
// it does, but for the wall budget a grant carries (cost_model.h WallBudget). The rows a submission
// writes are submission_table.h's.
//
// Nothing here commits, counts or logs events: the caller's transaction does, so a state change
// and its audit event stay one atomic change.
//
// Thread safety: free functions over a Transaction, which holds the database's lock.
#ifndef SANDSWIM_SERVER_STORE_JOB_TABLE_H_
#define SANDSWIM_SERVER_STORE_JOB_TABLE_H_

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "core/api.h"
#include "core/cost.h"
#include "core/status.h"
#include "server/store/database.h"

namespace sandswim::jobs {

const char* Noun(api::JobKind kind);                 // "bed" | "run"
std::string Subject(api::JobKind kind, int64_t id);  // "run/12", the events' subject

// ---- Leases -------------------------------------------------------------------------------------

struct LeaseRow {
  api::JobKind kind = api::JobKind::kRun;
  int64_t job_id = 0;
  bool completed = false;
  std::string outcome;
};
// The lease a token names, or kConflict for a token this daemon never granted.
Result<LeaseRow> FindLease(Transaction& t, const std::string& token);

// Records a grant (token, job, attempt, the worker's request) at `now`.
Status InsertLease(Transaction& t, const std::string& token, api::JobKind kind, int64_t job_id, int attempt,
                   const api::LeaseRequest& request, double now);
// Closes a lease: completed at `now` with its outcome (done, failed, queued, released, ...). Every
// way a lease closes (this and MarkLeaseExpired) records closed_at and the simulated time its
// attempt reached (schema/018: the run's sim_time_s while this lease is its current one -- the
// result's once done, else the last heartbeat's; MarkRetriedOrFailed and MarkReleased stamp it
// before they clear a run's progress): each attempt is charged once by the rounds' ledger.
Status CloseLease(Transaction& t, const std::string& token, double now, const std::string& outcome);
// Marks a lease reclaimed by the daemon (outcome "expired", closed at `now`); the job moves on
// without it. Call it after RetryOrFail's state change (the reach was stamped there).
Status MarkLeaseExpired(Transaction& t, const std::string& token, double now);
// Remembers which grant went out with the completion of `token` (Completion::next).
Status SetNextToken(Transaction& t, const std::string& token, const std::string& next_token);

// The job leased together with the completion of `token`, while that lease is still open.
struct GrantRef {
  std::string token;
  api::JobKind kind = api::JobKind::kRun;
  int64_t job_id = 0;
};
Result<std::optional<GrantRef>> OpenNextGrant(Transaction& t, const std::string& token);
// Puts that job back in the queue as if never leased (attempt uncounted; a run with no progress),
// or, a run no live sweep wants (`wanted` false, RunWanted), cancels it, and closes its lease as
// "unreceived" -- when it is still running under that grant. False when it has moved on.
Result<bool> TakeBackGrant(Transaction& t, const GrantRef& grant, bool wanted, double now);

// Slurm jobs that hold an open lease on a running job, sorted.
Result<std::vector<std::string>> SlurmJobsWithOpenLeases(Transaction& t);

// At the daemon's start: every running job's lease expires no sooner than `until` (the outage
// does not count against it). Returns how many leases it extended.
Result<int64_t> ExtendRunningLeases(Transaction& t, double until);

// ---- Jobs (beds and runs) -----------------------------------------------------------------------

struct JobRow {
  JobState state = JobState::kQueued;
  std::string lease_token;
  int attempts = 0;
  int max_attempts = 0;  // the job's own, else the default given
};
// kConflict when the job no longer exists.
Result<JobRow> LoadJob(Transaction& t, api::JobKind kind, int64_t id, int default_max);

// Running jobs whose lease is lost: expired before `now`, or (with a Slurm job) granted to that
// job at or before `asked_at` with an expiry at or before `expiring_by`. Oldest id first.
struct LostLease {
  int64_t id = 0;
  JobRow job;
  std::string worker;
};
Result<std::vector<LostLease>> ExpiredLeases(Transaction& t, api::JobKind kind, double now, int default_max);
// Every running job of `kind` with its lease (token, worker), oldest id first.
Result<std::vector<LostLease>> RunningLeases(Transaction& t, api::JobKind kind, int default_max);
Result<std::vector<LostLease>> SlurmJobLeases(Transaction& t, api::JobKind kind, const std::string& slurm_job,
                                              double expiring_by, double asked_at, int default_max);

// The job leased: running under `token` until `expires_at`, one more attempt.
Status MarkLeased(Transaction& t, api::JobKind kind, int64_t id, const std::string& token, double expires_at,
                  const std::string& worker, double now);
// After a failure: `state` kQueued (a retry; a run's queued_at is now) or kFailed (finished now).
Status MarkRetriedOrFailed(Transaction& t, api::JobKind kind, int64_t id, JobState state,
                           const std::string& error_kind, const std::string& message, double now);
// A cancelled completion: a run becomes kCancelled (finished now), a bed kQueued.
Status MarkCancelledOrQueued(Transaction& t, api::JobKind kind, int64_t id, JobState state,
                             const std::string& error_kind, const std::string& message, double now);
// How often the job was handed back before this call, which counts one more hand-back.
Result<int64_t> CountRelease(Transaction& t, api::JobKind kind, int64_t id);
// A handed-back job: queued again, its attempt uncounted (`wanted`), else cancelled (a run no
// live sweep wants any more).
Status MarkReleased(Transaction& t, api::JobKind kind, int64_t id, bool wanted, double now);

// ---- Beds ---------------------------------------------------------------------------------------

// The oldest queued bed that a queued run is waiting for.
struct QueuedBed {
  int64_t id = 0;
  std::string key;
  std::string deck;
  int attempts = 0;
  std::optional<std::string> engine_version;  // its key's (beds before migration 3: not stored)
};
Result<std::optional<QueuedBed>> NextQueuedBed(Transaction& t);

// A bed's heartbeat: its lease extended to `expires_at`, its heartbeat_at now (a running job counts
// as an engine while it heartbeats: cost_model.h kLiveEngineS).
Status ExtendBedLease(Transaction& t, int64_t bed_id, double expires_at, double now);

struct BedRow {
  std::string key;
  JobState state = JobState::kQueued;
  std::optional<std::string> path;  // of the uploaded restart file
  std::string sha256;
};
// kNotFound for an unknown bed.
Result<BedRow> LoadBed(Transaction& t, int64_t bed_id);
// The restart file uploaded under a bed's lease.
Status RecordBedUpload(Transaction& t, int64_t bed_id, const std::string& path, const std::string& sha256);
// The bed prepared: done at `now`, with its result and the MPI ranks it ran on (its completion's
// execution.ranks; the cost model's bed rates are per rank count).
Status MarkBedDone(Transaction& t, int64_t bed_id, const api::BedResult& result, int ranks, double now);
// Fails the queued runs waiting for a bed that failed for good, with a "runs.failed" event naming
// the bed and the reason. Returns how many.
Result<int64_t> FailRunsOfBed(Transaction& t, int64_t bed_id, const std::string& reason, double now);

// ---- Runs ---------------------------------------------------------------------------------------

// The oldest queued run whose bed is done, with what its deck and grant are made of.
struct QueuedRun {
  int64_t id = 0;
  std::string key;
  std::optional<std::string> stored_deck;  // runs submitted before migration 3 (run_decks)
  int attempts = 0;
  double run_duration_s = 0;
  int64_t steps = 0;
  int64_t bed_id = 0;
  std::string bed_sha256;
  std::string mode, axis;  // as stored; parsed by the caller
  double A = 0, f = 0, Omega = 0, omega = 0, duration_s = 0;
  std::string scale;
  std::string bed_key;
  std::optional<std::string> engine_version;  // of the bed
  std::optional<std::string> precision;       // JSON, as stored (core/precision.h StoredPrecision)
  std::optional<std::string> snapshots;       // JSON, as stored (core/deck.h StoredSnapshotFractions)
  std::optional<std::string> materials;       // JSON, as stored (core/materials.h StoredMaterials)
  std::optional<double> dt_s;                  // the drive's step, NULL: its materials' TimeStep
};
Result<std::optional<QueuedRun>> NextQueuedRun(Transaction& t);

// A run whose deck cannot be made (or no longer matches its key): failed with "deck_error".
Status FailRunDeck(Transaction& t, int64_t run_id, const std::string& why, double now);
// A heartbeat: the lease extended to `expires_at` and the progress recorded; and a progress mark
// (run_progress: its step now) when its newest is kProgressMarkS old or more, marks older than
// kProgressHorizonS removed then. The cost model reads the running runs' rate over the last
// kShareWindowS from them (cost_model.h: the ETA follows the machine's current share).
inline constexpr double kProgressMarkS = 60;
inline constexpr double kProgressHorizonS = 3 * kShareWindowS;
Status RecordProgress(Transaction& t, int64_t run_id, double expires_at, const api::Heartbeat& beat, double now);
// Whether some sweep that is not cancelled still wants the run (runs may be shared).
Result<bool> RunWanted(Transaction& t, int64_t run_id);

// The result of a run (replacing an older one: a forced rerun), under the run's key.
Status PutResult(Transaction& t, int64_t run_id, const api::RunResult& result, const api::Execution& execution,
                 double now);
Status PutTrajectory(Transaction& t, int64_t run_id, const api::Trajectory& trajectory);
Status PutLogTail(Transaction& t, int64_t run_id, const std::string& log_tail);
Status MarkRunDone(Transaction& t, int64_t run_id, double sim_time_s, int64_t steps, double now);

// ---- Run snapshots (their files: snapshot_files.h) ----------------------------------------------

// Records snapshot `s` of a run, its file's checksum `sha256` (replacing a record of the same idx).
Status PutSnapshot(Transaction& t, int64_t run_id, const api::Snapshot& s, const std::string& sha256);
// The snapshots a run's point asks for, as stored (core/deck.h StoredSnapshotFractions); nullopt
// when it asks for none or the run does not exist.
Result<std::optional<std::string>> SnapshotsAsked(Transaction& t, int64_t run_id);
// The recorded snapshots' idx by run id.
Result<std::map<int64_t, std::vector<int>>> RecordedSnapshots(Transaction& t);
// The ids of the runs running now.
Result<std::set<int64_t>> RunningRunIds(Transaction& t);

// ---- Sweeps -------------------------------------------------------------------------------------

// Marks the sweep cancelled (once); kNotFound for an unknown sweep.
Status MarkSweepCancelled(Transaction& t, int64_t sweep_id, double now);
// Of the sweep's runs that no live sweep wants any more: the queued ones become cancelled, the
// running ones are asked to stop at their next heartbeat. Returns {cancelled, asked to stop}.
Result<std::pair<int64_t, int64_t>> CancelOrphanedRuns(Transaction& t, int64_t sweep_id, double now);

}  // namespace sandswim::jobs

#endif  // SANDSWIM_SERVER_STORE_JOB_TABLE_H_
