// `sandswim analyze`: the service's U_z analysis (core/trajectory.h), offline, on LIGGGHTS dumps of
// the SO — the run directories this service writes, and any `dump custom` with the SO's id, x, y, z.
//
// For each dump, what the analysis needs besides the samples is read as the worker reads it
// (RunInputsFrom): the drive frequency, the time step and the floor from the run's deck (`drive.in`
// beside the dump, or --deck), the bed surface and the engine's stop from its log (`log.liggghts`
// beside the dump, or --log). Options override each; what is still unknown is said (a boundary not
// known is not checked). So a service run directory gives the numbers the worker reported.
//
// Thread safety: pure functions over the files named; nothing is shared.
#ifndef SANDSWIM_CLI_ANALYZE_H_
#define SANDSWIM_CLI_ANALYZE_H_

#include <cstdint>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "core/trajectory.h"

namespace sandswim::cli {

struct AnalyzeOptions {
  std::optional<double> f;        // Hz (0: no period)
  std::optional<double> dt;       // s per step
  std::optional<double> floor;    // m
  std::optional<double> surface;  // m
  std::optional<int64_t> so_id;   // the SO's atom id
  std::string deck, log;          // files; "" = drive.in / log.liggghts beside the dump, if there
  WindowRule rule;
};

// One dump's analysis: the inputs as found (and where), and the result.
struct DumpAnalysis {
  std::string dump;
  RunInputs inputs;
  std::string f_from, dt_from, floor_from, surface_from;  // "deck <path>", "--f", "log <path>", ...
  size_t samples = 0;
  api::RunResult result;
};

// InvalidArgument naming the option when the frequency is known from nowhere; IOError when a file
// cannot be read; Corruption when the dump cannot (with the line and the reason).
Result<DumpAnalysis> AnalyzeDumpFile(const std::string& dump_path, const AnalyzeOptions& options);

// {"dump","samples","inputs":{"f","dt","floor"?,"surface"?,"f_from",...},"result":RunResult}
nlohmann::json DumpAnalysisJson(const DumpAnalysis& a);
// A few lines for a terminal: U_z (DescribeUz), its interval and window, dz/T, what was not known.
std::string RenderDumpAnalysis(const DumpAnalysis& a);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_ANALYZE_H_
