// Format: how `sandswim` shows what the daemon answers. Pure functions from JSON values (the
// REST API's shapes, server/store/store.h and server/http/routes.cc) and plain structs to text: tables,
// CSV, progress bars, durations and the ETA. No I/O, no clock, no environment: the caller says
// whether colour is wanted (RenderOptions) and what time it is.
//
// Tables: a header row, then one row per item; columns are separated by two spaces, numbers are
// right-aligned, and no line has trailing blanks. Colour (ANSI SGR) only marks states and is
// added after padding, so columns line up with and without it.
//
// Numbers: %.4g for physical figures (U_z, Δz), %g for drive parameters; CSV cells use the
// shortest form that reads back to the same double (as the daemon's own CSV does).
//
// Thread safety: pure functions over values.
#ifndef SANDSWIM_CLI_FORMAT_H_
#define SANDSWIM_CLI_FORMAT_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/result_table.h"  // CsvCell, ResultColumns: the daemon's CSV
#include "core/status.h"

namespace sandswim::cli {

struct RenderOptions {
  bool color = false;  // ANSI colours for states (decided by the caller: TTY, NO_COLOR)
};

// An error as the CLI prints it after "sandswim: ": "FIELD: reason", or the reason alone.
std::string Describe(const Status& status);

// ---- Building blocks ---------------------------------------------------------------------------

enum class Align { kLeft, kRight };

struct Table {
  std::vector<std::string> header;
  std::vector<Align> align;  // per column; missing columns are kLeft
  std::vector<std::vector<std::string>> rows;
  std::vector<std::vector<std::string>> color;  // optional SGR code per cell ("31"), same shape
};

// Width of `text` on a terminal: UTF-8 code points (so "Δz" is 2 wide).
size_t DisplayWidth(const std::string& text);
std::string RenderTable(const Table& table);

// `text` wrapped in the SGR `code` ("1;31") when color is on.
std::string Colorize(const std::string& text, const std::string& code, bool color);
// The SGR code for a run state: done green, failed red, running yellow, cancelled dim.
std::string StateColor(const std::string& state);

// A number for people to read: %g with up to `precision` significant digits ("0.03", "-80",
// "1.235e-05"). (Decks use core/deck.h FormatNumber, the shortest text that reads back exactly.)
std::string DisplayNumber(double v, int precision = 6);
// "45s", "3m20s", "1h02m", "2d03h"; negative or non-finite: "?".
std::string FormatDuration(double seconds);
// "[#########...........]  45%" with `width` cells between the brackets; fraction clamped to
// [0, 1]. Partial cells are not drawn: the bar shows floor(fraction * width) '#'.
std::string ProgressBar(double fraction, int width = 20);

// ---- Domain values -----------------------------------------------------------------------------

struct Counts {
  int64_t queued = 0, running = 0, done = 0, failed = 0, cancelled = 0;
  int64_t total() const { return queued + running + done + failed + cancelled; }
  bool finished() const { return queued == 0 && running == 0; }
  bool operator==(const Counts& o) const {
    return queued == o.queued && running == o.running && done == o.done && failed == o.failed &&
           cancelled == o.cancelled;
  }
};
// From {"queued":..,"running":..,...} (missing keys count 0).
Counts CountsFromJson(const nlohmann::json& j);
// "2 queued, 1 running, 5 done, 0 failed, 0 cancelled"
std::string FormatCounts(const Counts& c, const RenderOptions& options = {});

// A point (PointToJson's shape, or a flat result row) in one line:
// "oscillatory A=0.03 f=3 Omega=-80 T=0.3s", "rotation omega=20 axis=z T=4s".
std::string FormatPoint(const nlohmann::json& point);

// ---- What `status` and `watch` show --------------------------------------------------------------

struct RunInFlight {
  int64_t id = 0;
  std::string point;      // FormatPoint()
  double sim_time_s = 0;  // simulated so far
  double duration_s = 0;  // the run's duration at its scale
  double so_z = 0;        // m
  std::string worker;
  double fraction() const;  // sim_time_s / duration_s in [0, 1]
};

struct RunFailure {
  int64_t id = 0;
  std::string point;
  std::string reason;  // "kind: message"
};

// One look at a sweep or a campaign run (built by snapshot.h from the daemon's answers).
struct Snapshot {
  std::string title;  // "sweep 3 omega-sign (scale smoke)"
  Counts counts;
  std::vector<RunInFlight> running;
  std::vector<RunFailure> failed;
  // The daemon's ETA (server/store/cost_model.h: the work left at the measured engine rates), with its
  // relative 1-sigma error, the band the daemon gives (low_s..high_s, s/e^r..s*e^r: 0 when it gives
  // none) and what it rests on; absent from a daemon older than the cost model.
  struct DaemonEta {
    double s = 0, rel_error = 0;
    std::string basis;
    double low_s = 0, high_s = 0;
    // The band to show: the daemon's, or s/e^r..s*e^r from rel_error when it sent none (an older
    // daemon); nullopt when it has no error to give.
    struct Band {
      double low_s, high_s;
    };
    std::optional<Band> band() const;
  };
  std::optional<DaemonEta> eta;
  // When runs are queued and none runs: the state of the bed they wait for ("queued",
  // "running", "done", "failed"), so the ETA line can say the bed is being prepared.
  std::string waiting_bed_state;
  // A campaign run in rounds (GET /api/v1/campaign-runs/{id} "adaptive" and "rounds"; null and []
  // otherwise): status prints a few lines a round.
  nlohmann::json adaptive;
  nlohmann::json rounds = nlohmann::json::array();
  // The ETA while work is moving: runs in flight, or the bed they wait for being prepared. When
  // nothing moves (no worker) there is no time to give, whatever the daemon estimates.
  std::optional<double> eta_s() const;
};

// The full `status` text: title, counts, runs in flight (bar, simulated time / duration, SO z),
// failures with their reasons, ETA.
std::string RenderStatus(const Snapshot& s, const RenderOptions& options);
// "failed:" and two lines a failed run (its id and point, then its reason); "" for none. The end
// of RenderStatus, and what `watch` prints when its target ends with failures.
std::string RenderFailures(const std::vector<RunFailure>& failed, const RenderOptions& options);
// The rounds of an adaptive campaign run, a few lines each: "round 2  finished  planned 0.48 core-h,
// spent 0.31, 12.4 core-h left" / each action's reason / "  after it: F1 holds (round 1), F4
// inconclusive", and the stop reason. "" for none.
std::string RenderRounds(const nlohmann::json& adaptive, const nlohmann::json& rounds);
// A `watch` frame on a terminal: title, counts + ETA, one progress line per running run.
std::string RenderWatchFrame(const Snapshot& s, const RenderOptions& options);
// {"title","counts":{...},"running":[{"id","point","sim_time_s","duration_s","so_z","worker"}],
//  "failed":[{"id","point","reason"}],"eta_s": number|null,"eta_rel_error"?,"eta_low_s"?,"eta_high_s"?,"eta_basis"?,"finished": bool}
nlohmann::json SnapshotToJson(const Snapshot& s);
// The one line `watch` prints when piped: "sweep 3 ...: 5/8 done, 1 running, 2 queued, 0 failed,
// 0 cancelled; ETA 3m20s".
std::string RenderWatchLine(const Snapshot& s);

// ---- Lists and results ---------------------------------------------------------------------------

// GET /api/v1/sweeps "sweeps" array -> ID NAME SCALE RUNS QUEUED RUNNING DONE FAILED CANCELLED.
std::string RenderSweepsTable(const nlohmann::json& sweeps, const RenderOptions& options);
// GET /api/v1/runs "runs" array -> ID STATE POINT PROGRESS U_z WORKER.
std::string RenderRunsTable(const nlohmann::json& runs, const RenderOptions& options);
// GET /api/v1/runs/{id} -> a multi-line description with deck and log tail.
std::string RenderRunDetail(const nlohmann::json& run, const RenderOptions& options);

// Results rows (the flat rows of GET .../results): one row per run.
// Table columns: RUN STATE MODE A f Omega/omega AXIS DURATION U_z (m/s) Δz (m) FLAGS [SWEEPS].
std::string RenderResultsTable(const nlohmann::json& rows, const RenderOptions& options);
// One row per point over its replicate beds (core/aggregate.h): U_z mean ± standard error, the
// between-bed sd, K (conclusive of all), each bed's U_z and what the aggregate rests on.
std::string RenderAggregatesTable(const nlohmann::json& aggregates, const RenderOptions& options);
// A results reply ({"results", "aggregates"}): the runs' table, then, when some point ran on more
// than one bed, the aggregates' table under a heading.
std::string RenderResults(const nlohmann::json& reply, const RenderOptions& options);
// The daemon's CSV of the same rows, byte for byte (core/result_table.h: ResultColumns(), plus
// "sweeps" when any row has them).
std::string RenderResultsCsv(const nlohmann::json& rows);

// GET /campaign-runs/{id}/claims (server/analysis/claim_check.h) as text: a summary line, then each claim
// as a block: its id, verdict (coloured: holds green, differs red, inconclusive yellow), title and
// source; what was measured here, part by part; what the paper reports; the points it needed
// that have no conclusive U_z, and why.
std::string RenderClaims(const nlohmann::json& reply, const RenderOptions& options);
// "surface", "floor", "surface,floor" or "" from a row's broke_surface / near_floor.
std::string ResultFlags(const nlohmann::json& row);

// ---- Campaigns (GET /api/v1/campaigns, GET/PUT /api/v1/campaigns/{name}) -------------------------

// Seconds since the Unix epoch as "2026-11-26 19:42 UTC"; a string is shown as it is; else "-".
std::string FormatTimestamp(const nlohmann::json& epoch_s);
// A schedule {cron, scale, next_due, source} (or a bare cron string) as "0 2 * * * at smoke, next
// due 2026-11-27 02:00 UTC", plus " (from sandswimd --schedule)" for a flag's; null: "-".
std::string FormatSchedule(const nlohmann::json& schedule);
// planned_runs {smoke, mini, paper} as "58 runs at smoke, 58 at mini, 58 at paper"; none: "".
std::string FormatPlannedRuns(const nlohmann::json& planned);
// GET /api/v1/campaigns "campaigns" -> NAME VERSION BUILT-IN EXTENDS SCHEDULE LAST RUN. An entry's
// "last_run" (a CampaignRun of GET /api/v1/campaign-runs, added by the caller) fills LAST RUN.
std::string RenderCampaignsTable(const nlohmann::json& campaigns);
// GET /api/v1/campaigns/{name}: name, version, what it extends, its plan at each scale, schedule
// and notes; the definition as written (or, `resolved`, what runs); its versions; its runs.
std::string RenderCampaignDetail(const nlohmann::json& reply, bool resolved, const RenderOptions& options);
// PUT /api/v1/campaigns/{name}'s answer: the version stored (or "unchanged"), the plan, the notes.
std::string RenderCampaignStored(const nlohmann::json& reply);
// The scheduled campaigns of GET /api/v1/campaigns -> CAMPAIGN CRON SCALE NEXT DUE SET BY (its
// "source": "flag" is sandswimd --schedule, "api" is sandswim schedule or the dashboard).
std::string RenderSchedulesTable(const nlohmann::json& campaigns);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_FORMAT_H_
