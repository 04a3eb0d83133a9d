// Engine probe: which LIGGGHTS the workers on this machine will run, read from the banner the
// engine prints first ("LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled ...)"). The daemon puts
// this string into every content key, so a new engine build invalidates old results.
//
// ProbeEngineVersion() runs the engine once (platform/subprocess.h) with empty input and no log
// file and reads its banner, killing it after `timeout_s`. It touches no files.
//
// Thread safety: free functions; safe from any thread.
#ifndef SANDSWIM_PLATFORM_ENGINE_PROBE_H_
#define SANDSWIM_PLATFORM_ENGINE_PROBE_H_

#include <optional>
#include <string>
#include <string_view>

#include "core/status.h"
#include "platform/subprocess.h"

namespace sandswim {

// The first line of `output` that starts with "LIGGGHTS (", trimmed; nullopt when none does.
std::optional<std::string> EngineVersionFromBanner(std::string_view output);

// Runs `engine` (a name on PATH or a path) as `engine -log none` with stdin from /dev/null.
// kUnavailable when it cannot be started, times out, or prints no banner.
Result<std::string> ProbeEngineVersion(const std::string& engine = "liggghts", double timeout_s = 10);
// The same through `processes` (platform/subprocess.h).
Result<std::string> ProbeEngineVersion(const std::string& engine, double timeout_s, Subprocesses& processes);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_ENGINE_PROBE_H_
