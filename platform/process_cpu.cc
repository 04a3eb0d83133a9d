#include "platform/process_cpu.h"

#include <dirent.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

namespace sandswim {

std::optional<GroupCpu> ReadGroupCpu(pid_t pgid) {
  if (pgid <= 0) return std::nullopt;
  DIR* proc = opendir("/proc");
  if (proc == nullptr) return std::nullopt;
  const double ticks = static_cast<double>(sysconf(_SC_CLK_TCK));
  GroupCpu group;
  while (dirent* entry = readdir(proc)) {
    const char* name = entry->d_name;
    if (name[0] < '0' || name[0] > '9') continue;
    std::ifstream in(std::string("/proc/") + name + "/stat");
    std::string line;
    if (!in || !std::getline(in, line)) continue;  // exited meanwhile
    // "pid (comm) state ppid pgrp ... utime stime ...": comm may hold spaces and parentheses.
    const size_t close = line.rfind(')');
    if (close == std::string::npos) continue;
    std::istringstream fields(line.substr(close + 1));
    std::string state;
    long long ppid = 0, pgrp = 0;
    fields >> state >> ppid >> pgrp;
    if (!fields || pgrp != pgid) continue;
    std::string skip;
    for (int i = 0; i < 8; ++i) fields >> skip;  // session .. cmajflt
    unsigned long long utime = 0, stime = 0;
    fields >> utime >> stime;
    if (!fields) continue;
    ++group.processes;
    group.cpu_s += static_cast<double>(utime + stime) / ticks;
    if (state == "R") group.runnable = true;
  }
  closedir(proc);
  if (group.processes == 0) return std::nullopt;
  return group;
}

}  // namespace sandswim
