#include "core/engine_log.h"
#include "core/text.h"

#include <cerrno>
#include <charconv>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

namespace sandswim {
namespace {

constexpr std::string_view kMarker = "SANDSWIM ";

std::vector<std::string_view> Split(std::string_view s) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

bool ToDouble(std::string_view tok, double* out) {
  if (tok.empty()) return false;
  auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  return ec == std::errc() && p == tok.data() + tok.size();
}

bool ToInt(std::string_view tok, int64_t* out) {
  // LIGGGHTS prints counts through equal-style variables, which may read "5024" or "5024.0".
  auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  if (ec == std::errc() && p == tok.data() + tok.size()) return true;
  double d;
  // Outside int64's range the cast below is undefined (a fuzzer found "grains 5.024e48").
  if (!ToDouble(tok, &d) || !(d >= -9223372036854775808.0 && d < 9223372036854775808.0)) return false;
  if (d != static_cast<double>(static_cast<int64_t>(d))) return false;
  *out = static_cast<int64_t>(d);
  return true;
}

// Reads "key value" pairs after `first` tokens; every key in `keys` must appear in order.
bool Pairs(const std::vector<std::string_view>& t, size_t first, const std::vector<std::string_view>& keys,
           std::vector<std::string_view>* values) {
  if (t.size() != first + 2 * keys.size()) return false;
  for (size_t k = 0; k < keys.size(); ++k) {
    if (t[first + 2 * k] != keys[k]) return false;
    values->push_back(t[first + 2 * k + 1]);
  }
  return true;
}

// Parses one "SANDSWIM ..." line into `log`; false when it does not fit any marker.
bool ParseMarker(std::string_view line, EngineLog* log) {
  std::vector<std::string_view> t = Split(line);
  std::vector<std::string_view> v;
  if (t.size() < 3) return false;
  if (t[1] == "bed" && t[2] == "grains") {
    BedGrainsMarker m;
    if (!Pairs(t, 2, {"grains", "so_z", "grain_top", "step"}, &v)) return false;
    if (!ToInt(v[0], &m.grains) || !ToDouble(v[1], &m.so_z) || !ToDouble(v[2], &m.grain_top) || !ToInt(v[3], &m.step)) {
      return false;
    }
    log->bed_grains = m;
    return true;
  }
  if (t[1] == "bed" && (t[2] == "equilibrated" || t[2] == "not_equilibrated")) {
    BedEquilibriumMarker m;
    m.equilibrated = t[2] == "equilibrated";
    if (!Pairs(t, 3, {"ke", "ke_peak"}, &v)) return false;
    if (!ToDouble(v[0], &m.ke) || !ToDouble(v[1], &m.ke_peak)) return false;
    log->bed_equilibrium = m;
    return true;
  }
  if (t[1] == "bed") return t[2] == "done" && t.size() == 3;  // "SANDSWIM bed done": nothing to keep
  if (t[1] == "drive" && t[2] == "start") {
    DriveStartMarker m;
    if (!Pairs(t, 3, {"grains", "so_z", "surface"}, &v)) return false;
    if (!ToInt(v[0], &m.grains) || !ToDouble(v[1], &m.so_z) || !ToDouble(v[2], &m.surface)) return false;
    log->drive_start = m;
    return true;
  }
  if (t[1] == "drive" && t[2] == "stop" && t.size() >= 4) {
    DriveStopMarker m;
    m.reason = std::string(t[3]);
    if (m.reason != "duration" && m.reason != "surface" && m.reason != "floor" && m.reason != "target" &&
        m.reason != "window")
      return false;
    if (!Pairs(t, 4, {"step", "t", "z"}, &v)) return false;
    if (!ToInt(v[0], &m.step) || !ToDouble(v[1], &m.t) || !ToDouble(v[2], &m.z)) return false;
    log->drive_stop = m;
    return true;
  }
  return false;
}

// A thermo line: every token a number, the first an integer step.
bool ThermoStep(std::string_view line, int64_t* step) {
  std::vector<std::string_view> t = Split(line);
  if (t.size() < 2) return false;
  int64_t s;
  auto [p, ec] = std::from_chars(t[0].data(), t[0].data() + t[0].size(), s);
  if (ec != std::errc() || p != t[0].data() + t[0].size()) return false;
  for (size_t i = 1; i < t.size(); ++i) {
    double d;
    if (!ToDouble(t[i], &d)) return false;
  }
  *step = s;
  return true;
}

const char* SignalName(int sig) {
  switch (sig) {
    case 1:
      return "SIGHUP";
    case 2:
      return "SIGINT";
    case 6:
      return "SIGABRT";
    case 7:
      return "SIGBUS";
    case 8:
      return "SIGFPE";
    case 9:
      return "SIGKILL";
    case 11:
      return "SIGSEGV";
    case 13:
      return "SIGPIPE";
    case 15:
      return "SIGTERM";
    default:
      return "signal";
  }
}

}  // namespace

EngineLog ParseEngineLog(std::string_view text) {
  EngineLog log;
  int64_t line_no = 0;
  size_t pos = 0;
  while (pos < text.size()) {
    size_t nl = text.find('\n', pos);
    // The last line of a growing log may be incomplete: markers and errors are read only from
    // complete lines, so a half-written number is never taken for the whole one.
    if (nl == std::string_view::npos) break;
    std::string_view line = text.substr(pos, nl - pos);
    pos = nl + 1;
    ++line_no;
    if (line_no == 1) {
      log.version_line = std::string(Trim(line));
      constexpr std::string_view kVersion = "(Version ";
      size_t v = line.find(kVersion);
      if (StartsWith(line, "LIGGGHTS") && v != std::string_view::npos) {
        size_t start = v + kVersion.size();
        size_t end = line.find_first_of(",)", start);
        if (end != std::string_view::npos) log.version = std::string(Trim(line.substr(start, end - start)));
      }
      continue;
    }
    if (StartsWith(line, kMarker)) {
      if (!ParseMarker(Trim(line), &log) && log.bad_marker.empty()) log.bad_marker = std::string(Trim(line));
      continue;
    }
    if (StartsWith(line, "ERROR")) {
      if (log.error_line.empty()) {
        log.error_line = std::string(Trim(line));
        log.error_line_number = line_no;
      }
      if (line.find("Lost atoms") != std::string_view::npos) log.lost_atoms = true;
      continue;
    }
    if (line.find("Lost atoms") != std::string_view::npos && !StartsWith(Trim(line), "thermo_modify")) {
      log.lost_atoms = true;
      continue;
    }
    int64_t step;
    if (!line.empty() && (line[0] == ' ' || (line[0] >= '0' && line[0] <= '9')) && ThermoStep(line, &step)) {
      log.last_thermo_step = step;
    }
  }
  return log;
}

std::string LastLines(std::string_view text, int n) {
  if (n <= 0) return "";
  size_t end = text.size();
  if (end > 0 && text[end - 1] == '\n') --end;
  size_t start = end;
  int lines = 0;
  while (start > 0) {
    if (text[start - 1] == '\n' && ++lines == n) break;
    --start;
  }
  return std::string(text.substr(start));
}

std::optional<api::Failure> ClassifyExit(api::JobKind kind, const ExitFacts& exit, const EngineLog& log,
                                         int64_t expected_steps) {
  auto fail = [](std::string k, std::string m) { return api::Failure{std::move(k), std::move(m)}; };
  if (!exit.started) return fail("engine_missing", "could not start the engine: " + exit.start_error);
  // The worker's own reasons come first: they explain the signal the engine then died on.
  if (exit.cancelled) return fail("cancelled", "stopped because the sweep was cancelled");
  if (exit.timed_out) return fail("timeout", "stopped after its wall-time budget");
  if (exit.stalled) return fail("stalled", "stopped: " + exit.stall_note);
  if (log.lost_atoms) {
    return fail("lost_atoms", log.error_line.empty() ? "LIGGGHTS lost atoms" : log.error_line);
  }
  if (!log.error_line.empty()) return fail("deck_error", log.error_line);
  if (exit.signal != 0) {
    return fail("signal", std::string("the engine died on ") + SignalName(exit.signal) + " (" +
                              std::to_string(exit.signal) + ")");
  }
  // LIGGGHTS writes its version line first thing, so no log at all means it never ran (mpirun
  // itself exits 134 when it cannot find the executable).
  if (log.version_line.empty()) {
    if (exit.exit_code != 0) {
      return fail("engine_missing", "the engine exited with status " + std::to_string(exit.exit_code) +
                                        " and wrote no log: is liggghts installed and on PATH (and mpirun/srun "
                                        "working)?");
    }
    return fail("bad_output", "the engine exited 0 but wrote no log");
  }
  if (exit.exit_code > 128 && exit.exit_code <= 128 + 64) {
    // mpirun reports a rank that died on a signal as 128 + signal.
    int sig = exit.exit_code - 128;
    return fail("signal", "exit status " + std::to_string(exit.exit_code) + ": a rank died on " + SignalName(sig) +
                              " (" + std::to_string(sig) + ")");
  }
  if (!log.bad_marker.empty()) {
    return fail("bad_output", "unreadable marker line (deck and worker disagree): " + log.bad_marker);
  }
  const std::string status_text = "exit status " + std::to_string(exit.exit_code);
  if (kind == api::JobKind::kBed) {
    if (!log.bed_grains) {
      return fail("incomplete", status_text + " without the 'SANDSWIM bed grains' marker (last step " +
                                    std::to_string(log.last_thermo_step) + ")");
    }
  } else {
    if (!log.drive_stop) {
      return fail("incomplete", status_text + " without the 'SANDSWIM drive stop' marker (last step " +
                                    std::to_string(log.last_thermo_step) + " of " + std::to_string(expected_steps) +
                                    ")");
    }
    const DriveStopMarker& stop = *log.drive_stop;
    if (stop.reason == "duration" && expected_steps > 0 && stop.step != expected_steps) {
      return fail("incomplete", "stopped at step " + std::to_string(stop.step) + " but " +
                                    std::to_string(expected_steps) + " steps were expected");
    }
  }
  if (exit.exit_code != 0) {
    // The markers say it finished, yet the process failed (e.g. at write_restart or teardown).
    return fail("incomplete", status_text + " after the engine printed its last marker");
  }
  return std::nullopt;
}

}  // namespace sandswim
