// LeaseQueue: the daemon side of the worker protocol (core/api.h). Beds and runs are jobs that
// workers lease, heartbeat and complete; every state change is one store transaction (Lease,
// Heartbeat and Complete go through Store::Write: concurrent calls share one commit, each in its
// own savepoint, and each returns only after that commit).
//
// Job states: queued -> running (leased) -> done | failed | queued (retry) | cancelled (runs).
//   Lease      picks, oldest first, a queued bed that a queued run is waiting for; failing that,
//              a queued run whose bed is done. The job's attempts count goes up by one; the
//              grant carries a fresh random 128-bit token (hex) that is the only proof of
//              ownership, and a TTL. Expired leases are reclaimed first (ExpireLeases). The grant
//              says whether any other job is leasable once it runs (queue_dry: none is), so a
//              worker may give it the cores of slots that would otherwise idle.
//   Heartbeat  under the current token: extends the lease by the TTL and records progress; the
//              reply says cancel=true once every sweep the run belongs to is cancelled.
//   Complete   under the current token: ok -> done (a run gets its result, trajectory and log
//              tail; a bed must have had its restart uploaded with PutBedRestart first and
//              becomes done with its sha256/grains/result). Failure -> back to queued while
//              attempts < max_attempts, else failed with the reason; a failure that repeats by
//              nature (a deck error, lost atoms, unreadable output, a missed equilibrium) is never
//              retried and a "stalled" engine once (core/api.h AttemptsFor); "cancelled" -> cancelled (a bed goes
//              back to queued). A bed that fails for good fails its queued runs ("bed_failed").
//              Completing a token that already completed answers "duplicate" and changes
//              nothing; a token that is not the job's current lease (expired and re-leased,
//              unknown) gets kConflict and changes nothing. So there is never a second result.
//              A completion may also ask for the worker's next job (Completion::next): it is
//              leased in the same transaction, after the completion, and returned with the reply.
//              A repeated completion with `next` (the first reply was lost) first takes back the
//              job the first one leased, if it is still running under that grant (queued again,
//              attempt uncounted, lease outcome "unreceived"), then leases afresh: no job waits
//              out a lease its worker never received.
//   Release    under the current token: the worker hands the job back unfinished (it is
//              stopping: Slurm signalled its allocation's end, or it was asked to stop). The job
//              goes back to queued and the attempt is not counted (attempts - 1): it was not the
//              job's fault -- unless it was handed back max_attempts times before: then the
//              hand-back counts ("released"), so a run that never fits its allocations ends
//              failed. A run no live sweep wants any more becomes cancelled. Releasing a token
//              again answers "duplicate".
//   ExpireLeases  running jobs past their lease expiry go back to queued (the attempt stays
//              counted) or, at max_attempts, to failed with kind "lease_expired" -- except a lease
//              an earlier daemon's local worker held and never heartbeated after the restart: it
//              is handed back as by Release (ExtendLeasesAfterRestart says why).
//   ReclaimSlurmJob  the same, before the expiry, for the leases of a Slurm job that is gone and
//              whose worker has been silent for half the TTL (kind "pilot_gone"); the daemon's
//              PilotWatch asks Slurm which jobs are gone.
//   Cancel     a sweep: its queued runs that belong to no other live sweep become cancelled;
//              its running runs are told to stop at their next heartbeat.
//
// Every leased token is recorded in the `leases` table (token, job, granted/expiry/completion),
// which is how a repeated completion is recognised as a duplicate.
//
// Thread safety: safe from any thread (all state is in the Store, which serialises).
// REQUIRES: `store` and `clock` outlive the queue.
#ifndef SANDSWIM_SERVER_JOBS_LEASE_QUEUE_H_
#define SANDSWIM_SERVER_JOBS_LEASE_QUEUE_H_

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core/api.h"
#include "core/deck.h"
#include "core/snapshot.h"
#include "core/status.h"
#include "platform/clock.h"
#include "platform/files.h"
#include "server/store/job_table.h"
#include "server/store/snapshot_files.h"
#include "server/store/store.h"

namespace sandswim {

struct LeaseQueueOptions {
  double ttl_s = 60;         // lease lifetime; each heartbeat extends it by this much
  int max_attempts = 3;      // leases a job gets before a failure or expiry is final
  double wall_budget_s = 0;  // passed to workers in every grant (0: the cost model's, server/store/cost_model.h WallBudget)
  // The data directory (platform/data_dir.h) whose snapshots/ keeps runs' snapshots; empty:
  // snapshot uploads are refused.
  std::string data_dir;
};

struct CancelSummary {
  int64_t cancelled = 0;  // queued runs now cancelled
  int64_t stopping = 0;   // running runs that will be told to stop
};
void to_json(nlohmann::json& j, const CancelSummary& c);

struct BedFile {
  int64_t bed_id = 0;
  std::string key;
  std::string path;  // absolute or as given by data_dir: DataDir::BedRestart(key)
  std::string sha256;
};

class LeaseQueue {
 public:
  LeaseQueue(Store* store, Clock* clock, LeaseQueueOptions options = {});

  const LeaseQueueOptions& options() const { return options_; }

  // The next job for this worker, or nullopt when nothing is leasable now. kInvalidArgument
  // ("slurm_job") when request.slurm_job is not a Slurm job id (digits).
  Result<std::optional<api::LeaseGrant>> Lease(const api::LeaseRequest& request);

  // kConflict when `token` is not the current lease of a running job.
  Result<api::HeartbeatReply> Heartbeat(const std::string& token, const api::Heartbeat& beat);
  // Called with every run heartbeat once it is recorded (the dashboard's trails,
  // server/dashboard/live_feed.h). Set it before serving; it must be cheap and thread-safe.
  using ProgressObserver = std::function<void(int64_t run_id, const api::Heartbeat& beat)>;
  void SetProgressObserver(ProgressObserver observer) { progress_observer_ = std::move(observer); }

  // kConflict as above (nothing changes); "duplicate" when this token already completed.
  // kInvalidArgument when the completion lacks what its kind needs (ok run without result, ok
  // bed without bed_result, failure without failure); kFailedPrecondition for an ok bed whose
  // restart was not uploaded (or whose bed_result.sha256 differs from the upload).
  // With `c.next`, also leases the next job for that request in the same transaction (as Lease
  // would, after the completion) and returns it in `next`; on any error nothing happens
  // (kInvalidArgument "next.slurm_job" for a bad job id). See "Complete" above for a retry.
  Result<api::CompletionReply> Complete(const std::string& token, const api::Completion& c);

  // kConflict as for Complete; {"queued"} once released, {"duplicate"} for a token that already
  // completed or was released.
  Result<api::CompletionReply> Release(const std::string& token, const std::string& reason);

  // Reclaims every lease that expired before the clock's now. Returns how many. A lease left by a
  // local worker of an earlier daemon (see ExtendLeasesAfterRestart) is handed back instead.
  Result<int64_t> ExpireLeases();
  // At start-up, before serving: while the daemon was down no worker could heartbeat, so the
  // outage must not count against their leases. Every running job's lease is extended to at
  // least now + TTL: a worker still running its job keeps it (its next heartbeat lands), one that
  // died meanwhile is reclaimed one TTL after the start. Without it, a daemon down for longer
  // than a TTL would re-queue runs whose engines are still running: a second execution (the
  // crash trials, tests/crash_trials_test.cc, catch that). Returns how many leases it extended.
  // `local_of_earlier_daemon(worker)`: whether a worker name is a local worker of an earlier daemon
  // (server/local_workers.h IsLocalWorkerName). Such a lease that expires without one heartbeat
  // after this start is handed back as Release does, its attempt uncounted: that worker died with
  // its daemon (stopped, or killed), which was not the job's fault. One that heartbeats is alive
  // and from then on expires, counted, as any other. (Kept in memory: a second restart within a
  // TTL finds the same leases again by their workers' names.)
  Result<int64_t> ExtendLeasesAfterRestart(
      const std::function<bool(const std::string& worker)>& local_of_earlier_daemon = {});
  // How many leases ExtendLeasesAfterRestart found left by an earlier daemon's local workers that
  // have not heartbeated since.
  size_t LeasesLeftByStoppedDaemon();

  // Hands back, as Release does (attempt uncounted; counted after max_attempts hand-backs), every
  // running job leased to `worker`. For the daemon's shutdown: once its local worker is stopped
  // (and killed if it ignored SIGTERM), whatever that worker could not hand back itself. Returns
  // how many jobs it handed back. REQUIRES: that worker is dead.
  Result<int64_t> HandBackLeasesOf(const std::string& worker, const std::string& reason);

  // The Slurm jobs (LeaseRequest::slurm_job) that hold a lease on a running job now, sorted.
  Result<std::vector<std::string>> RunningSlurmJobs();
  // Reclaims, as if they had expired now, the leases of running jobs granted to `slurm_job` at or
  // before `asked_at` (when Slurm said it no longer runs that job: see server/jobs/pilot_watch.h) whose
  // worker has not heartbeated for half the TTL -- a worker that still heartbeats is alive,
  // whatever Slurm said. The failure kind is "pilot_gone". Returns how many jobs went back to
  // the queue or failed.
  Result<int64_t> ReclaimSlurmJob(const std::string& slurm_job, double asked_at);

  // kNotFound for an unknown sweep. Cancelling twice is harmless.
  Result<CancelSummary> Cancel(int64_t sweep_id);

  // Stores a bed's restart file uploaded under a current bed lease: checks SHA-256 of `bytes`
  // against `sha256` (kInvalidArgument "X-Sha256" on mismatch), puts them at
  // DataDir(data_dir).BedRestart(key) atomically and records path and checksum. `upload_file`: the
  // file that holds `bytes` (an HTTP upload's, under DATA/uploads), renamed into place rather than
  // written again (platform/files.h PlaceFile); "" writes `bytes`. The bed stays running until
  // Complete(). kConflict when the token is not a current bed lease.
  Status PutBedRestart(const std::string& token, std::string_view bytes, const std::string& sha256,
                       const std::string& data_dir, const std::string& upload_file = "");

  // Stores snapshot `idx` of a run, uploaded under the run's current lease before its completion
  // lists it: checks `bytes` against `sha256` (kInvalidArgument "X-Sha256"), that it is a whole
  // full-bed snapshot (core/snapshot.h ParseBedSnapshot: kInvalidArgument "body") and that idx is
  // one the run asked for (kInvalidArgument "n"), then puts them at DataDir::Snapshot atomically
  // (`upload_file`: as for PutBedRestart). Nothing is recorded until Complete() lists it
  // (api::Completion::snapshots); a completion that lists a snapshot not uploaded, or uploaded with
  // other bytes, is refused (kFailedPrecondition). The bytes are hashed here, once: the completion
  // compares the checksum it lists with this one while the file is still the one written (same
  // identity), and hashes a file only when the daemon has not seen it written (after a restart),
  // before its transaction opens. kConflict when the token is not a current run lease;
  // kFailedPrecondition when the queue has no data_dir.
  Status PutRunSnapshot(const std::string& token, int idx, std::string_view bytes, const std::string& sha256,
                        const std::string& upload_file = "");

  // The lease check of PutBedRestart / PutRunSnapshot alone, made before an upload's body is read
  // (a body is written to disk as it arrives): kConflict when `token` is not a current,
  // uncompleted lease of `kind`, or (`job_id` given) is a lease of another job.
  Status CheckUploadLease(const std::string& token, api::JobKind kind, std::optional<int64_t> job_id = std::nullopt);
  // Removes snapshot files no done run recorded (a run that failed or was leased again after an
  // upload). A running run's files stay: its worker may still complete it, listing them (the
  // daemon stopped between the upload and the completion). Called at start-up. Returns how many
  // files it removed.
  Result<int64_t> RemoveUnrecordedSnapshots();

  // The restart file of a done bed (kNotFound for an unknown bed, kFailedPrecondition when the
  // bed is not done yet).
  Result<BedFile> GetBedRestart(int64_t bed_id);

 private:
  // The bodies of Lease and Complete, inside a caller's transaction at time `now`.
  Result<std::optional<api::LeaseGrant>> LeaseIn(Transaction& t, const api::LeaseRequest& request, double now);
  // A file's checksum as of its identity (platform/files.h).
  struct HashedFile {
    std::string sha256;
    FileIdentity identity;
  };
  Result<api::CompletionReply> CompleteIn(Transaction& t, const std::string& token, const api::Completion& c,
                                          double now, const std::map<int, HashedFile>& snapshots);
  // The checksums of the snapshot files an ok run completion lists, by idx, found before its write
  // transaction: those PutRunSnapshot wrote (not read again), else hashed now. A listed file that
  // is missing is left out (CompleteRun refuses it); so is everything when `token` is no run lease.
  Result<std::map<int, HashedFile>> HashListedSnapshots(const std::string& token, const api::Completion& c);
  // Whether `token` is a lease ExtendLeasesAfterRestart found left by an earlier daemon's local
  // worker and no heartbeat has come under it since.
  bool LeftByStoppedDaemon(const std::string& token);
  // LeaseIn's candidates: fill `g` and return true when a bed (a run) is leasable.
  Result<bool> NextBed(Transaction& t, api::LeaseGrant& g);
  Result<bool> NextRun(Transaction& t, api::LeaseGrant& g, double now);
  struct RunDeck {
    std::string deck;
    DriveInfo drive;
    std::optional<PrecisionTarget> precision;
    SnapshotFractions snapshots;
  };
  static Result<RunDeck> MakeRunDeck(const jobs::QueuedRun& run);
  // CompleteIn's outcomes: the state the job ends in.
  Result<JobState> CompleteRun(Transaction& t, int64_t id, const api::Completion& c, double now,
                               const std::map<int, HashedFile>& snapshots);
  Result<JobState> CompleteBed(Transaction& t, int64_t id, const api::Completion& c, double now);
  Result<JobState> CompleteFailure(Transaction& t, api::JobKind kind, int64_t id, const jobs::JobRow& job,
                                   const api::Failure& f, double now);

  Store* store_;
  Clock* clock_;
  LeaseQueueOptions options_;
  ProgressObserver progress_observer_;
  // The checksum of each snapshot file PutRunSnapshot wrote, by path, until its run completes.
  void ForgetWrittenSnapshots(int64_t run_id);  // its run completed: the files are recorded or gone
  std::mutex written_mu_;
  std::map<std::string, HashedFile> written_snapshots_;  // guarded by written_mu_
  std::mutex left_mu_;
  std::set<std::string> left_by_stopped_daemon_;  // lease tokens; guarded by left_mu_
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_JOBS_LEASE_QUEUE_H_
