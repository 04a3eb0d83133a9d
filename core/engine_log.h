// EngineLog: what the worker reads from a LIGGGHTS log, and how a finished job is judged.
//
// ParseEngineLog() is pure: it takes the log text (complete or still growing) and returns the
// engine version (first line, "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled ...)"), the
// "SANDSWIM ..." marker lines the decks print (core/deck.h; only lines that start with the
// marker count, not the echoed `print` commands), the first ERROR line, whether atoms were lost,
// and the last thermo step seen (progress of a bed job).
//
// ClassifyExit() decides whether a job completed and, if not, which api::Failure kind it is.
// LIGGGHTS exits 0 after SIGTERM without finishing, and an error on one rank can lose the log, so
// completion is judged by the markers and the steps, never by the exit status alone:
//   a run is complete when its "drive stop" marker is there and either its step equals the
//   expected steps or the stop is an early "surface"/"floor" stop;
//   a bed is complete when its "bed grains" marker is there.
//
// Thread safety: pure functions and values.
#ifndef SANDSWIM_CORE_ENGINE_LOG_H_
#define SANDSWIM_CORE_ENGINE_LOG_H_

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "core/api.h"

namespace sandswim {

// "SANDSWIM bed grains N so_z Z grain_top Z step S"
struct BedGrainsMarker {
  int64_t grains = 0;
  double so_z = 0;
  double grain_top = 0;
  int64_t step = 0;
};
// "SANDSWIM bed equilibrated|not_equilibrated ke E ke_peak E"
struct BedEquilibriumMarker {
  bool equilibrated = false;
  double ke = 0;
  double ke_peak = 0;
};
// "SANDSWIM drive start grains N so_z Z surface Z"
struct DriveStartMarker {
  int64_t grains = 0;
  double so_z = 0;
  double surface = 0;
};
// "SANDSWIM drive stop duration|surface|floor step S t T z Z"
struct DriveStopMarker {
  std::string reason;  // "duration" | "surface" | "floor" | "target" | "window" (core/api.h RunResult)
  int64_t step = 0;
  double t = 0;
  double z = 0;
};

struct EngineLog {
  std::string version_line;  // the log's first line, as written
  std::string version;       // "LIGGGHTS-PUBLIC 3.8.0", or empty
  std::optional<BedGrainsMarker> bed_grains;
  std::optional<BedEquilibriumMarker> bed_equilibrium;
  std::optional<DriveStartMarker> drive_start;
  std::optional<DriveStopMarker> drive_stop;
  std::string error_line;  // first line starting with "ERROR", trimmed; empty if none
  int64_t error_line_number = 0;
  bool lost_atoms = false;  // a "Lost atoms" line was printed
  int64_t last_thermo_step = -1;
  std::string bad_marker;  // first SANDSWIM line that did not parse (the deck and reader disagree)
};

EngineLog ParseEngineLog(std::string_view text);

// The last `n` lines of the text (for Completion::log_tail).
std::string LastLines(std::string_view text, int n);

// How the engine's process ended (filled in by the launcher and the worker).
struct ExitFacts {
  bool started = true;      // false: mpirun/srun/liggghts could not be executed
  int exit_code = 0;        // when it exited normally
  int signal = 0;           // non-zero: the process died on this signal
  bool timed_out = false;   // the worker stopped it after its wall-time budget
  bool cancelled = false;   // the worker stopped it because the sweep was cancelled
  bool stalled = false;     // the worker stopped it: its simulated time stood still (stall_note says how long)
  std::string stall_note;   // "no step past 0 for 610 s of wall time"
  std::string start_error;  // why it could not start
};

// nullopt: the job completed. Otherwise the failure, with the line or fact that shows it.
// `expected_steps` is the grant's steps (runs; ignored for beds and when 0).
std::optional<api::Failure> ClassifyExit(api::JobKind kind, const ExitFacts& exit, const EngineLog& log,
                                         int64_t expected_steps);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_ENGINE_LOG_H_
