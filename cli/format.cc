#include "cli/format.h"

#include "core/job_state.h"
#include "core/claims.h"
#include "core/materials.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <sstream>

namespace sandswim::cli {
namespace {

using json = nlohmann::json;

std::string Str(const json& j, const char* key, const std::string& fallback = "") {
  auto it = j.find(key);
  if (it == j.end() || it->is_null()) return fallback;
  if (it->is_string()) return it->get<std::string>();
  return it->dump();
}

std::optional<double> Num(const json& j, const char* key) {
  auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return std::nullopt;
  return it->get<double>();
}

int64_t Int(const json& j, const char* key) {
  auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return 0;
  return it->get<int64_t>();
}

bool Bool(const json& j, const char* key) {
  auto it = j.find(key);
  return it != j.end() && it->is_boolean() && it->get<bool>();
}

std::string Pad(const std::string& text, size_t width, Align align) {
  size_t w = DisplayWidth(text);
  if (w >= width) return text;
  std::string fill(width - w, ' ');
  return align == Align::kRight ? fill + text : text + fill;
}

std::string StateCell(const std::string& state) { return state.empty() ? "-" : state; }

// The drive's angular velocity: Omega for oscillatory points, omega for the rotation modes.
std::string OmegaCell(const json& p) {
  if (auto v = Num(p, "Omega")) return DisplayNumber(*v);
  if (auto v = Num(p, "omega")) return DisplayNumber(*v);
  return "-";
}

std::string NumCell(const json& j, const char* key, int precision = 6) {
  auto v = Num(j, key);
  return v ? DisplayNumber(*v, precision) : "-";
}

}  // namespace

std::string Describe(const Status& s) { return s.field().empty() ? s.reason() : s.field() + ": " + s.reason(); }

// ---- Building blocks ---------------------------------------------------------------------------

size_t DisplayWidth(const std::string& text) {
  size_t n = 0;
  for (unsigned char ch : text) {
    if ((ch & 0xC0) != 0x80) ++n;
  }
  return n;
}

std::string RenderTable(const Table& table) {
  size_t columns = table.header.size();
  for (const auto& row : table.rows) columns = std::max(columns, row.size());
  std::vector<size_t> width(columns, 0);
  auto measure = [&](const std::vector<std::string>& row) {
    for (size_t i = 0; i < row.size(); ++i) width[i] = std::max(width[i], DisplayWidth(row[i]));
  };
  measure(table.header);
  for (const auto& row : table.rows) measure(row);

  auto line = [&](const std::vector<std::string>& row, const std::vector<std::string>* colors) {
    std::string out;
    for (size_t i = 0; i < columns; ++i) {
      std::string cell = i < row.size() ? row[i] : "";
      Align align = i < table.align.size() ? table.align[i] : Align::kLeft;
      bool last = i + 1 == columns;
      // The last column is not padded on the right: no trailing blanks.
      std::string padded = (last && align == Align::kLeft) ? cell : Pad(cell, width[i], align);
      if (colors != nullptr && i < colors->size() && !(*colors)[i].empty()) {
        // Colour the text only, not the padding around it.
        size_t start = padded.find(cell);
        padded = padded.substr(0, start) + Colorize(cell, (*colors)[i], true) + padded.substr(start + cell.size());
      }
      out += (i ? "  " : "") + padded;
    }
    while (!out.empty() && out.back() == ' ') out.pop_back();
    return out + "\n";
  };
  std::string out = line(table.header, nullptr);
  for (size_t r = 0; r < table.rows.size(); ++r) {
    out += line(table.rows[r], r < table.color.size() ? &table.color[r] : nullptr);
  }
  return out;
}

std::string Colorize(const std::string& text, const std::string& code, bool color) {
  if (!color || code.empty() || text.empty()) return text;
  return "\x1b[" + code + "m" + text + "\x1b[0m";
}

std::string StateColor(const std::string& state) {
  if (InState(state, JobState::kDone)) return "32";
  if (InState(state, JobState::kFailed)) return "31";
  if (InState(state, JobState::kRunning)) return "33";
  if (InState(state, JobState::kCancelled)) return "2";
  return "";
}

std::string DisplayNumber(double v, int precision) {
  if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
  if (v == 0) return "0";  // never "-0"
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*g", precision, v);
  return buffer;
}

std::string FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  long long s = std::llround(seconds);
  char buffer[64];
  if (s < 60) {
    std::snprintf(buffer, sizeof buffer, "%llds", s);
  } else if (s < 3600) {
    std::snprintf(buffer, sizeof buffer, "%lldm%02llds", s / 60, s % 60);
  } else if (s < 86400) {
    std::snprintf(buffer, sizeof buffer, "%lldh%02lldm", s / 3600, (s % 3600) / 60);
  } else {
    std::snprintf(buffer, sizeof buffer, "%lldd%02lldh", s / 86400, (s % 86400) / 3600);
  }
  return buffer;
}

std::string ProgressBar(double fraction, int width) {
  if (!std::isfinite(fraction)) fraction = 0;
  fraction = std::clamp(fraction, 0.0, 1.0);
  width = std::max(width, 1);
  int filled = static_cast<int>(std::floor(fraction * width + 1e-9));
  char percent[16];
  std::snprintf(percent, sizeof percent, "%3d%%", static_cast<int>(std::floor(fraction * 100 + 1e-9)));
  return "[" + std::string(filled, '#') + std::string(width - filled, '.') + "] " + percent;
}

// ---- Domain values -----------------------------------------------------------------------------

Counts CountsFromJson(const json& j) {
  Counts c;
  if (!j.is_object()) return c;
  c.queued = Int(j, "queued");
  c.running = Int(j, "running");
  c.done = Int(j, "done");
  c.failed = Int(j, "failed");
  c.cancelled = Int(j, "cancelled");
  return c;
}

std::string FormatCounts(const Counts& c, const RenderOptions& options) {
  auto part = [&](int64_t n, const char* state) {
    std::string text = std::to_string(n) + " " + state;
    return n > 0 ? Colorize(text, StateColor(state), options.color) : text;
  };
  return part(c.queued, "queued") + ", " + part(c.running, "running") + ", " + part(c.done, "done") + ", " +
         part(c.failed, "failed") + ", " + part(c.cancelled, "cancelled");
}

std::string FormatPoint(const json& p) {
  if (!p.is_object()) return "?";
  std::string out = Str(p, "mode", "?");
  const char* fields[] = {"A", "f", "Omega", "omega"};
  for (const char* f : fields) {
    if (auto v = Num(p, f)) out += std::string(" ") + f + "=" + DisplayNumber(*v);
  }
  std::string axis = Str(p, "axis");
  if (!axis.empty()) out += " axis=" + axis;
  if (auto d = Num(p, "duration_s")) out += " T=" + DisplayNumber(*d) + "s";
  // Materials that are not Table 1's (a point's JSON carries only those: core/materials.h).
  for (const MaterialField& m : MaterialFields()) {
    const std::string name(m.name);
    if (auto v = Num(p, name.c_str())) out += " " + name + "=" + DisplayNumber(*v);
  }
  return out;
}

// ---- status / watch ----------------------------------------------------------------------------

double RunInFlight::fraction() const {
  if (!(duration_s > 0) || !std::isfinite(sim_time_s)) return 0;
  return std::clamp(sim_time_s / duration_s, 0.0, 1.0);
}

std::optional<Snapshot::DaemonEta::Band> Snapshot::DaemonEta::band() const {
  if (high_s > 0 && low_s >= 0 && low_s <= high_s) return Band{low_s, high_s};
  if (rel_error > 0 && std::isfinite(rel_error)) return Band{s / std::exp(rel_error), s * std::exp(rel_error)};
  return std::nullopt;
}

std::optional<double> Snapshot::eta_s() const {
  if (counts.finished()) return 0.0;
  // Nothing running: a time only while a bed is prepared or a prepared bed's runs wait for a slot
  // (the workers busy with other beds of the campaign); with the bed unstarted, a worker may lack.
  if (!eta || (counts.running == 0 && !InState(waiting_bed_state, JobState::kRunning) &&
               !InState(waiting_bed_state, JobState::kDone)))
    return std::nullopt;
  return eta->s;
}

namespace {

std::string EtaText(const Snapshot& s) {
  if (s.counts.finished()) return "finished";
  auto eta = s.eta_s();
  if (eta) {
    std::string text = "ETA " + FormatDuration(*eta);
    // The band as the daemon gives it (on a log scale, so not symmetric): "ETA 58m (50m-67m)".
    if (auto band = s.eta->band()) text += " (" + FormatDuration(band->low_s) + "-" + FormatDuration(band->high_s) + ")";
    if (s.counts.running == 0)
      text += InState(s.waiting_bed_state, JobState::kDone) ? " (none of its runs has started: they wait for a free worker)"
                                            : " (preparing the granular bed first)";
    return text;
  }
  if (s.counts.running == 0) {
    // Runs start only once their bed is prepared (minutes at smoke): say so, not "no worker".
    if (InState(s.waiting_bed_state, JobState::kRunning)) return "ETA unknown (preparing the granular bed first)";
    if (InState(s.waiting_bed_state, JobState::kQueued)) return "ETA unknown (the bed waits for a worker: is one running?)";
    return "ETA unknown (no run in flight: is a worker running?)";
  }
  return "ETA unknown (the daemon gives none: older than its cost model?)";
}

std::string InFlightLine(const RunInFlight& r) {
  return "run " + std::to_string(r.id) + "  " + ProgressBar(r.fraction()) + "  " + DisplayNumber(r.sim_time_s, 4) +
         "/" + DisplayNumber(r.duration_s, 4) + " s  z=" + DisplayNumber(r.so_z, 4) + " m  " + r.point;
}

}  // namespace

std::string RenderStatus(const Snapshot& s, const RenderOptions& options) {
  std::string out = s.title + "\n";
  out += "  runs: " + std::to_string(s.counts.total()) + " (" + FormatCounts(s.counts, options) + ")\n";
  out += "  " + EtaText(s) + "\n";
  if (s.eta_s() && s.eta && !s.eta->basis.empty()) out += "    (" + s.eta->basis + ")\n";
  if (!s.running.empty()) {
    out += "in flight:\n";
    for (const auto& r : s.running) {
      out += "  " + InFlightLine(r) + (r.worker.empty() ? "" : "  on " + r.worker) + "\n";
    }
  }
  out += RenderFailures(s.failed, options);
  out += RenderRounds(s.adaptive, s.rounds);
  return out;
}

std::string RenderFailures(const std::vector<RunFailure>& failed, const RenderOptions& options) {
  if (failed.empty()) return "";
  std::string out = Colorize("failed:", StateColor("failed"), options.color) + "\n";
  for (const auto& f : failed) out += "  run " + std::to_string(f.id) + "  " + f.point + "\n    " + f.reason + "\n";
  return out;
}

std::string RenderRounds(const json& adaptive, const json& rounds) {
  if (!rounds.is_array() || rounds.empty()) return "";
  auto h = [](const json& v) {
    if (!v.is_number()) return std::string("-");
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.3g", v.get<double>());
    return std::string(buf);
  };
  std::string out = "rounds";
  if (adaptive.is_object()) {
    out += " (budget " + h(adaptive.value("budget_core_h", json())) + " core-h, at most " +
           h(adaptive.value("max_rounds", json())) + " rounds)";
  }
  out += ":\n";
  for (const json& r : rounds) {
    const bool finished = r.value("finished_at", json()).is_number();
    out += "  round " + std::to_string(r.value("round", 0)) + "  " + (finished ? "finished" : "running") +
           "  planned " + h(r.value("core_h_planned", json())) + " core-h";
    if (finished) {
      out += ", spent " + h(r.value("core_h_spent", json())) + ", " + h(r.value("budget_left_core_h", json())) +
             " core-h left";
    }
    out += "\n";
    for (const json& a : r.value("actions", json::array())) out += "    " + a.value("reason", std::string()) + "\n";
    const json after = r.value("claims_after", json());
    if (after.is_array() && !after.empty()) {
      std::string states;
      for (const json& c : after) {
        states += (states.empty() ? "" : ", ") + c.value("claim", std::string("?")) + " " +
                  c.value("verdict", std::string("?"));
        if (c.contains("frozen_at_round")) states += " (round " + std::to_string(c.value("frozen_at_round", 0)) + ")";
      }
      out += "    after it: " + states + "\n";
    }
    if (r.value("stop_reason", json()).is_string()) out += "  stopped: " + r["stop_reason"].get<std::string>() + "\n";
  }
  return out;
}

std::string RenderWatchFrame(const Snapshot& s, const RenderOptions& options) {
  std::string out = s.title + "\n";
  out += "  " + FormatCounts(s.counts, options) + "; " + EtaText(s) + "\n";
  for (const auto& r : s.running) out += "  " + InFlightLine(r) + "\n";
  return out;
}

json SnapshotToJson(const Snapshot& s) {
  json running = json::array(), failed = json::array();
  for (const auto& r : s.running) {
    running.push_back({{"id", r.id},
                       {"point", r.point},
                       {"sim_time_s", r.sim_time_s},
                       {"duration_s", r.duration_s},
                       {"so_z", r.so_z},
                       {"worker", r.worker}});
  }
  for (const auto& f : s.failed) failed.push_back({{"id", f.id}, {"point", f.point}, {"reason", f.reason}});
  auto eta = s.eta_s();
  json j = {{"title", s.title},
          {"counts",
           {{"queued", s.counts.queued},
            {"running", s.counts.running},
            {"done", s.counts.done},
            {"failed", s.counts.failed},
            {"cancelled", s.counts.cancelled}}},
          {"running", running},
          {"failed", failed},
          {"eta_s", eta ? json(*eta) : json(nullptr)},
          {"finished", s.counts.finished()}};
  if (eta && s.eta) {
    j["eta_rel_error"] = s.eta->rel_error;
    if (auto band = s.eta->band()) {
      j["eta_low_s"] = band->low_s;
      j["eta_high_s"] = band->high_s;
    }
    j["eta_basis"] = s.eta->basis;
  }
  if (!s.rounds.empty()) {
    j["adaptive"] = s.adaptive;
    j["rounds"] = s.rounds;
  }
  return j;
}

std::string RenderWatchLine(const Snapshot& s) {
  const Counts& c = s.counts;
  return s.title + ": " + std::to_string(c.done) + "/" + std::to_string(c.total()) + " done, " +
         std::to_string(c.running) + " running, " + std::to_string(c.queued) + " queued, " + std::to_string(c.failed) +
         " failed, " + std::to_string(c.cancelled) + " cancelled; " + EtaText(s);
}

// ---- Lists and results -------------------------------------------------------------------------

std::string RenderSweepsTable(const json& sweeps, const RenderOptions&) {
  Table t;
  t.header = {"ID", "NAME", "SCALE", "RUNS", "QUEUED", "RUNNING", "DONE", "FAILED", "CANCELLED"};
  t.align = {Align::kRight, Align::kLeft,  Align::kLeft,  Align::kRight, Align::kRight,
             Align::kRight, Align::kRight, Align::kRight, Align::kRight};
  if (sweeps.is_array()) {
    for (const auto& s : sweeps) {
      Counts c = CountsFromJson(s.value("counts", json::object()));
      std::string name = Str(s, "name");
      if (Bool(s, "cancelled")) name += " (cancelled)";
      t.rows.push_back({Str(s, "id"), name, Str(s, "scale"), std::to_string(c.total()), std::to_string(c.queued),
                        std::to_string(c.running), std::to_string(c.done), std::to_string(c.failed),
                        std::to_string(c.cancelled)});
    }
  }
  return RenderTable(t);
}

std::string RenderRunsTable(const json& runs, const RenderOptions& options) {
  Table t;
  t.header = {"ID", "STATE", "PROGRESS", "U_z", "POINT", "WORKER"};  // uz_text carries its unit
  t.align = {Align::kRight, Align::kLeft, Align::kRight, Align::kRight, Align::kLeft, Align::kLeft};
  if (runs.is_array()) {
    for (const auto& r : runs) {
      std::string state = Str(r, "state");
      json progress = r.value("progress", json::object());
      std::string progress_text = "-";
      if (InState(state, JobState::kRunning) || InState(state, JobState::kDone)) {
        progress_text = NumCell(progress, "sim_time_s", 4) + "/" + NumCell(r, "run_duration_s", 4) + " s";
      }
      std::string worker = Str(r, "worker");
      t.rows.push_back({Str(r, "id"), StateCell(state), progress_text, Str(r, "uz_text", "-"),
                        FormatPoint(r.value("point", json::object())), worker.empty() ? "-" : worker});
      t.color.push_back({"", options.color ? StateColor(state) : ""});
    }
  }
  return RenderTable(t);
}

std::string RenderRunDetail(const json& run, const RenderOptions& options) {
  std::ostringstream out;
  std::string state = Str(run, "state");
  out << "run " << Str(run, "id") << "  " << Colorize(state, StateColor(state), options.color) << "\n";
  out << "  key:       " << Str(run, "key") << "\n";
  out << "  point:     " << FormatPoint(run.value("point", json::object())) << "\n";
  out << "  runs for:  " << NumCell(run, "run_duration_s") << " s simulated, " << Str(run, "steps", "?") << " steps\n";
  out << "  bed:       " << Str(run, "bed_id", "?") << " (" << Str(run, "bed_state", "?") << ")\n";
  std::string sweeps;
  for (const auto& id : run.value("sweeps", json::array())) sweeps += (sweeps.empty() ? "" : ", ") + id.dump();
  out << "  sweeps:    " << (sweeps.empty() ? "-" : sweeps) << "\n";
  std::string worker = Str(run, "worker");
  out << "  attempts:  " << Str(run, "attempts", "0") << (worker.empty() ? "" : ", last on " + worker) << "\n";
  json progress = run.value("progress", json::object());
  if (InState(state, JobState::kRunning)) {
    RunInFlight r;
    r.sim_time_s = Num(progress, "sim_time_s").value_or(0);
    r.duration_s = Num(run, "run_duration_s").value_or(0);
    out << "  progress:  " << ProgressBar(r.fraction()) << "  " << DisplayNumber(r.sim_time_s, 4) << "/"
        << DisplayNumber(r.duration_s, 4) << " s  z=" << NumCell(progress, "so_z", 4) << " m\n";
  }
  if (run.contains("result") && run["result"].is_object()) {
    const json& r = run["result"];
    out << "  result:    U_z = " << Str(r, "uz_text", "?") << "\n";
    if (r.contains("uz_ci95")) {
      out << "             95 % interval ± " << NumCell(r, "uz_ci95", 2) << " m/s (Student t, "
          << Str(r, "uz_blocks", "?") << " whole " << Str(r, "block_kind", "period") << " rates)\n";
    }
    std::string note = Str(r, "uz_stderr_note");
    if (!note.empty()) out << "             no error: " << note << "\n";
    std::string why = Str(r, "inconclusive_reason");
    if (!why.empty()) out << "             inconclusive: " << why << "\n";
    out << "  window:    " << NumCell(r, "window_t0", 4) << " .. " << NumCell(r, "window_t1", 4) << " s, ended by "
        << Str(r, "window_end", "?") << "\n";
    out << "  motion:    dz = " << NumCell(r, "dz", 4) << " m (dz/T over the whole run " << NumCell(r, "dz_rate", 3)
        << " m/s), x drift = " << NumCell(r, "x_drift", 4) << " m\n";
    // x's amplitude is absent where it was not measured (no whole period, or an older analysis).
    out << "  at f:      z oscillates " << NumCell(r, "z_osc_amplitude", 3) << " m, x "
        << (r.contains("x_osc_amplitude") ? NumCell(r, "x_osc_amplitude", 3) + " m" : std::string("not measured"))
        << "\n";
    if (r.contains("trend_p")) {
      out << "  trend:     period rate changes by " << NumCell(r, "trend_slope", 2) << " ± "
          << NumCell(r, "trend_slope_se", 2) << " m/s² (p = " << NumCell(r, "trend_p", 2) << ")"
          << (Bool(r, "trending") ? ": TRENDING, U_z is the window's mean of a drifting rate" : "") << "\n";
    } else if (!Str(r, "trend_note").empty()) {
      out << "  trend:     not tested: " << Str(r, "trend_note") << "\n";
    }
    const std::string stop_note = Str(r, "stop_note");
    out << "  ended:     " << (stop_note.empty() ? Str(r, "stop_reason", "?") : stop_note) << "\n";
    out << "  executed:  " << Str(r, "engine_version", "?") << " on " << Str(r, "host", "?") << ", "
        << Str(r, "ranks", "?") << " rank(s), " << FormatDuration(Num(r, "wall_s").value_or(-1)) << " wall\n";
  }
  if (run.contains("last_error") && run["last_error"].is_object()) {
    out << "  error:     " << Str(run["last_error"], "kind") << ": " << Str(run["last_error"], "message") << "\n";
  }
  std::string deck = Str(run, "deck");
  if (!deck.empty()) {
    out << "--- deck ---\n" << deck;
    if (deck.back() != '\n') out << "\n";
  }
  std::string log = Str(run, "log_tail");
  out << "--- log tail ---\n";
  if (log.empty()) {
    out << "(no log yet)\n";
  } else {
    out << log;
    if (log.back() != '\n') out << "\n";
  }
  return out.str();
}

std::string ResultFlags(const json& row) {
  std::string flags;
  if (Bool(row, "broke_surface")) flags = "surface";
  if (Bool(row, "near_floor")) flags += flags.empty() ? "floor" : ",floor";
  // The steady window was cut short by the SO nearing the surface or the floor.
  std::string end = Str(row, "window_end");
  if (end == "surface" || end == "floor") flags += (flags.empty() ? "window<" : ",window<") + end;
  // A run with a precision target: met ("target"), or ended without it ("target-missed").
  auto met = row.find("precision_met");
  if (met != row.end() && met->is_boolean())
    flags += (flags.empty() ? "" : ",") + std::string(*met ? "target" : "target-missed");
  // Its period rates drift with time (core/trajectory.h "Trend"): U_z is their mean over the window.
  if (Bool(row, "trending")) flags += (flags.empty() ? "" : ",") + std::string("trend");
  return flags;
}

namespace {

// The materials some row sets (its JSON carries only those not Table 1's), in core/materials.h's
// order: the swept ones, shown as columns beside the drive's.
std::vector<const MaterialField*> RowsMaterials(const json& rows) {
  std::vector<const MaterialField*> shown;
  if (!rows.is_array()) return shown;
  for (const MaterialField& f : MaterialFields()) {
    for (const auto& r : rows) {
      if (r.contains(std::string(f.name))) {
        shown.push_back(&f);
        break;
      }
    }
  }
  return shown;
}

// Inserts a column per material after the header's `at`-th column ("so_density (kg/m^3)"), and
// each row's value (Table 1's where it sets none).
void AddMaterialColumns(Table& t, const std::vector<const MaterialField*>& shown, size_t at) {
  for (size_t i = 0; i < shown.size(); ++i) {
    const MaterialField& f = *shown[i];
    t.header.insert(t.header.begin() + at + i,
                    std::string(f.name) + (f.unit.empty() ? "" : " (" + std::string(f.unit) + ")"));
    t.align.insert(t.align.begin() + at + i, Align::kRight);
  }
}
std::vector<std::string> MaterialCells(const json& r, const std::vector<const MaterialField*>& shown) {
  std::vector<std::string> cells;
  for (const MaterialField* f : shown) {
    const std::string name(f->name);
    cells.push_back(r.contains(name) ? NumCell(r, name.c_str()) : DisplayNumber(kTable1.*f->member));
  }
  return cells;
}

}  // namespace

std::string RenderResultsTable(const json& rows, const RenderOptions& options) {
  bool with_sweeps = false;
  if (rows.is_array()) {
    for (const auto& r : rows) with_sweeps = with_sweeps || r.contains("sweeps");
  }
  Table t;
  t.header = {"RUN",  "STATE",    "MODE",      "A",          "f",      "Omega/omega",
              "AXIS", "DURATION", "U_z (m/s)", "Δz/T (m/s)", "Δz (m)", "FLAGS"};
  t.align = {Align::kRight, Align::kLeft,  Align::kLeft,  Align::kRight, Align::kRight, Align::kRight,
             Align::kLeft,  Align::kRight, Align::kRight, Align::kRight, Align::kRight, Align::kLeft};
  constexpr size_t kAfterDrive = 8;  // the materials' columns follow DURATION
  const std::vector<const MaterialField*> materials = RowsMaterials(rows);
  AddMaterialColumns(t, materials, kAfterDrive);
  if (with_sweeps) t.header.push_back("SWEEPS");
  if (rows.is_array()) {
    for (const auto& r : rows) {
      std::string state = Str(r, "state");
      std::string axis = Str(r, "axis");
      std::string flags = ResultFlags(r);
      std::vector<std::string> row = {Str(r, "run_id"),          StateCell(state),         Str(r, "mode", "-"),
                                      NumCell(r, "A"),           NumCell(r, "f"),          OmegaCell(r),
                                      axis.empty() ? "-" : axis, NumCell(r, "duration_s"), Str(r, "Uz_text", "-"),
                                      NumCell(r, "dz_rate", 2),  NumCell(r, "dz", 3),      flags.empty() ? "-" : flags};
      const std::vector<std::string> cells = MaterialCells(r, materials);
      row.insert(row.begin() + kAfterDrive, cells.begin(), cells.end());
      if (with_sweeps) {
        std::string sweeps;
        for (const auto& s : r.value("sweeps", json::array())) {
          sweeps += (sweeps.empty() ? "" : ",") + (s.is_string() ? s.get<std::string>() : s.dump());
        }
        row.push_back(sweeps.empty() ? "-" : sweeps);
      }
      t.rows.push_back(std::move(row));
      t.color.push_back({"", options.color ? StateColor(state) : ""});
    }
  }
  return RenderTable(t);
}

std::string RenderAggregatesTable(const json& aggregates, const RenderOptions&) {
  Table t;
  t.header = {"MODE", "A", "f", "Omega/omega", "AXIS", "U_z (m/s), mean ± se", "K", "EACH BED (m/s)", "NOTE"};
  t.align = {Align::kLeft,  Align::kRight, Align::kRight, Align::kRight, Align::kLeft,
             Align::kRight, Align::kRight, Align::kLeft,  Align::kLeft};
  constexpr size_t kAfterDrive = 5;  // the materials' columns follow AXIS
  const std::vector<const MaterialField*> materials = RowsMaterials(aggregates);
  AddMaterialColumns(t, materials, kAfterDrive);
  if (aggregates.is_array()) {
    for (const auto& a : aggregates) {
      std::string each;
      for (const auto& v : a.value("values", json::array())) {
        std::string cell = v.contains("uz") && Bool(v, "conclusive") ? NumCell(v, "uz", 3)
                           : v.contains("uz")                        ? "(" + NumCell(v, "uz", 1) + ")"
                                                                     : Str(v, "state", "-");
        each += (each.empty() ? "" : " ") + cell;
      }
      const std::string axis = Str(a, "axis");
      const std::string note = Str(a, "note");
      std::vector<std::string> row = {Str(a, "mode", "-"),
                                      NumCell(a, "A"),
                                      NumCell(a, "f"),
                                      OmegaCell(a),
                                      axis.empty() ? "-" : axis,
                                      Str(a, "uz_text", "-"),
                                      Str(a, "conclusive", "0") + "/" + Str(a, "replicates", "0"),
                                      each.empty() ? "-" : each,
                                      note.empty() ? "-" : note};
      const std::vector<std::string> cells = MaterialCells(a, materials);
      row.insert(row.begin() + kAfterDrive, cells.begin(), cells.end());
      t.rows.push_back(std::move(row));
      t.color.push_back({});
    }
  }
  return RenderTable(t);
}

std::string RenderResults(const json& reply, const RenderOptions& options) {
  std::string out = RenderResultsTable(reply.value("results", json::array()), options);
  const json aggregates = reply.value("aggregates", json::array());
  bool replicated = false;
  for (const auto& a : aggregates) replicated = replicated || a.value("replicates", 0) > 1;
  if (replicated) {
    out += "\nper point, over its replicate beds (K = conclusive/all; an inconclusive bed's value in brackets):\n";
    out += RenderAggregatesTable(aggregates, options);
  }
  return out;
}

std::string RenderResultsCsv(const json& rows) {
  std::vector<std::string> columns = ResultCsvColumns();
  std::vector<json> list;
  bool with_sweeps = false;
  if (rows.is_array()) {
    for (const auto& r : rows) {
      with_sweeps = with_sweeps || r.contains("sweeps");
      list.push_back(ResultCsvRow(r));
    }
  }
  if (with_sweeps) columns.push_back("sweeps");
  return RowsToCsv(list, columns);
}

namespace {

// `text` is what is shown ("holds at smoke"), coloured by `verdict`.
std::string VerdictCell(const std::string& verdict, const RenderOptions& options, const std::string& text = "") {
  const std::string code = verdict == "holds" ? "32" : verdict == "differs" ? "31" : "33";
  return Colorize(text.empty() ? verdict : text, code, options.color);
}

// A verdict's error rates at its design (core/claim_rates.h), and what would help when its power
// is low or it is not calibrated; nothing from a daemon that sends none.
std::string RatesLine(const std::string& lead, const json& verdict) {
  if (!verdict.contains("rates") || !verdict["rates"].is_object()) return "";
  const json& r = verdict["rates"];
  std::string out = lead + Str(r, "text") + "\n";
  if (!Str(r, "advice").empty()) out += std::string(lead.size(), ' ') + Str(r, "advice") + "\n";
  return out;
}

}  // namespace

std::string RenderClaims(const json& reply, const RenderOptions& options) {
  const json counts = reply.value("counts", json::object());
  std::string out = Str(reply, "campaign", "?") + " at " + Str(reply, "scale", "?") +
                    ", campaign run cr:" + Str(reply, "campaign_run_id", "?") + ": ";
  const json claims = reply.value("claims", json::array());
  if (claims.empty()) {
    out += "no claims";
    const std::string note = Str(reply, "note");
    return out + (note.empty() ? "" : " (" + note + ")") + "\n";
  }
  out += Str(counts, "holds", "0") + " hold, " + Str(counts, "differs", "0") + " differ, " +
         Str(counts, "inconclusive", "0") + " inconclusive\n";
  if (!Str(reply, "note").empty()) out += "(" + Str(reply, "note") + ")\n";
  for (const auto& c : claims) {
    out += "\n" + Str(c, "id", "?") + "  " +
           VerdictCell(Str(c, "verdict", "inconclusive"), options, Str(c, "verdict_text")) + "  " +
           Str(c, "title") + " (" + Str(c, "source") + ")\n";
    out += "    here:  " + Str(c, "reason") + "\n";
    out += RatesLine("    rates: ", c);
    for (const auto& p : c.value("parts", json::array())) {
      out += "      " + VerdictCell(Str(p, "verdict", "inconclusive"), options) + "  " + Str(p, "name") + ": " +
             Str(p, "reason") + "\n";
      out += RatesLine("             rates: ", p);
    }
    const json paper = c.value("paper", json::object());
    const std::string numbers = DescribePaperNumbers(paper);
    out += "    paper: " + Str(paper, "text", "-") + (numbers.empty() ? "" : " [" + numbers + "]") + "\n";
    const json missing = c.value("missing", json::array());
    if (!missing.empty()) {
      out += "    without a conclusive U_z (" + std::to_string(missing.size()) + "):\n";
      for (const auto& m : missing) {
        std::string runs;
        for (const auto& id : m.value("run_ids", json::array())) runs += (runs.empty() ? "run " : ", ") + id.dump();
        out += "      " + Str(m, "sweep") + " " + Str(m, "point") + (runs.empty() ? "" : " (" + runs + ")") + ": " +
               Str(m, "why") + "\n";
      }
    }
  }
  return out;
}

// ---- Campaigns --------------------------------------------------------------------------------

std::string FormatTimestamp(const json& epoch_s) {
  if (epoch_s.is_string()) return epoch_s.get<std::string>();
  if (!epoch_s.is_number() || !std::isfinite(epoch_s.get<double>())) return "-";
  const std::time_t t = static_cast<std::time_t>(std::floor(epoch_s.get<double>()));
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[32];
  std::strftime(text, sizeof text, "%Y-%m-%d %H:%M UTC", &tm);
  return text;
}

std::string FormatSchedule(const json& schedule) {
  if (schedule.is_string()) return schedule.get<std::string>();
  if (!schedule.is_object()) return "-";
  std::string out = Str(schedule, "cron", "?");
  if (!Str(schedule, "scale").empty()) out += " at " + Str(schedule, "scale");
  if (schedule.contains("next_due") && !schedule["next_due"].is_null()) {
    out += ", next due " + FormatTimestamp(schedule["next_due"]);
  }
  if (Str(schedule, "source") == "flag") out += " (from sandswimd --schedule)";
  return out;
}

std::string FormatPlannedRuns(const json& planned) {
  std::string out;
  if (!planned.is_object()) return out;
  for (const char* scale : {"smoke", "mini", "paper"}) {
    if (!planned.contains(scale)) continue;
    out += (out.empty() ? Str(planned, scale) + " runs" : ", " + Str(planned, scale)) + " at " + scale;
  }
  return out;
}

namespace {

// A campaign run in one cell: "cr:12 smoke, 2026-11-26 19:50 UTC, 57/58 done, 1 failed".
std::string CampaignRunCell(const json& run) {
  if (!run.is_object()) return "-";
  std::string out = "cr:" + Str(run, "id", "?");
  if (!Str(run, "scale").empty()) out += " " + Str(run, "scale");
  out += ", " + FormatTimestamp(run.value("created_at", json()));
  if (run.contains("counts")) {
    const Counts c = CountsFromJson(run["counts"]);
    out += ", " + std::to_string(c.done) + "/" + std::to_string(c.total()) + " done";
    if (c.failed > 0) out += ", " + std::to_string(c.failed) + " failed";
    if (!c.finished()) out += ", " + std::to_string(c.queued + c.running) + " to go";
  } else if (!Str(run, "status").empty()) {
    out += ", " + Str(run, "status");
  }
  return out;
}

// A schedule in a list's cell: "0 2 * * * at smoke" (when it is next due: `sandswim schedule`).
std::string ScheduleCell(const json& schedule) {
  if (schedule.is_string()) return schedule.get<std::string>();
  if (!schedule.is_object()) return "-";
  const std::string scale = Str(schedule, "scale");
  return Str(schedule, "cron", "?") + (scale.empty() ? "" : " at " + scale);
}

// "paper-58" or "paper-58 (version 2)": a built-in base has no version worth saying.
std::string ExtendsCell(const json& j) {
  const std::string base = Str(j, "extends");
  if (base.empty()) return "-";
  const int64_t version = Int(j, "extends_version");
  return version > 0 ? base + " (version " + std::to_string(version) + ")" : base;
}

}  // namespace

std::string RenderCampaignsTable(const json& campaigns) {
  Table t;
  t.header = {"NAME", "VERSION", "BUILT-IN", "EXTENDS", "SCHEDULE", "LAST RUN"};
  t.align = {Align::kLeft, Align::kRight, Align::kLeft, Align::kLeft, Align::kLeft, Align::kLeft};
  if (campaigns.is_array()) {
    for (const auto& c : campaigns) {
      const bool builtin = Bool(c, "builtin");
      const int64_t version = Int(c, "version");
      t.rows.push_back({Str(c, "name", "?"), version > 0 ? std::to_string(version) : "-", builtin ? "yes" : "no",
                        ExtendsCell(c), ScheduleCell(c.value("schedule", json())),
                        CampaignRunCell(c.value("last_run", json()))});
    }
  }
  return RenderTable(t);
}

std::string RenderCampaignDetail(const json& reply, bool resolved, const RenderOptions& options) {
  std::ostringstream out;
  const std::string name = Str(reply, "name", "?");
  const bool builtin = Bool(reply, "builtin");
  out << "campaign " << name;
  if (builtin) {
    out << " (built-in, read-only: `sandswim campaign edit " << name << "` starts your own copy)\n";
  } else {
    out << ", version " << Str(reply, "version", "?");
    const int64_t current = Int(reply, "current_version");
    if (current > 0 && current != Int(reply, "version")) out << " (the current one is " << current << ")";
    out << "\n";
  }
  if (!Str(reply, "extends").empty()) out << "  extends:   " << ExtendsCell(reply) << "\n";
  const std::string planned = FormatPlannedRuns(reply.value("planned_runs", json()));
  if (!planned.empty()) out << "  plans:     " << planned << "\n";
  const json schedule = reply.value("schedule", json());
  out << "  schedule:  "
      << (schedule.is_null() ? "none (sandswim schedule " + name + " \"0 2 * * *\" --scale smoke)"
                             : FormatSchedule(schedule))
      << "\n";
  for (const auto& note : reply.value("notes", json::array())) {
    out << "  note:      " << (note.is_string() ? note.get<std::string>() : note.dump()) << "\n";
  }
  const char* which = resolved ? "resolved" : "definition";
  out << "\n"
      << (resolved ? "resolved definition (what runs: the base's fields filled in)"
                   : "definition (as written; --resolved shows what runs)")
      << ":\n"
      << reply.value(which, json::object()).dump(2) << "\n";

  const json versions = reply.value("versions", json::array());
  if (!versions.empty()) {
    Table t;
    t.header = {"VERSION", "CREATED", "EXTENDS", "SHA-256"};
    t.align = {Align::kRight};
    for (const auto& v : versions) {
      t.rows.push_back({Str(v, "version", "?"), FormatTimestamp(v.value("created_at", json())), ExtendsCell(v),
                        Str(v, "definition_sha256", "-").substr(0, 12)});
    }
    out << "\nversions:\n" << RenderTable(t);
  }
  const json runs = reply.value("runs", json::array());
  if (runs.empty()) {
    out << "\nruns: none yet (sandswim campaign run " << name << " --scale smoke)\n";
  } else {
    Table t;
    t.header = {"RUN", "VERSION", "SCALE", "STATUS", "CREATED"};
    t.align = {Align::kLeft, Align::kRight};
    for (const auto& r : runs) {
      const std::string status = Str(r, "status", "-");
      t.rows.push_back({"cr:" + Str(r, "id", "?"), Str(r, "campaign_version", "-"), Str(r, "scale", "-"), status,
                        FormatTimestamp(r.value("created_at", json()))});
      t.color.push_back({"", "", "", options.color ? StateColor(status) : ""});
    }
    out << "\nruns:\n" << RenderTable(t);
  }
  return out.str();
}

std::string RenderCampaignStored(const json& reply) {
  std::ostringstream out;
  const std::string name = Str(reply, "name", "?");
  if (Bool(reply, "unchanged")) {
    out << name << ": unchanged, still version " << Str(reply, "version", "?") << "\n";
  } else {
    const bool created = reply.contains("created") ? Bool(reply, "created") : Int(reply, "version") == 1;
    out << name << ": stored as version " << Str(reply, "version", "?") << (created ? " (a new campaign)" : "") << "\n";
  }
  const std::string planned = FormatPlannedRuns(reply.value("planned_runs", json()));
  if (!planned.empty()) out << "  plans " << planned << "\n";
  for (const auto& note : reply.value("notes", json::array())) {
    out << "  note: " << (note.is_string() ? note.get<std::string>() : note.dump()) << "\n";
  }
  return out.str();
}

std::string RenderSchedulesTable(const json& campaigns) {
  Table t;
  t.header = {"CAMPAIGN", "CRON", "SCALE", "NEXT DUE", "SET BY"};
  if (campaigns.is_array()) {
    for (const auto& c : campaigns) {
      const json s = c.value("schedule", json());
      if (s.is_null()) continue;
      if (s.is_string()) {
        t.rows.push_back({Str(c, "name", "?"), s.get<std::string>(), "-", "-"});
        continue;
      }
      const std::string source = Str(s, "source");
      t.rows.push_back({Str(c, "name", "?"), Str(s, "cron", "?"), Str(s, "scale", "-"),
                        FormatTimestamp(s.value("next_due", json())),
                        source == "flag"  ? "sandswimd --schedule"
                        : source == "api" ? "sandswim schedule"
                                          : "-"});
    }
  }
  return RenderTable(t);
}

}  // namespace sandswim::cli
