// LocalWorkers: the `--local-workers N` supervisor. It keeps N `sandswim-worker` child processes
// running on this machine, each in its own process group (so a signal to the group reaches the
// worker's mpirun and engine too), restarts one that dies after a backoff that doubles while
// they keep dying young, and stops them all on shutdown: SIGTERM to every group, a grace
// period, then SIGKILL.
//
// Process creation, reaping and signalling go through platform/subprocess.h, so the supervision
// logic is tested with FakeSubprocesses and a FakeClock.
//
// Thread safety: LocalWorkers is driven by one thread (Tick() from the supervisor loop, then
// Stop()); Start()/Tick()/Stop() must not run concurrently. RunUntilStopped() is that loop.
// REQUIRES: `processes` and `clock` outlive the supervisor.
#ifndef SANDSWIM_SERVER_LOCAL_WORKERS_H_
#define SANDSWIM_SERVER_LOCAL_WORKERS_H_

#include <sys/types.h>

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "core/status.h"
#include "platform/clock.h"
#include "platform/subprocess.h"

namespace sandswim {

struct LocalWorkersOptions {
  int count = 0;
  std::vector<std::string> argv;  // the worker command line, argv[0] a path
  double min_backoff_s = 1;       // delay before restarting a worker that died
  double max_backoff_s = 60;
  double healthy_after_s = 30;  // a worker that lived this long resets its backoff
  // SIGTERM -> SIGKILL. Longer than the worker's own grace for its engines (workers/worker.h
  // stop_grace_s, 10 s) plus a hand-back, so a worker that is stopping its engines is not killed
  // before it hands their jobs back.
  double grace_s = 30;
};

// The directory of the running executable (/proc/self/exe), where sandswim-worker is installed.
std::string ExecutableDir();

// This machine's host name (gethostname), as workers name their host.
std::string HostName();
// The name sandswimd gives its local worker (sandswim-worker --name): "<host>:local-<daemon pid>".
// A lease held under such a name on this host was a local worker's of this daemon or of an earlier
// one on the same database: one home for the rule both sides read (main.cc, at start and at stop).
std::string LocalWorkerName(const std::string& host, pid_t daemon_pid);
bool IsLocalWorkerName(const std::string& worker, const std::string& host);

class LocalWorkers {
 public:
  LocalWorkers(LocalWorkersOptions options, Subprocesses* processes, Clock* clock);
  ~LocalWorkers();

  // Spawns every worker. Fails (spawning none) when argv[0] is not an executable file.
  Status Start();
  // Reaps workers that died and restarts those whose backoff has passed.
  void Tick();
  // SIGTERM to every running worker's group, waits up to grace_s for them, then SIGKILL.
  void Stop();

  // Calls Tick() every `period_s` until RequestStop(), then Stop(). For the supervisor thread.
  void RunUntilStopped(double period_s = 0.2);
  void RequestStop();

  // Pids of the live workers (0 for a slot waiting to restart).
  std::vector<pid_t> pids() const;
  int restarts() const { return restarts_; }

 private:
  struct Slot {
    pid_t pid = 0;
    double started_at = 0;
    double restart_at = 0;  // when pid == 0
    double backoff_s = 0;
  };
  void Launch(Slot& slot);

  LocalWorkersOptions options_;
  Subprocesses* processes_;
  Clock* clock_;
  std::vector<Slot> slots_;
  int restarts_ = 0;
  bool stopped_ = false;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stop_requested_ = false;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_LOCAL_WORKERS_H_
