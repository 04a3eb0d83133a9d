#include "cli/analyze.h"

#include <filesystem>
#include <sstream>

#include "core/deck.h"
#include "core/engine_log.h"
#include "core/text.h"
#include "platform/files.h"

namespace sandswim::cli {
namespace {

namespace fs = std::filesystem;

// `given`, else `name` beside the dump when it exists; "" when neither.
std::string Beside(const std::string& given, const std::string& dump, const char* name) {
  if (!given.empty()) return given;
  fs::path p = fs::path(dump).parent_path() / name;
  std::error_code ec;
  return fs::is_regular_file(p, ec) ? p.string() : "";
}

}  // namespace

Result<DumpAnalysis> AnalyzeDumpFile(const std::string& dump_path, const AnalyzeOptions& o) {
  DumpAnalysis a;
  a.dump = dump_path;
  auto dump = ReadWholeFile(dump_path);
  if (!dump.ok()) return dump.status();

  DriveInfo drive;
  const std::string deck_path = Beside(o.deck, dump_path, "drive.in");
  if (!deck_path.empty()) {
    auto deck = ReadWholeFile(deck_path);
    if (!deck.ok()) return deck.status();
    auto info = ReadDriveInfo(*deck);
    if (!info.ok()) return Status::InvalidArgument("--deck", deck_path + ": " + info.status().reason());
    drive = *info;
  }
  EngineLog log;
  const std::string log_path = Beside(o.log, dump_path, kLogFile);
  if (!log_path.empty()) {
    auto text = ReadWholeFile(log_path);
    if (!text.ok()) return text.status();
    log = ParseEngineLog(*text);
  }
  a.inputs = RunInputsFrom(drive, log);
  const std::string from_deck = "deck " + deck_path, from_log = "log " + log_path;
  a.f_from = deck_path.empty() ? "" : from_deck;
  a.dt_from = deck_path.empty() ? "Table 1 (1e-5 s)" : from_deck;
  a.floor_from = a.inputs.bounds.floor ? from_deck : "";
  a.surface_from = a.inputs.bounds.surface ? from_log : "";
  if (o.f) {
    a.inputs.f = *o.f;
    a.f_from = "--f";
  }
  if (o.dt) {
    a.inputs.dt = *o.dt;
    a.dt_from = "--dt";
  }
  if (o.floor) {
    a.inputs.bounds.floor = *o.floor;
    a.floor_from = "--floor";
  }
  if (o.surface) {
    a.inputs.bounds.surface = *o.surface;
    a.surface_from = "--surface";
  }
  if (a.f_from.empty()) {
    return Status::InvalidArgument("--f", "no deck beside " + dump_path +
                                              " (drive.in) to read the drive frequency from: pass --f F (Hz; 0 for "
                                              "constant rotation) or --deck FILE");
  }
  if (!(a.inputs.f >= 0)) return Status::InvalidArgument("--f", "must be >= 0 Hz");
  if (!(a.inputs.dt > 0)) return Status::InvalidArgument("--dt", "must be > 0 s");

  auto samples = SamplesFromDump(*dump, a.inputs.dt, SoSelector{o.so_id});
  if (!samples.ok()) return Status::Corruption(dump_path + ": " + samples.status().reason());
  a.samples = samples->size();
  auto result = AnalyzeRun(*samples, a.inputs, o.rule);
  if (!result.ok()) return Status(result.status().code(), dump_path + ": " + result.status().reason());
  a.result = *result;
  return a;
}

nlohmann::json DumpAnalysisJson(const DumpAnalysis& a) {
  nlohmann::json inputs = {{"f", a.inputs.f}, {"dt", a.inputs.dt}, {"f_from", a.f_from}, {"dt_from", a.dt_from}};
  if (a.inputs.bounds.floor) {
    inputs["floor"] = *a.inputs.bounds.floor;
    inputs["floor_from"] = a.floor_from;
  }
  if (a.inputs.bounds.surface) {
    inputs["surface"] = *a.inputs.bounds.surface;
    inputs["surface_from"] = a.surface_from;
  }
  nlohmann::json result = a.result;
  result["uz_text"] = DescribeUz(a.result);
  return {{"dump", a.dump}, {"samples", a.samples}, {"inputs", inputs}, {"result", result}};
}

std::string RenderDumpAnalysis(const DumpAnalysis& a) {
  const api::RunResult& r = a.result;
  std::ostringstream out;
  out << a.dump << "\n";
  out << "  U_z:      " << DescribeUz(r) << "\n";
  if (r.uz_ci95) out << "            95 % interval ± " << Num(*r.uz_ci95, 4) << " m/s\n";
  if (!r.uz_stderr_note.empty()) out << "            no error: " << r.uz_stderr_note << "\n";
  if (!r.inconclusive_reason.empty()) out << "            inconclusive: " << r.inconclusive_reason << "\n";
  out << "  window:   " << Num(r.window_t0, 4) << " .. " << Num(r.window_t1, 4) << " s, " << r.uz_blocks << " whole "
      << (r.block_kind.empty() ? "period" : r.block_kind) << (r.uz_blocks == 1 ? "" : "s") << " of "
      << Num(r.block_s, 4) << " s, ended by " << r.window_end << "\n";
  out << "  motion:   dz = " << Num(r.dz, 4) << " m over " << Num(r.sim_time_s, 4) << " s (dz/T " << Num(r.dz_rate, 4)
      << " m/s), x drift " << Num(r.x_drift, 4) << " m\n";
  out << "  at f:     z oscillates " << Num(r.z_osc_amplitude, 4) << " m, x "
      << (r.x_osc_amplitude ? Num(*r.x_osc_amplitude, 4) + " m" : std::string("not measured")) << "\n";
  if (r.trend_p) {
    out << "  trend:    period rate changes by " << Num(*r.trend_slope, 3) << " ± " << Num(*r.trend_slope_se, 3)
        << " m/s² (p = " << Num(*r.trend_p, 3) << ")"
        << (r.trending ? ": TRENDING, U_z is the window's mean of a drifting rate" : "") << "\n";
  } else {
    out << "  trend:    not tested: " << r.trend_note << "\n";
  }
  out << "  inputs:   " << a.samples << " samples; f = " << Num(a.inputs.f, 4) << " Hz (" << a.f_from
      << "), dt = " << Num(a.inputs.dt, 4) << " s (" << a.dt_from << ")\n";
  out << "            floor "
      << (a.inputs.bounds.floor ? Num(*a.inputs.bounds.floor, 4) + " m (" + a.floor_from + ")"
                                : std::string("unknown: not checked (--floor Z)"))
      << ", surface "
      << (a.inputs.bounds.surface ? Num(*a.inputs.bounds.surface, 4) + " m (" + a.surface_from + ")"
                                  : std::string("unknown: not checked (--surface Z)"))
      << "\n";
  return out.str();
}

}  // namespace sandswim::cli
