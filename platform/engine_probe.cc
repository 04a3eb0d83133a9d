#include "platform/engine_probe.h"

namespace sandswim {

std::optional<std::string> EngineVersionFromBanner(std::string_view output) {
  size_t pos = 0;
  while (pos < output.size()) {
    size_t end = output.find('\n', pos);
    if (end == std::string_view::npos) end = output.size();
    std::string_view line = output.substr(pos, end - pos);
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) {
      line.remove_suffix(1);
    }
    if (line.rfind("LIGGGHTS (", 0) == 0) return std::string(line);
    pos = end + 1;
  }
  return std::nullopt;
}

Result<std::string> ProbeEngineVersion(const std::string& engine, double timeout_s, Subprocesses& processes) {
  // The engine exits by itself on empty input; one that hangs is killed at the deadline, and a
  // banner it printed before still counts.
  Result<CommandOutput> run = processes.Run({engine, "-log", "none"}, {}, timeout_s);
  if (!run.ok()) return Status::Unavailable("cannot start " + engine + ": " + run.status().reason());
  if (auto version = EngineVersionFromBanner(run->out)) return *version;
  if (run->timed_out)
    return Status::Unavailable(engine + " printed no banner within " + std::to_string(timeout_s) + " s");
  return Status::Unavailable(engine + " printed no \"LIGGGHTS (Version ...)\" banner");
}

Result<std::string> ProbeEngineVersion(const std::string& engine, double timeout_s) {
  PosixSubprocesses processes;
  return ProbeEngineVersion(engine, timeout_s, processes);
}

}  // namespace sandswim
