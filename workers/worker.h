// Worker: the lease -> run -> report loop of sandswim-worker.
//
// Run() starts `slots` threads; each leases a job from the daemon, prepares its run directory
// (deck, bed restart from the per-host cache), starts the engine through the Launcher, and while
// it runs sends a heartbeat every `heartbeat_every_s` carrying the simulated time and the SO's z
// (read from the growing so.dump with the streaming DumpReader; for beds, the step from the log).
// It stops the engine (SIGTERM, grace, SIGKILL) when
//   - a heartbeat reply says cancel      -> completes with failure "cancelled";
//   - a heartbeat gets 409 (lease lost)  -> does not complete (the lease is someone else's now);
//   - the grant's wall-time budget ends  -> completes with failure "timeout";
//   - the worker is asked to stop        -> does not complete (see below).
// When the engine exits, the job is judged from the log's markers and steps (ClassifyExit), the
// dump is parsed into the run's results and downsampled trajectory (core/trajectory.h), a bed's
// restart is uploaded with its SHA-256, and the job is completed with its execution facts.
//
// Daemon down: heartbeats that fail are logged and the job keeps running; completion and
// uploads retry with backoff (client.h). A daemon restart therefore loses nothing.
// Worker asked to stop (SIGTERM/SIGINT): no new leases; running engines are stopped and their
// jobs are NOT completed, so their leases expire and the daemon leases the runs again. A
// "signal" failure would count against the run's retries for something that was not its fault.
//
// Thread safety: Run() once; RequestStop() from any thread (not from a signal handler: main.cc
// waits for signals on a thread of its own and calls it from there).
#ifndef SANDSWIM_WORKERS_WORKER_H_
#define SANDSWIM_WORKERS_WORKER_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>

#include "core/api.h"
#include "workers/client.h"
#include "workers/launcher.h"
#include "workers/run_dir.h"

namespace sandswim::worker {

struct WorkerOptions {
  std::string name;               // "host:pid" by default (main.cc)
  std::string host;
  int ranks = 1;
  int slots = 1;
  LauncherKind launcher = LauncherKind::kMpirun;
  std::string engine = "liggghts";
  std::string workdir = "var/worker";
  bool once = false;              // one job, then return
  bool as_root = false;           // add mpirun's run-as-root permission to the engine's environment
  bool keep_run_dirs = false;     // keep directories of jobs that completed ok (failed ones are kept)
  double heartbeat_every_s = 5;   // also capped at a third of the lease's ttl
  double stop_grace_s = 10;       // SIGTERM -> SIGKILL
  double idle_poll_s = 2;         // when the queue is empty
  double max_backoff_s = 30;      // when the daemon cannot be reached
};

struct WorkerStats {
  int64_t leased = 0;
  int64_t completed = 0;     // completions the daemon accepted (any state)
  int64_t abandoned = 0;     // lease lost or worker stopping: not completed
};

class Worker {
 public:
  Worker(WorkerOptions options, ServerClient& client, Launcher& launcher);

  // Runs the slots until RequestStop() (or, with `once`, until one job is done).
  void Run();
  void RequestStop();
  bool stopping() const { return stopping_.load(); }

  // Runs one leased job to its end (used by the slots; public for tests).
  void RunJob(const api::LeaseGrant& grant);

  WorkerStats stats() const;

 private:
  void SlotLoop();
  // Sleeps up to `seconds`, less when asked to stop. False when stopping.
  bool Idle(double seconds);

  WorkerOptions options_;
  ServerClient& client_;
  Launcher& launcher_;
  BedCache beds_;
  std::atomic<bool> stopping_{false};
  mutable std::mutex mu_;
  std::condition_variable cv_;
  WorkerStats stats_;
};

}  // namespace sandswim::worker

#endif  // SANDSWIM_WORKERS_WORKER_H_
