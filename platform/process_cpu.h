// The CPU a process group has had, read from /proc: what tells an engine that is hung from one
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

struct GroupCpu {
  double cpu_s = 0;        // user + system CPU of the group's live processes
  bool runnable = false;   // one of them was running or runnable (state R) when read
  int processes = 0;
};

// The group's CPU from /proc/*/stat; nullopt when no process of the group is visible here (pgid
// <= 0, the group has exited, or it runs on another node, as under srun).
std::optional<GroupCpu> ReadGroupCpu(pid_t pgid);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_PROCESS_CPU_H_
