// Launcher: starts the engine (mpirun/srun/liggghts) as a child process in its own process group,
// and stops and reaps it.
//
// Abstract so it can be faked in tests of the worker loop. The real one (GuardedLauncher)
// spawns a small guard process (sandswim-engine-guard next to this program; a fork of this
// process when that is missing) that leads a new process group and starts the engine in it, in the
// run directory, with its stdout and stderr in a file there. A LaunchSpec marked single_process
// (a direct engine) needs no guard and is started itself, with the same guarantees. The engine never outlives the
// worker: the guard gets PR_SET_PDEATHSIG when the worker thread that started it dies (even by
// SIGKILL) and then SIGKILLs the whole group, mpirun and ranks included. So a Start()ing thread
// must outlive its EngineProcess (the worker's slot threads wait for their engines). The guard
// exits as the engine did, so exit codes and signals read as the engine's own. Stop() sends SIGTERM to the whole group
// (mpirun and every rank), waits up to a grace period, then sends SIGKILL. Wall and CPU time come
// from wait4()'s rusage, which covers the ranks that mpirun reaped.
//
// Why not platform/subprocess.h, which starts every other program: the engine needs what a
// general facility should not do -- a guard tied to the starting thread by PR_SET_PDEATHSIG,
// vfork from a multi-threaded worker, the rusage of the whole rank tree.
//
// Thread safety: a Launcher may be shared by threads; one EngineProcess belongs to one thread.
#ifndef SANDSWIM_WORKERS_LAUNCHER_H_
#define SANDSWIM_WORKERS_LAUNCHER_H_

#include <sys/types.h>

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/status.h"

namespace sandswim::worker {

enum class LauncherKind { kMpirun, kSrun, kDirect };
const char* LauncherName(LauncherKind kind);  // "mpirun" | "srun" | "direct"

struct LaunchSpec {
  std::vector<std::string> argv;                         // argv[0] is looked up on PATH
  std::string cwd;                                       // run directory
  std::vector<std::pair<std::string, std::string>> env;  // added to the worker's environment
  std::string output_file;                               // stdout+stderr, relative to cwd ("" = /dev/null)
  // The command is one process that starts no others (a direct engine): it needs no guard. It is
  // started straight from the worker (vfork + exec) as the leader of its own group, and asks
  // for SIGKILL itself when the worker's thread dies: one program start per run instead of two.
  bool single_process = false;
};

// The command line for the engine (single_process for direct). mpirun: `mpirun -np R --bind-to none ENGINE -in DECK
// -log LOG -screen /dev/null` (with OMPI_ALLOW_RUN_AS_ROOT[_CONFIRM]=1 in env when running as root); srun (inside an
// allocation): `srun --mpi=pmix -n R --exclusive ENGINE ...`; direct: `ENGINE ...` (R must be 1).
// (`-screen none` segfaults with fix insert/pack, so the screen goes to /dev/null.)
// `widened` (a job on idle slots' cores, workers/worker.h): mpirun gets `--oversubscribe`, since
// Open MPI counts physical cores as its slots and refuses more ranks than that ("not enough
// slots"), while the worker's slots may count logical CPUs (--local-workers $(nproc)).
LaunchSpec EngineCommand(LauncherKind kind, int ranks, const std::string& engine, const std::string& deck_file,
                         const std::string& log_file, const std::string& cwd, bool as_root, bool widened = false);

struct ExitStatus {
  int exit_code = 0;  // when it exited
  int signal = 0;     // non-zero: died on this signal
  double wall_s = 0;
  double cpu_s = 0;  // user + system of the child and the children it reaped
};

// One started engine process (group).
class EngineProcess {
 public:
  virtual ~EngineProcess() = default;
  // Waits up to `seconds` (0: just checks) for the process to exit; true once it has.
  virtual bool WaitFor(double seconds) = 0;
  // SIGTERM to the group, up to `grace_s` for it to exit, then SIGKILL; returns once reaped.
  virtual void Stop(double grace_s) = 0;
  // REQUIRES: WaitFor() returned true or Stop() returned.
  virtual ExitStatus exit_status() const = 0;
  // The process id, which is also its process group id.
  virtual pid_t pid() const = 0;
};

class Launcher {
 public:
  virtual ~Launcher() = default;
  // Unavailable (naming the command and errno text) when the command cannot be executed.
  virtual Result<std::unique_ptr<EngineProcess>> Start(const LaunchSpec& spec) = 0;
};

// The real thing: a guard process leading a new process group and the engine in it, or the
// engine itself as the group leader for a single_process spec.
class GuardedLauncher : public Launcher {
 public:
  Result<std::unique_ptr<EngineProcess>> Start(const LaunchSpec& spec) override;
};

// The engine guard (sandswim-engine-guard's main, and the fork fallback): leads the engine's
// process group, dies with the worker thread that started it and takes the group with it, and
// exits as the engine did. Only async-signal-safe calls: usable right after fork().
struct GuardArgs {
  const char* exe;  // the engine, resolved
  char* const* argv;
  char* const* envp;
  const char* cwd;   // nullptr: stay
  const char* out;   // stdout + stderr, relative to cwd (nullptr: already set up)
  int report_fd;     // {stage, errno} written here on a failure before exec
  pid_t worker_pid;  // the expected parent
};
[[noreturn]] void GuardMain(const GuardArgs& args);

}  // namespace sandswim::worker

#endif  // SANDSWIM_WORKERS_LAUNCHER_H_
