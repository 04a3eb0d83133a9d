// Worker: the lease -> run -> report loop of sandswim-worker.
//
// Run() starts `slots` threads; each leases a job from the daemon, prepares its run directory
// (deck, bed restart from the per-host cache), starts the engine through the Launcher, and while
// it runs sends a heartbeat every `heartbeat_every_s` carrying the simulated time and the SO's z
// (read from the growing so.dump with the streaming DumpReader; for beds, the step from the log).
// A run with a precision target (the lease's) is followed at every heartbeat: once U_z's interval
// meets the target, or the steady window has closed, the worker rewrites the run's control file
// and the deck ends the run cleanly after its next chunk (core/precision.h, core/deck.h).
// It stops the engine (SIGTERM, grace, SIGKILL) when
//   - a heartbeat reply says cancel      -> completes with failure "cancelled";
//   - a heartbeat gets 409 (lease lost)  -> does not complete (the lease is someone else's now);
//   - the grant's wall-time budget ends  -> completes with failure "timeout";
//   - its simulated time stands still for stall_after_s -> completes with failure "stalled";
//   - the worker is asked to stop        -> hands the job back (see below).
// When the engine exits, the job is judged by the pure workers/job_outcome.h (the log's markers
// and steps, the run's results and downsampled trajectory from the dump, which was read once as it
// grew), a bed's restart is uploaded with its SHA-256, and the job is completed with its execution
// facts. The drive facts the dump is read with (dt, f, floor) come typed in the lease.
//
// Daemon down: heartbeats that fail are logged and the job keeps running; completion and
// uploads retry with backoff (client.h). A daemon restart therefore loses nothing.
// Worker asked to stop (SIGTERM/SIGINT, or SIGUSR1 from Slurm before its allocation ends): no
// new leases; running engines are stopped and their jobs are NOT completed but released
// (ServerClient::Release): the daemon queues them again without counting the attempt. A
// "signal" failure would count against the run's retries for something that was not its fault.
// When the release cannot be sent, the lease expires and the daemon re-leases the run anyway.
// An engine that dies while the worker is stopping (Slurm signals the steps too) is released
// the same way.
//
// No idle cores: each slot stands for `ranks` cores of this host. A job granted with the daemon's
// queue dry (api::LeaseGrant::queue_dry: a bed its runs wait for, the queue's last runs) takes the
// slots that are idle at that moment as extra MPI ranks, up to `max_ranks` in all (0 or <= ranks:
// never; never with the direct launcher); those slots lease nothing until it ends. A slot takes its
// core before it asks for a lease (and gives it back when no job comes), so no job a slot gets
// ever finds its core lent; a job granted with the queue dry waits for the leases on their way
// (a round trip) and takes the cores of those that came back empty. A widened engine that does
// not start (its MPI launcher refuses the ranks) runs on `ranks` within the same lease, attempt
// uncounted, and the worker widens no job after that. Ranks enter
// neither the deck nor the key; the completion's execution says how many the job ran on.
//
// Inside a Slurm allocation (`allocation_seconds_left` set), a slot leases a job only while
// slurm::ShouldLease says it would finish before the allocation ends: it expects a run to take
// as long as the longest run this worker has done, or `end_margin_s` before the first one.
//
// Thread safety: Run() once; RequestStop() from any thread (not from a signal handler: main.cc
// waits for signals on a thread of its own and calls it from there).
#ifndef SANDSWIM_WORKERS_WORKER_H_
#define SANDSWIM_WORKERS_WORKER_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>

#include "core/api.h"
#include "core/deck.h"
#include "core/engine_log.h"
#include "platform/clock.h"
#include "platform/process_cpu.h"
#include "workers/client.h"
#include "workers/launcher.h"
#include "workers/run_dir.h"

namespace sandswim::worker {

class JobProgress;  // a running job's progress, read from its growing dump or log (worker.cc)

struct WorkerOptions {
  std::string name;  // "host:pid" by default (main.cc)
  std::string host;
  std::string slurm_job;  // SLURM_JOB_ID inside an allocation (sent with every lease request)
  int ranks = 1;
  int slots = 1;
  // A job granted with the queue dry may run on up to this many ranks, taken from idle slots
  // (see the top of this file). 0 or <= ranks: every job runs on `ranks`.
  int max_ranks = 0;
  LauncherKind launcher = LauncherKind::kMpirun;
  std::string engine = "liggghts";
  std::string workdir = "var/worker";
  bool once = false;             // one job, then return
  bool as_root = false;          // add mpirun's run-as-root permission to the engine's environment
  bool keep_run_dirs = false;    // keep directories of jobs that completed ok (failed ones are kept)
  double heartbeat_every_s = 5;  // also capped at a third of the lease's ttl
  double stop_grace_s = 10;      // SIGTERM -> SIGKILL
  // A hung engine: when its simulated time (a bed's step) has not moved for this long, the engine
  // is stopped and the job fails as "stalled" (0: never). A drive run's dump and a bed's log move
  // every 100 and 1,000 steps: at paper scale on one core (7x10^4 grains, ~25 steps/s) that is
  // every 4 and 40 s, so 600 s is ample. A starved engine is not a hung one: when the engine's
  // processes are visible here (engine_cpu) and were runnable while standing still, yet had less
  // than a quarter of a core over that time, the machine is busy with other work; the worker logs
  // it and waits another stall_after_s (the lease's wall budget still bounds the run). A sleeping
  // engine (never runnable) or a spinning one (a quarter of a core or more) is hung.
  double stall_after_s = 600;
  // The CPU of the engine's processes, the launcher's pid and its descendants: ReadProcessTreeCpu, or a fake.
  std::function<std::optional<TreeCpu>(pid_t)> engine_cpu = ReadProcessTreeCpu;
  double stop_settle_s = 2;      // after an engine fails, how long to wait for the worker's own stop
  double idle_poll_s = 2;        // when the queue is empty
  double exit_when_idle_s = 0;   // > 0: a slot returns after this long without work (array jobs)
  double max_backoff_s = 30;     // when the daemon cannot be reached
  // Seconds until this worker's Slurm allocation ends (nullopt: no limit); empty when the worker
  // is not in an allocation. Called before every lease.
  std::function<Result<std::optional<double>>()> allocation_seconds_left;
  double end_margin_s = 300;  // a run's expected wall time before this worker has done one
  // Time for heartbeats, budgets, stalls, idle polls and backoff (the engine's own waits are the
  // Launcher's); nullptr: the system's. REQUIRES: outlives the Worker.
  Clock* clock = nullptr;
};

struct WorkerStats {
  int64_t leased = 0;
  int64_t completed = 0;           // completions the daemon accepted (any state)
  int64_t abandoned = 0;           // lease lost or worker stopping: not completed
  int64_t released = 0;            // handed back to the daemon unfinished (worker stopping)
  bool allocation_ending = false;  // stopped leasing: the next run would outlast the allocation
  int64_t widened = 0;             // jobs run on more ranks than `ranks`, with idle slots' cores
};

class Worker {
 public:
  Worker(WorkerOptions options, ServerClient& client, Launcher& launcher);

  // Runs the slots until RequestStop() (or, with `once`, until one job is done).
  void Run();
  void RequestStop();
  bool stopping() const { return stopping_.load(); }

  // Runs one leased job to its end on `ranks` MPI ranks (0: options.ranks) (used by the slots;
  // public for tests). With `next`, and when the slot goes on, the completion also asks for the
  // next job (one round trip per job); a grant that came with the reply is left in `*next` for
  // the caller to run or hand back.
  void RunJob(const api::LeaseGrant& grant, std::optional<api::LeaseGrant>* next = nullptr, int ranks = 0);

  WorkerStats stats() const;

 private:
  struct Job;  // one job as it is run (worker.cc)
  void SlotLoop();
  // The slots' cores (see the top of this file): waits until one is free and takes it, before its
  // slot asks for a lease (false: stopping); the lease came back, with a job (the core stays
  // taken) or without; takes the idle ones a job granted with the queue dry may have as extra
  // ranks, once the leases on their way have come back (at most kLeaseInFlightWaitS) (how many it
  // took); gives `n` back.
  static constexpr double kLeaseInFlightWaitS = 5;
  int Slots() const;
  bool TakeFreeSlot();
  void LeaseArrived(bool got_job);
  int TakeIdleSlots(const api::LeaseGrant& grant);
  void ReturnSlots(int n);
  // Runs a job on the slot it holds plus the idle slots it may take; gives back what it took
  // (its own slot too, unless a next job came with its completion).
  void RunOnSlot(const api::LeaseGrant& grant, std::optional<api::LeaseGrant>* next);
  // RunJob for a slot: `*lent` extra slots' cores are held for the job; an engine that will not
  // start on them is run on options.ranks, and they are given back at once (*lent becomes 0).
  void RunJob(const api::LeaseGrant& grant, std::optional<api::LeaseGrant>* next, int ranks, int* lent);
  bool EngineNeverRan(const ExitFacts& facts, const RunDir& dir) const;
  // RunJob's steps: the run directory with its deck and bed (nullopt: the job was reported); the
  // engine started and watched, heartbeating (nullopt: the job was abandoned or handed back); a
  // bed's restart uploaded and reported. The outcome between them is workers/job_outcome.h's.
  std::optional<RunDir> Prepare(Job& job);
  std::optional<ExitFacts> Supervise(Job& job, const RunDir& dir, const DriveInfo& drive, JobProgress& progress);
  void ReportBed(Job& job, const RunDir& dir, api::BedResult bed);
  // Uploads the frames nearest the run's asked snapshot fractions (core/deck.h) and lists them
  // in the completion. False when the lease was lost or the worker is stopping (the job was
  // abandoned or handed back); a frame that cannot be read or uploaded otherwise is left out
  // with a warning: the run's result does not depend on it.
  bool HandInSnapshots(Job& job, const RunDir& dir, double t_end);
  // Whether a failed engine was stopped with the worker (waits stop_settle_s for the worker's stop).
  bool StoppedWithTheWorker();
  // How a job ends: not completed (lease lost), handed back (worker stopping), completed.
  void Abandon(Job& job, const std::string& why);
  void HandBack(Job& job, const std::string& why);
  void Complete(Job& job, const RunDir* dir);
  void Fail(Job& job, const RunDir* dir, const std::string& kind, const std::string& message);
  // Sleeps up to `seconds`, less when asked to stop. False when stopping.
  bool Idle(double seconds);
  // Seconds of the clock's monotonic time since `t` (one of its readings).
  double Since(double t) { return clock_->Monotonic() - t; }
  // False (and logs why, once) when the next run would not finish inside the allocation.
  bool RunFitsAllocation();

  WorkerOptions options_;
  SystemClock system_clock_;
  Clock* clock_;  // options_.clock, or system_clock_
  ServerClient& client_;
  Launcher& launcher_;
  BedCache beds_;
  std::atomic<bool> stopping_{false};
  mutable std::mutex mu_;
  std::condition_variable cv_;
  WorkerStats stats_;
  std::optional<double> longest_run_s_;  // wall time of the longest run done ok, for ShouldLease
  int slots_in_use_ = 0;                 // slots leasing, running a job, or lent to a wider one (<= Slots())
  bool widen_refused_ = false;           // a widened engine did not start: no job is widened again
  int leasing_ = 0;                      // slots whose lease is on its way (their cores are in slots_in_use_)
};

}  // namespace sandswim::worker

#endif  // SANDSWIM_WORKERS_WORKER_H_
