#include "platform/process_cpu.h"

#include <dirent.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace sandswim {

std::optional<TreeCpu> ReadProcessTreeCpu(pid_t root) {
  if (root <= 0) return std::nullopt;
  DIR* proc = opendir("/proc");
  if (proc == nullptr) return std::nullopt;
  struct Row {
    long long ppid = 0;
    bool runnable = false;
    double cpu_s = 0;
  };
  const double ticks = static_cast<double>(sysconf(_SC_CLK_TCK));
  std::map<long long, Row> rows;
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
    std::string state, skip;
    Row row;
    fields >> state >> row.ppid;
    for (int i = 0; i < 9; ++i) fields >> skip;  // pgrp .. cmajflt
    unsigned long long utime = 0, stime = 0;
    fields >> utime >> stime;
    if (!fields) continue;
    row.runnable = state == "R";
    row.cpu_s = static_cast<double>(utime + stime) / ticks;
    rows[std::atoll(name)] = row;
  }
  closedir(proc);
  if (rows.count(root) == 0) return std::nullopt;
  std::multimap<long long, long long> children;
  for (const auto& [pid, row] : rows) children.emplace(row.ppid, pid);
  TreeCpu tree;
  std::vector<long long> todo = {root};
  while (!todo.empty()) {
    const long long pid = todo.back();
    todo.pop_back();
    const Row& row = rows.at(pid);
    ++tree.processes;
    tree.cpu_s += row.cpu_s;
    tree.runnable = tree.runnable || row.runnable;
    auto [first, last] = children.equal_range(pid);
    for (auto it = first; it != last; ++it) todo.push_back(it->second);
  }
  return tree;
}

}  // namespace sandswim
