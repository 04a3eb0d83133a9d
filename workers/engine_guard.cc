// sandswim-engine-guard WORKER_PID REPORT_FD EXE ARGV0 [ARGS...]: the process the worker starts for
// each engine (workers/launcher.h): it leads the engine's process group, starts EXE with ARGV0
// ARGS... and this environment, dies with the worker (PR_SET_PDEATHSIG) taking the group with it,
// and exits as the engine did. A static program of its own, so that starting it is a cheap
// posix_spawn and its fork of the engine copies almost nothing.
#include <unistd.h>

#include <cstdlib>

#include "workers/launcher.h"

int main(int argc, char** argv) {
  if (argc < 5) return 127;
  sandswim::worker::GuardArgs a;
  a.worker_pid = static_cast<pid_t>(std::atoll(argv[1]));
  a.report_fd = std::atoi(argv[2]);
  a.exe = argv[3];
  a.argv = argv + 4;
  a.envp = environ;
  a.cwd = nullptr;
  a.out = nullptr;
  sandswim::worker::GuardMain(a);
}
