// The CPU a process and its descendants have had, read from /proc: what tells an engine that is hung from one
// that is starved. Both leave the simulated time standing still; a hung engine either sleeps
// (blocked: none of its processes runnable) or spins (busy-waiting MPI ranks use their cores),
// while a starved one is runnable and gets little CPU because the machine is busy with other work.
//
// Thread safety: free function.
#ifndef SANDSWIM_PLATFORM_PROCESS_CPU_H_
#define SANDSWIM_PLATFORM_PROCESS_CPU_H_

#include <sys/types.h>

#include <optional>

namespace sandswim {

struct TreeCpu {
  double cpu_s = 0;        // user + system CPU of the live processes of the tree
  bool runnable = false;   // one of them was running or runnable (state R) when read
  int processes = 0;
};

// The CPU of `root` and every live descendant (by parent links: mpirun puts its ranks in process
// groups of their own, so the engine's group alone would miss them), from /proc/*/stat; nullopt
// when `root` is not visible here (root <= 0, or it has exited). Ranks on another node (srun)
// are not seen: then the tree is the local launcher alone.
std::optional<TreeCpu> ReadProcessTreeCpu(pid_t root);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_PROCESS_CPU_H_
