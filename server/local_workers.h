// LocalWorkers: the `--local-workers N` supervisor. It keeps N `sandswim-worker` child processes
// running on this machine, each in its own process group (so a signal to the group reaches the
// worker's mpirun and engine too), restarts one that dies after a backoff that doubles while
// they keep dying young, and stops them all on shutdown: SIGTERM to every group, a grace
// period, then SIGKILL.
//
// Process creation, reaping and signalling go through ProcessLauncher so the supervision logic
// is tested with a fake launcher and a FakeClock; PosixLauncher is the real one.
//
// Thread safety: LocalWorkers is driven by one thread (Tick() from the supervisor loop, then
// Stop()); Start()/Tick()/Stop() must not run concurrently. RunUntilStopped() is that loop.
// REQUIRES: the launcher and clock outlive the supervisor.
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

namespace sandswim {

class ProcessLauncher {
 public:
  virtual ~ProcessLauncher() = default;
  // Starts argv[0] (a path) with argv, in a new process group whose id is the child's pid.
  virtual Result<pid_t> Spawn(const std::vector<std::string>& argv) = 0;
  // Non-blocking: the child's wait status once it has exited (and is reaped), else nullopt.
  virtual std::optional<int> Reap(pid_t pid) = 0;
  // Sends `signal` to the process group `pgid`.
  virtual void SignalGroup(pid_t pgid, int signal) = 0;
  // Waits a little (the real one sleeps; a fake may advance its clock).
  virtual void Pause(double seconds) = 0;
};

class PosixLauncher : public ProcessLauncher {
 public:
  Result<pid_t> Spawn(const std::vector<std::string>& argv) override;
  std::optional<int> Reap(pid_t pid) override;
  void SignalGroup(pid_t pgid, int signal) override;
  void Pause(double seconds) override;
};

struct LocalWorkersOptions {
  int count = 0;
  std::vector<std::string> argv;  // the worker command line, argv[0] a path
  double min_backoff_s = 1;       // delay before restarting a worker that died
  double max_backoff_s = 60;
  double healthy_after_s = 30;    // a worker that lived this long resets its backoff
  double grace_s = 10;            // SIGTERM -> SIGKILL
};

// The directory of the running executable (/proc/self/exe), where sandswim-worker is installed.
std::string ExecutableDir();

class LocalWorkers {
 public:
  LocalWorkers(LocalWorkersOptions options, ProcessLauncher* launcher, Clock* clock);
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
  ProcessLauncher* launcher_;
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
