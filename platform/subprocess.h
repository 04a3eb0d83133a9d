// Subprocesses: the one way sandswim starts a program other than the engine, behind an interface
// with a fake (platform/fake_subprocesses.h), so what starts processes is tested without them.
//
//   Run          a command to completion: argv[0] looked up on PATH, no shell (no argument is
//                ever re-parsed), stdin from /dev/null, stdout and stderr captured (drained
//                together, so a command that fills one pipe never blocks), `env` added to this
//                process's environment; killed (SIGKILL) and reaped once `timeout_s` passes, with
//                what it printed so far. Users: the engine probe, the Slurm client commands, the figure
//                renderer (server/analysis/plot_renderer.h).
//   Spawn        a long-lived child (argv[0] a path) leading a new process group, with default
//                signal handling (the daemon blocks SIGTERM/SIGINT in its threads to sigwait for
//                them; a child must not inherit that), then Reap / SignalGroup / Pause to
//                supervise it. User: the local-worker supervisor (server/local_workers.h).
// The engine itself is started by the worker's launcher (workers/launcher.h), which needs what a
// general facility should not do: a guard process tied to the starting thread with
// PR_SET_PDEATHSIG, vfork from a multi-threaded worker, and rusage of the whole rank tree.
//
// Thread safety: PosixSubprocesses is stateless and safe from any thread; each Run owns its pipes.
#ifndef SANDSWIM_PLATFORM_SUBPROCESS_H_
#define SANDSWIM_PLATFORM_SUBPROCESS_H_

#include <sys/types.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "core/status.h"

namespace sandswim {

using EnvVars = std::vector<std::pair<std::string, std::string>>;

struct CommandOutput {
  int exit_code = 0;  // its exit status, or 128 + the signal that killed it
  std::string out;
  std::string err;
  bool timed_out = false;  // killed at the deadline; out/err hold what it printed before
};

class Subprocesses {
 public:
  virtual ~Subprocesses() = default;
  // kUnavailable naming the program when it cannot be started; otherwise its output, whatever
  // its exit code.
  virtual Result<CommandOutput> Run(const std::vector<std::string>& argv, const EnvVars& env, double timeout_s) = 0;
  // kUnavailable when argv[0] cannot be started. The child's pid is its process group's id.
  virtual Result<pid_t> Spawn(const std::vector<std::string>& argv) = 0;
  // Non-blocking: the child's wait status once it has exited (and is reaped), else nullopt.
  virtual std::optional<int> Reap(pid_t pid) = 0;
  // Sends `signal` to the process group `pgid`.
  virtual void SignalGroup(pid_t pgid, int signal) = 0;
  // Waits a little (the real one sleeps; a fake advances its clock).
  virtual void Pause(double seconds) = 0;
};

class PosixSubprocesses : public Subprocesses {
 public:
  Result<CommandOutput> Run(const std::vector<std::string>& argv, const EnvVars& env, double timeout_s) override;
  Result<pid_t> Spawn(const std::vector<std::string>& argv) override;
  std::optional<int> Reap(pid_t pid) override;
  void SignalGroup(pid_t pgid, int signal) override;
  void Pause(double seconds) override;
};

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_SUBPROCESS_H_
