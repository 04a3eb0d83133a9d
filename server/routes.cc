#include "server/routes.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <utility>

#include <httplib.h>
#include <openssl/crypto.h>
#include <spdlog/spdlog.h>

#include "core/aggregate.h"
#include "core/result_table.h"
#include "core/snapshot.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "platform/http_status.h"
#include "server/store/campaigns.h"
#include "server/store/cost_model.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/drift_report.h"
#include "server/dashboard/dashboard_files.h"
#include "server/analysis/figures.h"
#include "server/guarded_http_server.h"
#include "server/dashboard/live_feed.h"
#include "server/analysis/report.h"
#include "server/store/schema_files.h"
#include "server/jobs/submission.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

// A body bigger than its route's limit is still read (and thrown away) up to this many bytes, so
// the client gets its 413 instead of a connection reset; past it the connection is closed.
constexpr size_t kDrainCapBytes = size_t{64} << 20;
constexpr const char* kProblemType = "application/problem+json";

std::string HttpTitle(int http_status) {
  static const std::map<int, const char*> kTitles = {{200, "OK"},
                                                     {201, "Created"},
                                                     {204, "No Content"},
                                                     {400, "Bad Request"},
                                                     {401, "Unauthorized"},
                                                     {403, "Forbidden"},
                                                     {404, "Not Found"},
                                                     {405, "Method Not Allowed"},
                                                     {409, "Conflict"},
                                                     {411, "Length Required"},
                                                     {413, "Content Too Large"},
                                                     {415, "Unsupported Media Type"},
                                                     {416, "Range Not Satisfiable"},
                                                     {421, "Misdirected Request"},
                                                     {422, "Unprocessable Content"},
                                                     {429, "Too Many Requests"},
                                                     {500, "Internal Server Error"},
                                                     {503, "Service Unavailable"}};
  auto it = kTitles.find(http_status);
  return it != kTitles.end() ? it->second : "HTTP " + std::to_string(http_status);
}

// Counts every answered request by status code, for /metrics; and the failed token attempts
// (server/request_policy.h), which it also shows.
struct HttpCounters {
  std::mutex mu;
  std::map<int, uint64_t> by_status;
  std::unique_ptr<FailedAuthThrottle> auth_failures;
  void Count(int status) {
    std::lock_guard<std::mutex> lock(mu);
    ++by_status[status == -1 ? 200 : status];
  }
};

// ---- One request in flight ---------------------------------------------------------------------

struct Call {
  const httplib::Request& req;
  httplib::Response& res;
  Deps& deps;
  std::string body;                                // BodyKind::kJson, at most max_json_body
  const httplib::ContentReader* reader = nullptr;  // BodyKind::kRestart, not yet read
  HttpCounters* counters = nullptr;
};

void SendJson(Call& c, int http_status, const json& body) {
  c.res.status = http_status;
  c.res.set_content(api::ToJsonText(body), "application/json");
}

// A 5xx says what failed but not where: file paths stay in the log.
void SendProblem(httplib::Response& res, const Status& status, int http_status = 0) {
  if (http_status == 0) http_status = HttpStatusFor(status.code());
  res.status = http_status;
  const Status told = http_status >= 500 ? Status(status.code(), RedactPaths(status.reason()), status.field()) : status;
  res.set_content(api::ToJsonText(ProblemFor(told, http_status)), kProblemType);
  if (http_status == 503 && !res.has_header("Retry-After")) res.set_header("Retry-After", "10");
  if (http_status >= 500) {
    spdlog::error(
        "HTTP {}: {} (check the daemon's --db and --data paths and disk space; "
        "the request can be retried)",
        http_status, status.ToString());
  }
}

void Fail(Call& c, const Status& status, int http_status = 0) { SendProblem(c.res, status, http_status); }

// Parses a JSON body; a syntax error names the byte where parsing stopped.
Result<json> ParseJsonBody(const std::string& body, bool allow_empty) {
  if (body.empty()) {
    if (allow_empty) return json::object();
    return Status::InvalidArgument("body", "a JSON body is required");
  }
  try {
    return json::parse(body);
  } catch (const json::parse_error& e) {
    return Status::InvalidArgument("body", "malformed JSON at byte " + std::to_string(e.byte) + ": " + e.what());
  } catch (const json::exception& e) {  // e.g. a number too large for a double (1e999)
    return Status::InvalidArgument("body", std::string("unreadable JSON: ") + e.what());
  }
}

// Converts a worker message with its nlohmann conversions; a wrong type names the message.
template <typename T>
Result<T> ParseMessage(const std::string& body, const char* what, bool allow_empty) {
  auto j = ParseJsonBody(body, allow_empty);
  if (!j.ok()) return j.status();
  if (!j->is_object()) return Status::InvalidArgument("body", std::string(what) + " must be a JSON object");
  try {
    return j->template get<T>();
  } catch (const json::exception& e) {
    return Status::InvalidArgument("body", std::string("not a valid ") + what + ": " + e.what());
  }
}

Result<int64_t> ParseInt(const std::string& text, const std::string& field, int64_t min, int64_t max) {
  int64_t v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) {
    return Status::InvalidArgument(field, "must be an integer, got \"" + text + "\"");
  }
  if (v < min || v > max) {
    return Status::InvalidArgument(
        field, "must be in [" + std::to_string(min) + ", " + std::to_string(max) + "], got " + text);
  }
  return v;
}

Result<int64_t> PathId(const Call& c, size_t index = 1) {
  return ParseInt(c.req.matches[index].str(), "id", 1, INT64_MAX);
}

std::string PathToken(const Call& c) { return c.req.matches[1].str(); }

// Optional integer query parameter.
Result<std::optional<int64_t>> QueryInt(const Call& c, const std::string& name, int64_t min, int64_t max) {
  if (!c.req.has_param(name.c_str())) return std::optional<int64_t>();
  auto v = ParseInt(c.req.get_param_value(name.c_str()), name, min, max);
  if (!v.ok()) return v.status();
  return std::optional<int64_t>(*v);
}

struct PageArgs {
  int64_t after_id = 0;
  int limit = 100;
};

Result<PageArgs> ParsePage(const Call& c) {
  PageArgs page;
  auto cursor = QueryInt(c, "cursor", 0, INT64_MAX);
  if (!cursor.ok()) return cursor.status();
  auto limit = QueryInt(c, "limit", 1, 1000);
  if (!limit.ok()) return limit.status();
  if (*cursor) page.after_id = **cursor;
  if (*limit) page.limit = static_cast<int>(**limit);
  return page;
}

// Cursors are opaque strings to clients (today: the last id of the page).
void CursorToString(json& page) {
  auto it = page.find("next_cursor");
  if (it != page.end() && it->is_number_integer()) *it = std::to_string(it->get<int64_t>());
}

bool WantsCsv(const Call& c) {
  if (c.req.has_param("format")) return c.req.get_param_value("format") == "csv";
  return c.req.get_header_value("Accept").find("text/csv") != std::string::npos;
}

// ---- Result rows (JSON objects and CSV rows share the columns) ---------------------------------

json ResultRowJson(const ResultRow& row) {
  json j = json::object();
  for (const auto& col : ResultColumns()) j[col] = nullptr;
  j["run_id"] = row.run_id;
  j["key"] = row.key;
  j["state"] = row.state;
  const json point = PointToJson(row.point);
  for (auto it = point.begin(); it != point.end(); ++it) j[it.key()] = it.value();
  j["run_duration_s"] = row.run_duration_s;
  j["replicate"] = row.replicate;
  j["bed_id"] = row.bed_id;
  if (row.result) {
    const api::RunResult& r = row.result->result;
    j["Uz_text"] = DescribeUz(r, false);
    if (r.uz) j["Uz"] = *r.uz;
    if (r.uz_stderr) j["Uz_stderr"] = *r.uz_stderr;
    if (r.uz_ci95) j["Uz_ci95"] = *r.uz_ci95;
    j["Uz_blocks"] = r.uz_blocks;
    j["block_s"] = r.block_s;
    j["block_kind"] = r.block_kind;
    j["window_t0"] = r.window_t0;
    j["window_t1"] = r.window_t1;
    j["window_end"] = r.window_end;
    j["conclusive"] = r.conclusive;
    j["inconclusive_reason"] = r.inconclusive_reason;
    j["trending"] = r.trending;
    if (r.trend_p) j["trend_p"] = *r.trend_p;
    if (r.trend_slope) j["trend_slope"] = *r.trend_slope;
    if (r.trend_slope_se) j["trend_slope_se"] = *r.trend_slope_se;
    j["trend_note"] = r.trend_note;
    j["dz"] = r.dz;
    j["dz_rate"] = r.dz_rate;
    j["analysis"] = r.analysis;
    j["analysed_from"] = r.analysed_from;
    j["z_osc_amplitude"] = r.z_osc_amplitude;
    if (r.x_osc_amplitude) j["x_osc_amplitude"] = *r.x_osc_amplitude;
    j["x_drift"] = r.x_drift;
    j["broke_surface"] = r.broke_surface;
    j["near_floor"] = r.near_floor;
    j["stop_reason"] = r.stop_reason;
    j["stop_note"] = r.stop_note;
    j["precision_met"] = r.precision_met ? json(*r.precision_met) : json(nullptr);
    j["sim_time_s"] = r.sim_time_s;
    j["grains"] = r.grains;
    j["engine_version"] = row.result->execution.engine_version;
  }
  return j;
}

// The per-point aggregates over replicate beds (core/aggregate.h) of these runs, each with its
// point's fields.
json AggregatesJson(const std::vector<ResultRow>& rows) {
  std::vector<std::pair<Point, ReplicateValue>> runs;
  runs.reserve(rows.size());
  for (const ResultRow& row : rows) {
    ReplicateValue v;
    v.run_id = row.run_id;
    v.replicate = row.replicate;
    v.bed_id = row.bed_id;
    v.state = row.state;
    if (row.state == "done" && row.result) {  // a requeued run's old result is not averaged
      const api::RunResult& r = row.result->result;
      v.conclusive = r.conclusive;
      v.uz = r.uz;
      v.uz_stderr = r.uz_stderr;
      v.uz_ci95 = r.uz_ci95;
    }
    runs.emplace_back(row.point, v);
  }
  json out = json::array();
  for (const PointAggregate& a : AggregateByPoint(runs)) {
    json j = PointToJson(a.point);
    j.erase("duration_s");
    j.update(AggregateToJson(a.aggregate));
    out.push_back(std::move(j));
  }
  return out;
}

// `?format=csv`: the runs, one a line (core/result_table.h); JSON: {"id", "results", "aggregates"}.
void SendRows(Call& c, int64_t id, const std::vector<json>& rows, const std::vector<ResultRow>& distinct,
              bool with_sweeps) {
  if (WantsCsv(c)) {
    std::vector<std::string> columns = ResultColumns();
    if (with_sweeps) columns.push_back("sweeps");
    c.res.status = 200;
    c.res.set_content(RowsToCsv(rows, columns), "text/csv; charset=utf-8");
    return;
  }
  SendJson(c, 200, {{"id", id}, {"results", rows}, {"aggregates", AggregatesJson(distinct)}});
}

// A campaign run's distinct runs, each naming the sweeps it belongs to (`distinct`: the same runs,
// as read).
Result<std::vector<json>> CampaignRunRows(Store& store, const CampaignRunInfo& info,
                                          std::vector<ResultRow>* distinct = nullptr) {
  std::vector<json> rows;
  std::map<int64_t, size_t> index_of_run;
  for (int64_t sweep_id : info.sweep_ids) {
    auto sweep = store.GetSweep(sweep_id);
    if (!sweep.ok()) return sweep.status();
    auto results = store.SweepResults(sweep_id);
    if (!results.ok()) return results.status();
    for (const ResultRow& row : *results) {
      auto [it, inserted] = index_of_run.emplace(row.run_id, rows.size());
      if (inserted) {
        rows.push_back(ResultRowJson(row));
        rows.back()["sweeps"] = json::array();
        if (distinct) distinct->push_back(row);
      }
      rows[it->second]["sweeps"].push_back(sweep->name);
    }
  }
  return rows;
}

// ---- Handlers: parse -> call -> render ---------------------------------------------------------

void SubmitSweeps(Call& c) {
  auto body = ParseJsonBody(c.body, /*allow_empty=*/false);
  if (!body.ok()) return Fail(c, body.status());
  auto request = ParseSubmitRequest(*body);
  if (!request.ok()) return Fail(c, request.status());
  if (c.req.has_header("Idempotency-Key")) request->idempotency_key = c.req.get_header_value("Idempotency-Key");
  request->max_queued_runs = c.deps.max_queued_runs;
  auto result = Submit(*c.deps.store, *request, c.deps.engine_version, c.deps.clock->Now());
  if (!result.ok()) {
    if (result.status().code() == StatusCode::kUnavailable) c.res.set_header("Retry-After", "60");  // the queue cap
    return Fail(c, result.status());
  }
  json reply = *result;
  std::string location;
  if (result->campaign_run_id) {
    reply["id"] = *result->campaign_run_id;
    reply["campaign"] = *request->campaign;
    reply["sweeps"] = result->sweep_ids;
    location = "/api/v1/campaign-runs/" + std::to_string(*result->campaign_run_id);
  } else {
    location = "/api/v1/sweeps/" + std::to_string(result->sweep_ids.at(0));
  }
  c.res.set_header("Location", location);
  SendJson(c, 201, reply);
}

void ListSweeps(Call& c) {
  auto page = ParsePage(c);
  if (!page.ok()) return Fail(c, page.status());
  auto sweeps = c.deps.store->ListSweeps(page->after_id, page->limit);
  if (!sweeps.ok()) return Fail(c, sweeps.status());
  json reply = *sweeps;
  CursorToString(reply);
  SendJson(c, 200, reply);
}

void GetSweep(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto sweep = c.deps.store->GetSweep(*id);
  if (!sweep.ok()) return Fail(c, sweep.status());
  auto eta = ReadEta(*c.deps.store, EtaScope::kSweep, *id, c.deps.clock->Now(), c.deps.engine_slots);
  if (!eta.ok()) return Fail(c, eta.status());
  json reply = *sweep;
  reply["eta"] = EtaJson(*eta);
  SendJson(c, 200, reply);
}

void GetSweepResults(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto results = c.deps.store->SweepResults(*id);
  if (!results.ok()) return Fail(c, results.status());
  std::vector<json> rows;
  rows.reserve(results->size());
  for (const ResultRow& row : *results) rows.push_back(ResultRowJson(row));
  SendRows(c, *id, rows, *results, /*with_sweeps=*/false);
}

void CancelSweep(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto summary = c.deps.leases->Cancel(*id);
  if (!summary.ok()) return Fail(c, summary.status());
  auto sweep = c.deps.store->GetSweep(*id);
  if (!sweep.ok()) return Fail(c, sweep.status());
  json reply = *sweep;
  reply["cancel"] = *summary;
  SendJson(c, 200, reply);
}

void ListRuns(Call& c) {
  RunFilter filter;
  auto page = ParsePage(c);
  if (!page.ok()) return Fail(c, page.status());
  filter.after_id = page->after_id;
  filter.limit = page->limit;
  auto sweep = QueryInt(c, "sweep", 1, INT64_MAX);
  if (!sweep.ok()) return Fail(c, sweep.status());
  filter.sweep_id = *sweep;
  if (c.req.has_param("state")) filter.state = c.req.get_param_value("state");
  auto runs = c.deps.store->ListRuns(filter);
  if (!runs.ok()) return Fail(c, runs.status());
  json reply = *runs;
  CursorToString(reply);
  SendJson(c, 200, reply);
}

void GetRun(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto run = c.deps.store->GetRun(*id);
  if (!run.ok()) return Fail(c, run.status());
  SendJson(c, 200, *run);
}

void ListBeds(Call& c) {
  auto beds = c.deps.store->ListBeds();
  if (!beds.ok()) return Fail(c, beds.status());
  SendJson(c, 200, {{"beds", *beds}});
}

void GetBed(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto bed = c.deps.store->GetBed(*id);
  if (!bed.ok()) return Fail(c, bed.status());
  SendJson(c, 200, *bed);
}

json CampaignJson(const Campaign& campaign, bool builtin, bool stored) {
  json sweeps = json::array();
  for (const SweepSpec& s : campaign.sweeps) sweeps.push_back(s.name);
  return {{"name", campaign.name},
          {"description", campaign.description},
          {"scale", campaign.scale},
          {"builtin", builtin},
          {"stored", stored},
          {"sweeps", sweeps},
          {"schedule", campaign.schedule ? json(*campaign.schedule) : json(nullptr)},
          {"drift_tolerance_mps", campaign.drift_tolerance_mps}};
}

// Stored campaigns (a stored definition overrides the builtin one of its name), then the
// builtin campaigns nobody has stored.
void ListCampaigns(Call& c) {
  json campaigns = json::array();
  std::set<std::string> listed;
  const std::vector<std::string> builtin_names = BuiltinCampaignNames();
  auto is_builtin = [&](const std::string& name) {
    return std::find(builtin_names.begin(), builtin_names.end(), name) != builtin_names.end();
  };
  auto stored = c.deps.store->ListCampaigns();
  if (!stored.ok()) return Fail(c, stored.status());
  for (const StoredCampaign& s : *stored) {
    auto campaign = ParseCampaign(s.definition);
    if (!campaign.ok()) {
      return Fail(
          c, Status::Corruption("stored campaign '" + s.name + "' no longer parses: " + campaign.status().ToString()));
    }
    campaign->name = s.name;
    campaign->schedule = s.schedule;
    campaign->drift_tolerance_mps = s.drift_tolerance_mps;
    campaigns.push_back(CampaignJson(*campaign, is_builtin(s.name), /*stored=*/true));
    listed.insert(s.name);
  }
  for (const std::string& name : builtin_names) {
    if (listed.count(name)) continue;
    auto campaign = BuiltinCampaign(name);
    if (!campaign.ok()) return Fail(c, campaign.status());
    campaigns.push_back(CampaignJson(*campaign, /*builtin=*/true, /*stored=*/false));
  }
  SendJson(c, 200, {{"campaigns", campaigns}});
}

void GetCampaignRun(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto info = c.deps.store->GetCampaignRun(*id);
  if (!info.ok()) return Fail(c, info.status());
  auto drift = LastDriftFor(*c.deps.store, *info);
  if (!drift.ok()) return Fail(c, drift.status());
  auto eta = ReadEta(*c.deps.store, EtaScope::kCampaignRun, *id, c.deps.clock->Now(), c.deps.engine_slots);
  if (!eta.ok()) return Fail(c, eta.status());
  json reply = *info;
  reply["last_drift"] = drift->has_value() ? json(**drift) : json(nullptr);
  reply["eta"] = EtaJson(*eta);
  SendJson(c, 200, reply);
}

// The engine rates measured so far (server/store/cost_model.h): what `sandswim expand --cost` uses.
void GetCostModel(Call& c) {
  auto model = ReadCostModel(*c.deps.store, c.deps.clock->Now());
  if (!model.ok()) return Fail(c, model.status());
  json reply = *model;
  reply["engine_slots"] = c.deps.engine_slots;
  SendJson(c, 200, reply);
}

// The latest drift report of a campaign (?scale= narrows it to one scale).
void GetCampaignDrift(Call& c) {
  const std::string name = c.req.matches[1].str();
  const std::string scale = c.req.has_param("scale") ? c.req.get_param_value("scale") : "";
  if (c.req.has_param("scale") && FindScale(scale) == nullptr) {
    return Fail(c, Status::InvalidArgument("scale", "unknown scale \"" + scale + "\" (paper, mini, smoke)"));
  }
  auto report = LatestDriftReport(*c.deps.store, name, scale);
  if (!report.ok()) return Fail(c, report.status());
  if (!report->has_value()) {
    if (auto found = FindCampaign(*c.deps.store, name); !found.ok()) return Fail(c, found.status());
    return Fail(c, Status::NotFound("no drift report for campaign '" + name + "'" +
                                    (scale.empty() ? "" : " at scale " + scale) +
                                    " yet: one is made when a rerun of it finishes"));
  }
  SendJson(c, 200, **report);
}

void GetCampaignRunResults(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto info = c.deps.store->GetCampaignRun(*id);
  if (!info.ok()) return Fail(c, info.status());
  std::vector<ResultRow> distinct;
  auto rows = CampaignRunRows(*c.deps.store, *info, &distinct);
  if (!rows.ok()) return Fail(c, rows.status());
  SendRows(c, *id, *rows, distinct, /*with_sweeps=*/true);
}

// The verdict of each of the campaign's claims for this run (server/analysis/claim_check.h).
void GetCampaignRunClaims(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto claims = CheckClaims(*c.deps.store, *id);
  if (!claims.ok()) return Fail(c, claims.status());
  SendJson(c, 200, CampaignRunClaimsToJson(*claims));
}

// ---- Figures, fits and reports (server/analysis/figures.h, server/analysis/report.h) ----------------------------

// Figures live next to the results, keyed by their data (FigureCache): never stale.
FigureCache FiguresOf(const Deps& deps) {
  return FigureCache((std::filesystem::path(deps.data_dir) / "figures").string(), deps.renderer);
}

// The HTML report and SVG figures are documents of their own, made by the daemon: inline styles
// (the report's <style>, PLplot's style attributes) and inline images, but no script at all.
constexpr const char* kDocumentCsp =
    "default-src 'none'; style-src 'unsafe-inline'; img-src 'self' data:; frame-ancestors 'none'";

void SendFigure(Call& c, const std::string& name, const Plot& plot, ImageFormat format) {
  auto bytes = FiguresOf(c.deps).Get(name, plot, format);
  if (!bytes.ok()) return Fail(c, bytes.status());
  c.res.status = 200;
  c.res.set_header("Content-Security-Policy", kDocumentCsp);
  c.res.set_content(*bytes, ImageContentType(format));
}

template <ImageFormat kFormat>
void GetRunFigure(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto plot = RunFigure(*c.deps.store, *id);
  if (!plot.ok()) return Fail(c, plot.status());
  SendFigure(c, RunFigureName(*id), *plot, kFormat);
}

Result<SweepAnalysis> FinishedSweep(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return id.status();
  auto analysis = AnalyzeSweep(*c.deps.store, *id);
  if (!analysis.ok()) return analysis.status();
  if (analysis->samples.empty()) {
    return Status::FailedPrecondition("id",
                                      "sweep " + std::to_string(*id) + " has no finished run yet: nothing to plot");
  }
  return analysis;
}

template <ImageFormat kFormat>
void GetSweepTrajectoriesFigure(Call& c) {
  auto a = FinishedSweep(c);
  if (!a.ok()) return Fail(c, a.status());
  if (a->runs.empty())
    return Fail(c, Status::FailedPrecondition("id", "no finished run of this sweep has a trajectory"));
  // ?branch=rising|sinking: the runs of one branch (the paper's panels a and b).
  const std::string branch = c.req.has_param("branch") ? c.req.get_param_value("branch") : "";
  if (c.req.has_param("branch") && branch != "rising" && branch != "sinking")
    return Fail(c, Status::InvalidArgument("branch", "must be rising (Omega < 0) or sinking (Omega > 0)"));
  Plot plot = SweepTrajectoriesFigure(*a, branch);
  if (plot.series.empty()) {
    return Fail(c, Status::FailedPrecondition("branch", "no finished run of the " + branch + " branch of sweep " +
                                                            std::to_string(a->info.id) + " has a trajectory"));
  }
  SendFigure(c, SweepTrajectoriesName(a->info.id, branch), plot, kFormat);
}

// The drive modes side by side (the paper's Fig. 2): ?coordinate=z (default) or x.
template <ImageFormat kFormat>
void GetCampaignRunModesFigure(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  const std::string coordinate = c.req.has_param("coordinate") ? c.req.get_param_value("coordinate") : "z";
  if (coordinate != "x" && coordinate != "z")
    return Fail(c, Status::InvalidArgument("coordinate", "must be x or z (the SO's displacement drawn against t)"));
  auto cr = c.deps.store->GetCampaignRun(*id);
  if (!cr.ok()) return Fail(c, cr.status());
  auto analyses = AnalyzeCampaignRun(*c.deps.store, *cr);
  if (!analyses.ok()) return Fail(c, analyses.status());
  std::optional<Plot> modes = ModesFigure(*cr, *analyses, coordinate == "x" ? Coordinate::kX : Coordinate::kZ);
  if (!modes) {
    return Fail(c, Status::FailedPrecondition("id", "campaign run " + std::to_string(*id) +
                                                        " has no finished run of a drive other than the oscillatory "
                                                        "one (vibration, rotation or both) yet"));
  }
  SendFigure(c, ModesFigureName(*id, coordinate == "x" ? Coordinate::kX : Coordinate::kZ), *modes, kFormat);
}

template <ImageFormat kFormat>
void GetSweepUzFigure(Call& c) {
  auto a = FinishedSweep(c);
  if (!a.ok()) return Fail(c, a.status());
  if (std::string why = NoUzToPlot(*a); !why.empty()) {
    return Fail(c, Status::FailedPrecondition("id", "sweep " + std::to_string(a->info.id) + ": " + why));
  }
  SendFigure(c, SweepUzName(a->info.id), SweepUzFigure(*a), kFormat);
}

void GetSweepFits(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto a = AnalyzeSweep(*c.deps.store, *id);
  if (!a.ok()) return Fail(c, a.status());
  json reply = a->fits;
  reply["sweep_id"] = *id;
  reply["finished_runs"] = a->samples.size();
  SendJson(c, 200, reply);
}

void SendReport(Call& c, int64_t campaign_run_id) {
  FigureCache figures = FiguresOf(c.deps);
  auto html = CampaignReport(*c.deps.store, figures, campaign_run_id, c.deps.clock->Now(), c.deps.data_dir);
  if (!html.ok()) return Fail(c, html.status());
  c.res.status = 200;
  c.res.set_header("Content-Security-Policy", kDocumentCsp);
  c.res.set_content(*html, "text/html; charset=utf-8");
}

void GetCampaignRunReport(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  SendReport(c, *id);
}

// The report of a campaign's latest run (?scale= narrows it to one scale).
void GetCampaignReport(Call& c) {
  const std::string name = c.req.matches[1].str();
  const std::string scale = c.req.has_param("scale") ? c.req.get_param_value("scale") : "";
  if (c.req.has_param("scale") && FindScale(scale) == nullptr) {
    return Fail(c, Status::InvalidArgument("scale", "unknown scale \"" + scale + "\" (paper, mini, smoke)"));
  }
  auto runs = c.deps.store->ListCampaignRuns(name, 1000);
  if (!runs.ok()) return Fail(c, runs.status());
  for (const CampaignRunInfo& run : *runs) {
    if (scale.empty() || run.scale == scale) return SendReport(c, run.id);
  }
  return Fail(c, Status::NotFound("no run of campaign '" + name + "'" + (scale.empty() ? "" : " at scale " + scale) +
                                  " yet: submit it first (sandswim submit " + name + ")"));
}

void LeaseJob(Call& c) {
  auto request = ParseMessage<api::LeaseRequest>(c.body, "LeaseRequest", /*allow_empty=*/true);
  if (!request.ok()) return Fail(c, request.status());
  if (Status s = api::LimitLengths(*request); !s.ok()) return Fail(c, s);
  auto grant = c.deps.leases->Lease(*request);
  if (!grant.ok()) return Fail(c, grant.status());
  if (!*grant) {
    c.res.status = 204;
    return;
  }
  SendJson(c, 200, {{"lease", **grant}});
}

void HeartbeatLease(Call& c) {
  auto beat = ParseMessage<api::Heartbeat>(c.body, "Heartbeat", /*allow_empty=*/true);
  if (!beat.ok()) return Fail(c, beat.status());
  auto reply = c.deps.leases->Heartbeat(PathToken(c), *beat);
  if (!reply.ok()) return Fail(c, reply.status());
  SendJson(c, 200, *reply);
}

void CompleteLease(Call& c) {
  auto completion = ParseMessage<api::Completion>(c.body, "Completion", /*allow_empty=*/false);
  if (!completion.ok()) return Fail(c, completion.status());
  if (Status s = api::LimitLengths(*completion); !s.ok()) return Fail(c, s);
  auto reply = c.deps.leases->Complete(PathToken(c), *completion);
  if (!reply.ok()) return Fail(c, reply.status());
  SendJson(c, 200, *reply);
}

void ReleaseLease(Call& c) {
  auto request = ParseMessage<api::ReleaseRequest>(c.body, "ReleaseRequest", /*allow_empty=*/true);
  if (!request.ok()) return Fail(c, request.status());
  if (Status s = api::LimitLengths(*request); !s.ok()) return Fail(c, s);
  auto reply = c.deps.leases->Release(PathToken(c), request->reason);
  if (!reply.ok()) return Fail(c, reply.status());
  SendJson(c, 200, *reply);
}

// A file mapped read-only, so a restart of any size reaches PutBedRestart without a copy in memory.
class MappedFile {
 public:
  ~MappedFile() {
    if (data_ != nullptr) munmap(data_, size_);
    if (fd_ >= 0) close(fd_);
  }
  Status Open(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) return Status::IOError("cannot open " + path);
    struct stat st {};
    if (fstat(fd_, &st) != 0) return Status::IOError("cannot stat " + path);
    size_ = static_cast<size_t>(st.st_size);
    if (size_ == 0) return Status::Ok();
    void* p = mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (p == MAP_FAILED) return Status::IOError("cannot map " + path);
    data_ = p;
    return Status::Ok();
  }
  std::string_view view() const {
    return data_ == nullptr ? std::string_view() : std::string_view(static_cast<const char*>(data_), size_);
  }

 private:
  int fd_ = -1;
  void* data_ = nullptr;
  size_t size_ = 0;
};

// A request body received into a temporary file under DATA/uploads, mapped read-only, and
// removed when this goes: an upload of any size reaches its store without a copy in memory.
struct Upload {
  std::filesystem::path temp;
  MappedFile mapped;
  ~Upload() {
    std::error_code ignored;
    if (!temp.empty()) std::filesystem::remove(temp, ignored);
  }
};

// Receives the body into `upload` (at most max_restart_body bytes: 413 past it). False when it
// answered the request with a problem instead. Called once the lease is checked: a body is read
// only for a lease that may upload it (a refusal before it ends the connection; the server then
// drains what the client still sends for a moment, so that the answer reaches it, not a reset).
bool ReceiveUpload(Call& c, const std::string& name, const std::string& what, Upload& upload) {
  static std::atomic<uint64_t> upload_counter{0};
  std::filesystem::path dir = UploadDir(c.deps.data_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    Fail(c, Status::IOError("cannot create " + dir.string() + ": " + ec.message()));
    return false;
  }
  upload.temp = dir / (name + "-" + std::to_string(getpid()) + "-" + std::to_string(upload_counter.fetch_add(1)) +
                       ".part");
  std::ofstream out(upload.temp, std::ios::binary | std::ios::trunc);
  if (!out) {
    Fail(c, Status::IOError("cannot write " + upload.temp.string()));
    return false;
  }
  size_t received = 0;
  bool too_big = false;
  (*c.reader)([&](const char* data, size_t n) {
    received += n;
    if (received > c.deps.max_restart_body) {
      too_big = true;
      return false;
    }
    out.write(data, static_cast<std::streamsize>(n));
    return static_cast<bool>(out);
  });
  out.close();
  if (too_big) {
    c.res.set_header("Connection", "close");
    Fail(c,
         Status::ResourceExhausted("body", what + " may be at most " + std::to_string(c.deps.max_restart_body) + " bytes"),
         413);
    return false;
  }
  if (!out) {
    const int err = errno;
    Fail(c, err == ENOSPC ? Status::Unavailable("cannot write " + upload.temp.string() +
                                                ": the disk that holds --data is full; free space on it and send "
                                                "it again (nothing was kept)")
                          : Status::IOError("cannot write " + upload.temp.string() + ": " + std::strerror(err)));
    return false;
  }
  Status s = upload.mapped.Open(upload.temp.string());
  if (!s.ok()) {
    Fail(c, s);
    return false;
  }
  return true;
}

// An upload refused before its body is read: the rest of the body is not read either, so the
// connection ends with the answer.
void RefuseUpload(Call& c, const Status& why) {
  c.res.set_header("Connection", "close");
  Fail(c, why);
}

void UploadBedRestart(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return RefuseUpload(c, id.status());
  std::string token = c.req.get_param_value("token");
  std::string sha256 = c.req.get_header_value("X-Sha256");
  if (token.empty()) return RefuseUpload(c, Status::InvalidArgument("token", "the query parameter token= is required"));
  if (sha256.empty()) return RefuseUpload(c, Status::InvalidArgument("X-Sha256", "the header X-Sha256 is required"));
  // The lease, and that it is this bed's, before a byte of the body reaches the disk.
  if (Status held = c.deps.leases->CheckUploadLease(token, api::JobKind::kBed, *id); !held.ok()) {
    return RefuseUpload(c, held);
  }
  Upload upload;
  if (!ReceiveUpload(c, "bed-" + std::to_string(*id), "a bed restart", upload)) return;
  Status s = c.deps.leases->PutBedRestart(token, upload.mapped.view(), sha256, c.deps.data_dir);
  if (!s.ok()) return Fail(c, s);
  SendJson(c, 200, {{"bed_id", *id}, {"sha256", sha256}, {"bytes", upload.mapped.view().size()}});
}

// A full-bed snapshot of a running run, handed in before the completion that lists it.
void UploadRunSnapshot(Call& c) {
  auto n = ParseInt(c.req.matches[2].str(), "n", 0, 1000);
  if (!n.ok()) return RefuseUpload(c, n.status());
  std::string sha256 = c.req.get_header_value("X-Sha256");
  if (sha256.empty()) return RefuseUpload(c, Status::InvalidArgument("X-Sha256", "the header X-Sha256 is required"));
  if (Status held = c.deps.leases->CheckUploadLease(PathToken(c), api::JobKind::kRun); !held.ok()) {
    return RefuseUpload(c, held);
  }
  Upload upload;
  if (!ReceiveUpload(c, "snapshot", "a snapshot", upload)) return;
  Status s = c.deps.leases->PutRunSnapshot(PathToken(c), static_cast<int>(*n), upload.mapped.view(), sha256);
  if (!s.ok()) return Fail(c, s);
  SendJson(c, 200, {{"n", *n}, {"sha256", sha256}, {"bytes", upload.mapped.view().size()}});
}

// Streams `size` bytes of an open file as the reply's body, a megabyte at a time.
void SendFile(Call& c, std::shared_ptr<std::ifstream> file, size_t size, const char* content_type) {
  c.res.set_content_provider(size, content_type, [file](size_t offset, size_t length, httplib::DataSink& sink) {
    std::vector<char> buffer(std::min<size_t>(length, size_t{1} << 20));
    file->seekg(static_cast<std::streamoff>(offset));
    file->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    std::streamsize got = file->gcount();
    if (got <= 0) return false;
    return sink.write(buffer.data(), static_cast<size_t>(got));
  });
}

void DownloadBedRestart(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto bed = c.deps.leases->GetBedRestart(*id);
  if (!bed.ok()) return Fail(c, bed.status());
  auto file = std::make_shared<std::ifstream>(bed->path, std::ios::binary);
  std::error_code ec;
  auto size = std::filesystem::file_size(bed->path, ec);
  if (!*file || ec) {
    return Fail(c, Status::IOError("bed " + std::to_string(*id) + "'s restart file " + bed->path +
                                   " is missing; the bed must be prepared again"));
  }
  c.res.status = 200;
  c.res.set_header("X-Sha256", bed->sha256);
  SendFile(c, file, static_cast<size_t>(size), "application/octet-stream");
}

// ---- Snapshots of the bed (core/snapshot.h; the paper's Fig. 5) --------------------------------

struct FoundSnapshot {
  int64_t run_id = 0;
  Point point;
  api::Snapshot meta;
  std::string path;
};

// The run's snapshot named by the path ({id}, {n}); NotFound saying which it has.
Result<FoundSnapshot> FindSnapshot(const Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return id.status();
  auto n = ParseInt(c.req.matches[2].str(), "n", 0, 1000);
  if (!n.ok()) return n.status();
  auto run = c.deps.store->GetRun(*id);
  if (!run.ok()) return run.status();
  const std::vector<api::Snapshot>& snapshots = run->snapshots;
  for (const api::Snapshot& s : snapshots) {
    if (s.idx == *n) return FoundSnapshot{*id, run->summary.point, s, SnapshotPath(c.deps.data_dir, *id, s.idx)};
  }
  return Status::NotFound("run " + std::to_string(*id) + " has no snapshot " + std::to_string(*n) + " (it has " +
                          std::to_string(snapshots.size()) +
                          "; a run takes snapshots when its sweep asks for them: \"snapshots\": [0, 0.5, 1])");
}

// The snapshot as the engine wrote it (dump custom: id type x y z vx vy vz radius).
void GetSnapshotDump(Call& c) {
  auto found = FindSnapshot(c);
  if (!found.ok()) return Fail(c, found.status());
  auto file = std::make_shared<std::ifstream>(found->path, std::ios::binary);
  std::error_code ec;
  auto size = std::filesystem::file_size(found->path, ec);
  if (!*file || ec) return Fail(c, Status::IOError("snapshot file " + found->path + " is missing"));
  c.res.status = 200;
  c.res.set_header("Content-Disposition", "attachment; filename=\"run-" + std::to_string(found->run_id) +
                                              "-snapshot-" + std::to_string(found->meta.idx) + ".dump\"");
  SendFile(c, file, static_cast<size_t>(size), "text/plain; charset=utf-8");
}

// The snapshot as a legacy VTK file, which ParaView opens directly.
void GetSnapshotVtk(Call& c) {
  auto found = FindSnapshot(c);
  if (!found.ok()) return Fail(c, found.status());
  auto snapshot = ReadStoredSnapshot(c.deps.data_dir, found->run_id, found->meta.idx);
  if (!snapshot.ok()) return Fail(c, snapshot.status());
  const std::string title = "sandswim run " + std::to_string(found->run_id) + " snapshot " +
                            std::to_string(found->meta.idx) + " t = " + Num(found->meta.t_s, 4) + " s";
  c.res.status = 200;
  c.res.set_header("Content-Disposition", "attachment; filename=\"run-" + std::to_string(found->run_id) +
                                              "-snapshot-" + std::to_string(found->meta.idx) + ".vtk\"");
  c.res.set_content(BedSnapshotVtk(*snapshot, title), "application/octet-stream");
}

// The y-z slice through the SO (server/analysis/figures.h SnapshotSlicePlot).
template <ImageFormat kFormat>
void GetSnapshotSlice(Call& c) {
  auto found = FindSnapshot(c);
  if (!found.ok()) return Fail(c, found.status());
  auto snapshot = ReadStoredSnapshot(c.deps.data_dir, found->run_id, found->meta.idx);
  if (!snapshot.ok()) return Fail(c, snapshot.status());
  const Plot plot = SnapshotSlicePlot(found->run_id, found->point, found->meta, SliceThroughSo(*snapshot));
  SendFigure(c, "run-" + std::to_string(found->run_id) + "-snapshot-" + std::to_string(found->meta.idx) + "-slice",
             plot, kFormat);
}

// A consistent copy of the database, made while the daemon serves (Database::BackupTo) under
// DATA/backups/ and streamed; the file is removed once sent. A POST: it writes a file and costs a
// whole copy, which no link or image of another page may start.
void PostBackup(Call& c) {
  const std::string dir = BackupDir(c.deps.data_dir);
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return Fail(c, Status::IOError("cannot create " + dir + ": " + ec.message()));
  static std::atomic<int64_t> serial{0};
  const std::string path = dir + "/backup-" + std::to_string(static_cast<int64_t>(c.deps.clock->Now())) + "-" +
                           std::to_string(++serial) + ".db";
  Result<int64_t> bytes = c.deps.store->db().BackupTo(path);
  if (!bytes.ok()) return Fail(c, bytes.status());
  auto file = std::make_shared<std::ifstream>(path, std::ios::binary);
  if (!*file) return Fail(c, Status::IOError("the backup " + path + " vanished before it was sent"));
  std::filesystem::remove(path, ec);  // the open stream keeps the data until it is sent
  c.res.status = 200;
  c.res.set_header("X-Schema-Version", std::to_string(c.deps.store->db().schema_version()));
  c.res.set_header("Content-Disposition", "attachment; filename=\"sandswim-backup.db\"");
  SendFile(c, file, static_cast<size_t>(*bytes), "application/vnd.sqlite3");
}

}  // namespace

std::string BackupDir(const std::string& data_dir) { return data_dir + "/backups"; }

std::string UploadDir(const std::string& data_dir) { return data_dir + "/uploads"; }

Result<int> ClearScratchDirs(const std::string& data_dir) {
  int removed = 0;
  for (const std::string& dir : {BackupDir(data_dir), UploadDir(data_dir)}) {
    std::error_code ec;
    if (!std::filesystem::exists(dir, ec)) continue;
    for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
      std::filesystem::remove_all(entry.path(), ec);
      if (ec) return Status::IOError("cannot remove the stale " + entry.path().string() + ": " + ec.message());
      ++removed;
    }
    if (ec) return Status::IOError("cannot list " + dir + ": " + ec.message());
  }
  return removed;
}

namespace {

// ---- Handlers: the dashboard's live feed (server/dashboard/live_feed.h) -------------------------------

// A stream says it is alive at least this often: proxies close silent connections, and a write is
// how the server learns that the page went away, so a closed stream frees its slot within ~2 s.
constexpr double kLiveKeepAliveS = 2;

LiveFeed* NeedLiveFeed(Call& c) {
  if (c.deps.live == nullptr) Fail(c, Status::Unavailable("this daemon serves no live feed"));
  return c.deps.live;
}

void GetLive(Call& c) {
  LiveFeed* feed = NeedLiveFeed(c);
  if (feed == nullptr) return;
  auto snap = feed->Current();
  const std::string etag = "\"live-" + std::to_string(snap->version) + "\"";
  c.res.set_header("ETag", etag);
  c.res.set_header("Cache-Control", "no-cache");
  if (c.req.get_header_value("If-None-Match") == etag) {
    c.res.status = 304;
    return;
  }
  c.res.status = 200;
  c.res.set_content(snap->json, "application/json");
}

// Server-sent events: "event: board" with the snapshot as data, at each new version; a comment
// line every kLiveKeepAliveS otherwise. At most LiveFeed's max_streams at once, and its
// max_streams_per_client from one peer address (503 past them).
void GetLiveEvents(Call& c) {
  LiveFeed* feed = NeedLiveFeed(c);
  if (feed == nullptr) return;
  const std::string client = c.req.remote_addr;
  if (!feed->OpenStream(client)) {  // expected under many pages: answered without the error log of a 5xx
    c.res.set_header("Retry-After", "10");
    c.res.status = 503;
    c.res.set_content(api::ToJsonText(ProblemFor(
                          Status::Unavailable("every live stream this daemon allows (in all, or to this client) is "
                                              "open: poll GET /api/v1/live"),
                          503)),
                      kProblemType);
    return;
  }
  auto last = std::make_shared<uint64_t>(0);
  c.res.set_header("Cache-Control", "no-store");
  c.res.set_chunked_content_provider(
      "text/event-stream",
      [feed, last](size_t, httplib::DataSink& sink) {
        auto snap = feed->WaitNewer(*last, kLiveKeepAliveS);
        if (feed->stopped()) {
          sink.done();
          return true;
        }
        std::string message;
        if (snap->version > *last) {
          *last = snap->version;
          message = "id: " + std::to_string(snap->version) + "\nevent: board\ndata: " + snap->json + "\n\n";
        } else {
          message = ": alive\n\n";
        }
        return sink.write(message.data(), message.size());  // false: the page went away
      },
      [feed, client](bool) { feed->CloseStream(client); });
}

// The run's z(t) so far, from its heartbeats while it runs (empty once it is not running: its
// stored trajectory is GET /api/v1/runs/{id}'s).
void GetRunTrail(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  LiveFeed* feed = NeedLiveFeed(c);
  if (feed == nullptr) return;
  LiveFeed::Trail trail = feed->TrailOf(*id);
  SendJson(c, 200, {{"run_id", *id}, {"t", trail.t}, {"z", trail.z}});
}

void ListCampaignRunsRoute(Call& c) {
  const std::string campaign = c.req.has_param("campaign") ? c.req.get_param_value("campaign") : "";
  auto limit = QueryInt(c, "limit", 1, 1000);
  if (!limit.ok()) return Fail(c, limit.status());
  auto runs = c.deps.store->ListCampaignRuns(campaign, static_cast<int>(limit->value_or(50)));
  if (!runs.ok()) return Fail(c, runs.status());
  SendJson(c, 200, {{"campaign_runs", *runs}});
}

void OpenApi(Call& c) {
  auto doc = SchemaFile("schema/openapi.json");
  if (!doc) return Fail(c, Status::Internal("schema/openapi.json was not compiled in; rebuild sandswimd"));
  c.res.status = 200;
  c.res.set_content(std::string(*doc), "application/json");
}

void Healthz(Call& c) {
  Status s = c.deps.store->db().HealthCheck();
  if (!s.ok()) return Fail(c, Status::Unavailable("store: " + s.ToString()));
  SendJson(c, 200,
           {{"status", "ok"},
            {"engine_version", c.deps.engine_version},
            {"schema_version", c.deps.store->db().schema_version()}});
}

std::string MetricsText(const Metrics& m, HttpCounters& http) {
  std::ostringstream out;
  auto gauge_by_state = [&out](const char* name, const char* help, const RunCounts& c) {
    out << "# HELP " << name << " " << help << "\n# TYPE " << name << " gauge\n";
    const std::pair<const char*, int64_t> states[] = {{"queued", c.queued},
                                                      {"running", c.running},
                                                      {"done", c.done},
                                                      {"failed", c.failed},
                                                      {"cancelled", c.cancelled}};
    for (const auto& [state, n] : states) out << name << "{state=\"" << state << "\"} " << n << "\n";
  };
  auto counter = [&out](const char* name, const char* help, int64_t v) {
    out << "# HELP " << name << " " << help << "\n# TYPE " << name << " counter\n" << name << " " << v << "\n";
  };
  gauge_by_state("sandswim_runs", "Runs by state.", m.runs);
  gauge_by_state("sandswim_beds", "Beds by state.", m.beds);
  out << "# HELP sandswim_sweeps Sweeps submitted.\n# TYPE sandswim_sweeps gauge\nsandswim_sweeps " << m.sweeps << "\n";
  counter("sandswim_leases_granted_total", "Leases granted to workers.", m.leases_granted);
  counter("sandswim_completions_total", "Completions accepted.", m.completions);
  counter("sandswim_lease_expirations_total", "Leases that ran out.", m.expirations);
  counter("sandswim_pilots_gone_total", "Leases reclaimed early because Slurm no longer ran their job.", m.pilots_gone);
  counter("sandswim_duplicate_completions_total", "Repeated completions answered duplicate.", m.duplicates);
  if (http.auth_failures) {
    const FailedAuthThrottle::Counts auth = http.auth_failures->counts();
    counter("sandswim_auth_failures_total", "Requests refused for a wrong token.", auth.failures);
    counter("sandswim_auth_delayed_total", "Wrong-token requests answered after a delay.", auth.delayed);
    out << "# HELP sandswim_auth_delay_seconds_total Seconds wrong-token requests were held.\n"
           "# TYPE sandswim_auth_delay_seconds_total counter\nsandswim_auth_delay_seconds_total "
        << auth.delay_s_total << "\n";
    counter("sandswim_auth_busy_total", "Wrong-token requests answered 429 at once (no free delay slot).", auth.busy);
  }
  out << "# HELP sandswim_http_requests_total HTTP requests answered, by status code.\n"
         "# TYPE sandswim_http_requests_total counter\n";
  std::lock_guard<std::mutex> lock(http.mu);
  for (const auto& [code, n] : http.by_status) {
    out << "sandswim_http_requests_total{code=\"" << code << "\"} " << n << "\n";
  }
  return out.str();
}

void GetMetrics(Call& c) {
  auto metrics = c.deps.store->GetMetrics();
  if (!metrics.ok()) return Fail(c, metrics.status());
  c.res.status = 200;
  c.res.set_content(MetricsText(*metrics, *c.counters), "text/plain; version=0.0.4");
}

// ---- The route table ---------------------------------------------------------------------------

using Handler = void (*)(Call&);

struct Route {
  const char* method;
  const char* path;
  Access access;
  BodyKind body;
  Handler handler;
};

// clang-format off
// clang-format off: one route a line, in columns, read top to bottom.
const Route kRoutes[] = {
  // method  path                                   access            body                handler
  {"POST", "/api/v1/sweeps",                        Access::kWrite,  BodyKind::kJson,    SubmitSweeps},
  {"GET",  "/api/v1/sweeps",                        Access::kRead,   BodyKind::kNone,    ListSweeps},
  {"GET",  "/api/v1/sweeps/{id}",                   Access::kRead,   BodyKind::kNone,    GetSweep},
  {"GET",  "/api/v1/sweeps/{id}/results",           Access::kRead,   BodyKind::kNone,    GetSweepResults},
  {"POST", "/api/v1/sweeps/{id}/cancel",            Access::kWrite,  BodyKind::kJson,    CancelSweep},
  {"GET",  "/api/v1/runs",                          Access::kRead,   BodyKind::kNone,    ListRuns},
  {"GET",  "/api/v1/runs/{id}",                     Access::kRead,   BodyKind::kNone,    GetRun},
  {"GET",  "/api/v1/beds",                          Access::kRead,   BodyKind::kNone,    ListBeds},
  {"GET",  "/api/v1/beds/{id}",                     Access::kRead,   BodyKind::kNone,    GetBed},
  {"GET",  "/api/v1/campaigns",                     Access::kRead,   BodyKind::kNone,    ListCampaigns},
  {"GET",  "/api/v1/campaigns/{name}/drift",        Access::kRead,   BodyKind::kNone,    GetCampaignDrift},
  {"GET",  "/api/v1/campaign-runs",                 Access::kRead,   BodyKind::kNone,    ListCampaignRunsRoute},
  {"GET",  "/api/v1/campaign-runs/{id}",            Access::kRead,   BodyKind::kNone,    GetCampaignRun},
  {"GET",  "/api/v1/campaign-runs/{id}/results",    Access::kRead,   BodyKind::kNone,    GetCampaignRunResults},
  {"GET",  "/api/v1/campaign-runs/{id}/claims",     Access::kRead,   BodyKind::kNone,    GetCampaignRunClaims},
  // Figures (SVG or PNG by extension), fits and reports (server/analysis/report.h).
  {"GET",  "/api/v1/runs/{id}/snapshots/{n}.dump",  Access::kRead,   BodyKind::kNone,    GetSnapshotDump},
  {"GET",  "/api/v1/runs/{id}/snapshots/{n}.vtk",   Access::kRead,   BodyKind::kNone,    GetSnapshotVtk},
  {"GET",  "/api/v1/runs/{id}/snapshots/{n}/slice.svg", Access::kRead, BodyKind::kNone,  GetSnapshotSlice<ImageFormat::kSvg>},
  {"GET",  "/api/v1/runs/{id}/snapshots/{n}/slice.png", Access::kRead, BodyKind::kNone,  GetSnapshotSlice<ImageFormat::kPng>},
  {"GET",  "/api/v1/runs/{id}/trajectory.svg",      Access::kRead,   BodyKind::kNone,    GetRunFigure<ImageFormat::kSvg>},
  {"GET",  "/api/v1/runs/{id}/trajectory.png",      Access::kRead,   BodyKind::kNone,    GetRunFigure<ImageFormat::kPng>},
  {"GET",  "/api/v1/sweeps/{id}/trajectories.svg",  Access::kRead,   BodyKind::kNone,    GetSweepTrajectoriesFigure<ImageFormat::kSvg>},
  {"GET",  "/api/v1/sweeps/{id}/trajectories.png",  Access::kRead,   BodyKind::kNone,    GetSweepTrajectoriesFigure<ImageFormat::kPng>},
  {"GET",  "/api/v1/sweeps/{id}/uz.svg",            Access::kRead,   BodyKind::kNone,    GetSweepUzFigure<ImageFormat::kSvg>},
  {"GET",  "/api/v1/sweeps/{id}/uz.png",            Access::kRead,   BodyKind::kNone,    GetSweepUzFigure<ImageFormat::kPng>},
  {"GET",  "/api/v1/sweeps/{id}/fits",              Access::kRead,   BodyKind::kNone,    GetSweepFits},
  {"GET",  "/api/v1/campaign-runs/{id}/modes.svg",  Access::kRead,   BodyKind::kNone,    GetCampaignRunModesFigure<ImageFormat::kSvg>},
  {"GET",  "/api/v1/campaign-runs/{id}/modes.png",  Access::kRead,   BodyKind::kNone,    GetCampaignRunModesFigure<ImageFormat::kPng>},
  {"GET",  "/api/v1/campaign-runs/{id}/report",     Access::kRead,   BodyKind::kNone,    GetCampaignRunReport},
  {"GET",  "/api/v1/campaigns/{name}/report",       Access::kRead,   BodyKind::kNone,    GetCampaignReport},
  {"POST", "/api/v1/backup",                        Access::kWrite,  BodyKind::kJson,    PostBackup},
  {"GET",  "/api/v1/live",                          Access::kRead,   BodyKind::kNone,    GetLive},
  {"GET",  "/api/v1/live/events",                   Access::kRead,   BodyKind::kNone,    GetLiveEvents},
  {"GET",  "/api/v1/runs/{id}/trail",               Access::kRead,   BodyKind::kNone,    GetRunTrail},
  // The worker protocol (core/api.h), in the order a worker uses it.
  {"POST", "/api/v1/leases",                        Access::kWorker, BodyKind::kJson,    LeaseJob},
  {"GET",  "/api/v1/beds/{id}/restart",             Access::kWorker, BodyKind::kNone,    DownloadBedRestart},
  {"POST", "/api/v1/leases/{token}/heartbeat",      Access::kWorker, BodyKind::kJson,    HeartbeatLease},
  {"PUT",  "/api/v1/beds/{id}/restart",             Access::kWorker, BodyKind::kRestart, UploadBedRestart},
  {"PUT",  "/api/v1/leases/{token}/snapshots/{n}",  Access::kWorker, BodyKind::kRestart, UploadRunSnapshot},
  {"POST", "/api/v1/leases/{token}/complete",       Access::kWorker, BodyKind::kJson,    CompleteLease},
  {"POST", "/api/v1/leases/{token}/release",        Access::kWorker, BodyKind::kJson,    ReleaseLease},
  // Operations.
  {"GET",  "/api/v1/openapi.json",                  Access::kPublic, BodyKind::kNone,    OpenApi},
  {"GET",  "/healthz",                              Access::kPublic, BodyKind::kNone,    Healthz},
  {"GET",  "/metrics",                              Access::kRead,   BodyKind::kNone,    GetMetrics},
  {"GET",  "/api/v1/cost-model",                    Access::kRead,   BodyKind::kNone,    GetCostModel},
};
// clang-format on
// clang-format on

// "/api/v1/sweeps/{id}" -> "/api/v1/sweeps/(\d+)"; tokens are what LeaseQueue mints (hex).
std::string PathRegex(const std::string& path) {
  static const std::regex kId(R"(\{id\})"), kToken(R"(\{token\})"), kName(R"(\{name\})"), kN(R"(\{n\})");
  std::string r = std::regex_replace(path, kId, R"(([0-9]+))");
  r = std::regex_replace(r, kN, R"(([0-9]+))");
  r = std::regex_replace(r, kToken, R"(([A-Za-z0-9_-]+))");
  r = std::regex_replace(r, kName, R"(([A-Za-z0-9._-]+))");
  return std::regex_replace(r, std::regex(R"(\.)"), R"(\.)");
}

struct CompiledRoute {
  const Route* route;
  std::regex pattern;
};

const std::vector<CompiledRoute>& CompiledRoutes() {
  static const std::vector<CompiledRoute> kCompiled = [] {
    std::vector<CompiledRoute> v;
    for (const Route& r : kRoutes) v.push_back({&r, std::regex(PathRegex(r.path))});
    return v;
  }();
  return kCompiled;
}

const Route* FindRoute(const std::string& method, const std::string& path) {
  for (const CompiledRoute& cr : CompiledRoutes()) {
    if (method == cr.route->method && std::regex_match(path, cr.pattern)) return cr.route;
  }
  return nullptr;
}

// Why a request may not reach its route, and with which HTTP status.
struct Refusal {
  Status status;
  int http_status = 0;
};

// The token the request carries: the Authorization header's bearer token, else, for a read, the
// access_token query parameter (the dashboard's images and links, which cannot send a header).
std::optional<std::string> GivenToken(const Route& route, const httplib::Request& req) {
  const std::string header = req.get_header_value("Authorization");
  const std::string prefix = "Bearer ";
  if (header.rfind(prefix, 0) == 0) return header.substr(prefix.size());
  if (route.access == Access::kRead && req.has_param("access_token")) return req.get_param_value("access_token");
  return std::nullopt;
}

std::optional<Refusal> CheckAuth(const Deps& deps, const Route& route, const httplib::Request& req,
                                 FailedAuthThrottle& throttle) {
  if (deps.token.empty() || route.access == Access::kPublic) return std::nullopt;
  if (route.access == Access::kRead && deps.public_reads) return std::nullopt;
  std::optional<std::string> given = GivenToken(route, req);
  if (!given) {
    return Refusal{Status(StatusCode::kUnauthenticated,
                          "this daemon has a token: send \"Authorization: Bearer <token>\" (sandswimd printed "
                          "the dashboard's link with it when it started; the CLI and local workers read its "
                          "token file)",
                          "Authorization"),
                   401};
  }
  if (given->size() == deps.token.size() && CRYPTO_memcmp(given->data(), deps.token.data(), given->size()) == 0) {
    return std::nullopt;
  }
  if (throttle.Failed(ClientKey(req.remote_addr), req.method + " " + req.path) == FailedAuthThrottle::Verdict::kBusy) {
    return Refusal{
        Status(StatusCode::kResourceExhausted,
               "too many requests with a wrong token from " + req.remote_addr + "; try again later", "Authorization"),
        429};
  }
  return Refusal{Status(StatusCode::kUnauthenticated, "the bearer token is not the daemon's token", "Authorization"),
                 401};
}

// Empty when the request may reach its route; otherwise why not (server/request_policy.h).
std::optional<Refusal> CheckRequest(const Deps& deps, const Route& route, const httplib::Request& req,
                                    FailedAuthThrottle& throttle) {
  if (std::string_view(route.method) != "GET") {
    if (auto cross = CrossSiteRefusal(deps.host_policy, req.get_header_value("Origin"),
                                      req.get_header_value("Sec-Fetch-Site"))) {
      spdlog::warn("refused {} {} from {}: {}", req.method, req.path, req.remote_addr, cross->reason());
      return Refusal{*cross, 403};
    }
    if (route.body == BodyKind::kJson && !IsJsonMediaType(req.get_header_value("Content-Type"))) {
      return Refusal{Status::InvalidArgument("Content-Type", "this route takes only application/json, not \"" +
                                                                 req.get_header_value("Content-Type") + "\""),
                     415};
    }
  }
  return CheckAuth(deps, route, req, throttle);
}

// Reads a JSON body up to `limit` bytes; past it, reads on (discarding) up to the drain cap.
// Returns false when the body was too large.
bool ReadBody(const httplib::ContentReader& reader, size_t limit, std::string& body, bool& drained) {
  size_t received = 0;
  bool too_big = false;
  drained = true;
  reader([&](const char* data, size_t n) {
    received += n;
    if (received > limit) too_big = true;
    if (!too_big) body.append(data, n);
    if (received > kDrainCapBytes) {
      drained = false;
      return false;
    }
    return true;
  });
  return !too_big;
}

void Dispatch(const Route& route, Deps& deps, HttpCounters* counters, const httplib::Request& req,
              httplib::Response& res, const httplib::ContentReader* reader) {
  Call c{req, res, deps, {}, nullptr, counters};
  std::optional<Refusal> denied = CheckRequest(deps, route, req, *counters->auth_failures);
  if (denied && denied->http_status == 429) res.set_header("Retry-After", "1");
  if (denied) {
    // Not a byte of a refused body is read on a request thread (a client sending it a byte a
    // minute would hold the thread for hours): the answer goes at once, and the server drains what
    // the client still sends for a moment before closing (server/guarded_http_server.cc).
    if (reader != nullptr) res.set_header("Connection", "close");
    return SendProblem(res, denied->status, denied->http_status);
  }
  if (reader != nullptr && route.body == BodyKind::kJson) {
    bool drained = true;
    bool fits = ReadBody(*reader, deps.max_json_body, c.body, drained);
    if (!drained) res.set_header("Connection", "close");
    if (!fits) {
      return SendProblem(res,
                         Status::ResourceExhausted(
                             "body", "a JSON body may be at most " + std::to_string(deps.max_json_body) + " bytes"),
                         413);
    }
  }
  if (route.body == BodyKind::kRestart) c.reader = reader;
  route.handler(c);
}

// Dispatch, counted for /metrics.
void DispatchCounted(const Route& route, Deps& deps, HttpCounters* counters, const httplib::Request& req,
                     httplib::Response& res, const httplib::ContentReader* reader) {
  Dispatch(route, deps, counters, req, res, reader);
  counters->Count(res.status);
}

}  // namespace

// ---- Public ------------------------------------------------------------------------------------

std::vector<RouteInfo> RouteTable() {
  std::vector<RouteInfo> table;
  for (const Route& r : kRoutes) table.push_back({r.method, r.path, r.access, r.body});
  return table;
}

json ProblemFor(const Status& status, int http_status) {
  return {{"type", ProblemTypeFor(status.code())},
          {"title", HttpTitle(http_status)},
          {"status", http_status},
          {"detail", status.field().empty() ? status.reason() : status.field() + ": " + status.reason()},
          {"field", status.field()}};
}

void RegisterRoutes(httplib::Server& server, Deps& deps) {
  Deps* d = &deps;
  auto counters = std::make_shared<HttpCounters>();
  counters->auth_failures = std::make_unique<FailedAuthThrottle>(deps.clock, FailedAuthThrottle::Options{});
  for (const Route& route : kRoutes) {
    const Route* r = &route;
    std::string pattern = PathRegex(route.path);
    httplib::Server::Handler plain = [r, d, counters](const httplib::Request& req, httplib::Response& res) {
      DispatchCounted(*r, *d, counters.get(), req, res, nullptr);
    };
    httplib::Server::HandlerWithContentReader with_body =
        [r, d, counters](const httplib::Request& req, httplib::Response& res, const httplib::ContentReader& reader) {
          DispatchCounted(*r, *d, counters.get(), req, res, &reader);
        };
    std::string method = route.method;
    if (method == "GET")
      server.Get(pattern, plain);
    else if (method == "POST")
      server.Post(pattern, with_body);
    else if (method == "PUT")
      server.Put(pattern, with_body);
  }

  // The dashboard (server/dashboard/): the same page at every dashboard path (the page reads the
  // API from the browser, so a link to any of them can be pasted into a notebook), its scripts
  // and styles under /ui/. Public: they hold no data; the API's rules hold for what they read.
  auto dashboard_file = [counters](const std::string& name, httplib::Response& res) {
    std::optional<std::string_view> bytes = DashboardFile(name);
    if (!bytes) {
      SendProblem(res, Status::NotFound("no dashboard file \"" + name + "\""));
      counters->Count(404);
      return;
    }
    const size_t dot = name.rfind('.');
    const std::string ext = dot == std::string::npos ? "" : name.substr(dot);
    const char* type = ext == ".js"    ? "text/javascript; charset=utf-8"
                       : ext == ".css" ? "text/css; charset=utf-8"
                                       : "text/html; charset=utf-8";
    res.set_header("Cache-Control", "no-cache");
    res.status = 200;
    res.set_content(bytes->data(), bytes->size(), type);
    counters->Count(200);
  };
  httplib::Server::Handler page = [dashboard_file](const httplib::Request&, httplib::Response& res) {
    dashboard_file("index.html", res);
  };
  server.Get("/", page);
  // No icon (the page names this one so the browser asks for nothing else): 204, not a 404.
  server.Get("/favicon.ico", [counters](const httplib::Request&, httplib::Response& res) {
    res.status = 204;
    counters->Count(204);
  });
  server.Get("/submit", page);
  server.Get(R"(/(campaign-runs|sweeps|runs|beds)(/[0-9]+)?)", page);
  server.Get(R"(/ui/([A-Za-z0-9_-][A-Za-z0-9._-]*))",
             [dashboard_file](const httplib::Request& req, httplib::Response& res) {
               dashboard_file(req.matches[1].str(), res);
             });

  // OPTIONS says which methods a path takes, and approves no other origin (no CORS headers): a
  // browser's preflight for a cross-origin JSON write fails here.
  server.Options(R"(.*)", [counters](const httplib::Request& req, httplib::Response& res) {
    std::set<std::string> methods = {"OPTIONS"};
    for (const CompiledRoute& cr : CompiledRoutes()) {
      if (std::regex_match(req.path, cr.pattern)) methods.insert(cr.route->method);
    }
    if (methods.size() == 1) methods.insert("GET");  // the dashboard's pages and files
    std::string allow;
    for (const std::string& m : methods) allow += (allow.empty() ? "" : ", ") + m;
    res.status = 204;
    res.set_header("Allow", allow);
    counters->Count(204);
  });

  // Refuse a Host that does not name this daemon (DNS rebinding), and what cannot be drained,
  // before any byte of the body is read.
  server.set_pre_routing_handler([d, counters](const httplib::Request& req, httplib::Response& res) {
    if (!HostAllowed(d->host_policy, req.get_header_value("Host"))) {
      spdlog::warn("refused {} {} from {}: Host \"{}\" does not name this daemon", req.method, req.path,
                   req.remote_addr, req.get_header_value("Host"));
      res.set_header("Connection", "close");
      SendProblem(res,
                  Status::InvalidArgument("Host", "\"" + req.get_header_value("Host") +
                                                      "\" is not a name of this daemon (its address, localhost, "
                                                      "or a name given to sandswimd with --allow-host)"),
                  421);
      counters->Count(421);
      return httplib::Server::HandlerResponse::Handled;
    }
    // Compress with gzip, never brotli: the library compresses brotli at its highest quality, and
    // a 10,000-run result table (12 MB of JSON) took 41 s that way against 0.24 s with gzip
    // (tests/bench/bench_dashboard.cc). Every browser asks for both; the header is rewritten
    // before the library reads it (the request is the library's own object, passed const).
    if (std::string accepts = req.get_header_value("Accept-Encoding"); accepts.find("br") != std::string::npos) {
      auto& headers = const_cast<httplib::Request&>(req).headers;
      headers.erase("Accept-Encoding");
      headers.emplace("Accept-Encoding", accepts.find("gzip") != std::string::npos ? "gzip" : "identity");
    }
    const Route* route = FindRoute(req.method, req.path);
    if (route == nullptr || route->body == BodyKind::kNone || !req.has_header("Content-Length")) {
      return httplib::Server::HandlerResponse::Unhandled;
    }
    size_t limit = route->body == BodyKind::kRestart ? d->max_restart_body : std::max(d->max_json_body, kDrainCapBytes);
    auto length = ParseInt(req.get_header_value("Content-Length"), "Content-Length", 0, INT64_MAX);
    if (length.ok() && static_cast<uint64_t>(*length) <= limit) return httplib::Server::HandlerResponse::Unhandled;
    res.set_header("Connection", "close");
    SendProblem(
        res,
        Status::ResourceExhausted(
            "body", "the body is larger than this route takes (" +
                        std::to_string(route->body == BodyKind::kRestart ? d->max_restart_body : d->max_json_body) +
                        " bytes)"),
        413);
    counters->Count(413);
    return httplib::Server::HandlerResponse::Handled;
  });

  server.set_payload_max_length(std::max(deps.max_restart_body, kDrainCapBytes) + 1);

  // Backstop: whatever httplib answers by itself (404, 405, 413, 400) becomes a problem document.
  httplib::Server::HandlerWithResponse on_error = [counters](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty() || res.content_length_ > 0) return httplib::Server::HandlerResponse::Unhandled;
    counters->Count(res.status);  // answered by httplib itself (no route, unreadable request)
    std::string reason = res.status == 404 ? "no route " + req.method + " " + req.path + " (see /api/v1/openapi.json)"
                                           : HttpTitle(res.status);
    StatusCode code = res.status == 404   ? StatusCode::kNotFound
                      : res.status >= 500 ? StatusCode::kInternal
                                          : StatusCode::kInvalidArgument;
    std::string field = res.status == 413 ? "body" : "";
    res.set_content(api::ToJsonText(ProblemFor(Status(code, reason, field), res.status)), kProblemType);
    return httplib::Server::HandlerResponse::Handled;
  };
  server.set_error_handler(on_error);

  server.set_exception_handler([](const httplib::Request& req, httplib::Response& res, std::exception_ptr ep) {
    try {
      std::rethrow_exception(ep);
    } catch (const json::parse_error& e) {
      SendProblem(
          res, Status::InvalidArgument("body", "malformed JSON at byte " + std::to_string(e.byte) + ": " + e.what()));
    } catch (const json::exception& e) {
      SendProblem(res, Status::InvalidArgument("body", e.what()));
    } catch (const std::exception& e) {
      SendProblem(res, Status::Internal(req.method + " " + req.path + " threw: " + e.what()));
    } catch (...) {
      SendProblem(res, Status::Internal(req.method + " " + req.path + " threw a non-standard exception"));
    }
  });

  // Every response, the library's own answers too: no framing, no sniffing, no referrer, and only
  // the daemon's own scripts, styles and images (the dashboard has no inline script or style).
  server.set_post_routing_handler([](const httplib::Request&, httplib::Response& res) {
    if (!res.has_header("Content-Security-Policy")) {
      res.set_header("Content-Security-Policy", "default-src 'self'; frame-ancestors 'none'");
    }
    res.set_header("X-Frame-Options", "DENY");
    res.set_header("X-Content-Type-Options", "nosniff");
    res.set_header("Referrer-Policy", "no-referrer");
  });

  server.set_logger([](const httplib::Request& req, const httplib::Response& res) {
    spdlog::debug("{} {} -> {}", req.method, req.path, res.status);
  });
}

// ---- Listen address ----------------------------------------------------------------------------

Result<ListenAddress> ParseListenAddress(const std::string& text) {
  ListenAddress address;
  std::string host, port;
  if (!text.empty() && text[0] == '[') {
    size_t close = text.find(']');
    if (close == std::string::npos || close + 1 >= text.size() || text[close + 1] != ':') {
      return Status::InvalidArgument("--listen", "expected [IPv6]:PORT, got \"" + text + "\"");
    }
    host = text.substr(1, close - 1);
    port = text.substr(close + 2);
  } else {
    size_t colon = text.rfind(':');
    if (colon == std::string::npos) {
      return Status::InvalidArgument("--listen", "expected HOST:PORT (e.g. 127.0.0.1:8640), got \"" + text + "\"");
    }
    host = text.substr(0, colon);
    port = text.substr(colon + 1);
  }
  if (host.empty()) host = "127.0.0.1";
  auto p = ParseInt(port, "--listen", 0, 65535);
  if (!p.ok()) return Status::InvalidArgument("--listen", "port must be 0..65535, got \"" + port + "\"");
  address.host = host;
  address.port = static_cast<int>(*p);
  return address;
}

Status CheckListenPolicy(const ListenAddress& address, bool have_token, bool tls, bool plain_http_ok) {
  if (IsLoopbackHost(address.host)) return Status::Ok();
  if (!have_token) {
    return Status(StatusCode::kFailedPrecondition,
                  "refusing to listen on " + address.host +
                      " (not loopback) without a token: drop --no-token (the daemon makes one in DATA/token), "
                      "or listen on 127.0.0.1",
                  "--listen");
  }
  if (!tls && !plain_http_ok) {
    return Status(StatusCode::kFailedPrecondition,
                  "refusing to serve plain HTTP on " + address.host +
                      " (not loopback): the token, and the decks workers run, would cross the network readable "
                      "and changeable. Serve HTTPS (--tls self-signed, or --tls-cert FILE --tls-key FILE), or "
                      "say --plain-http when a TLS proxy or a private network stands in front",
                  "--listen");
  }
  return Status::Ok();
}

// ---- ApiServer ---------------------------------------------------------------------------------

namespace {
// The worker protocol and /healthz: what the reserved threads serve (server/guarded_http_server.h),
// so that no reader can cost a worker its lease.
bool IsReservedRoute(const std::string& method, const std::string& path) {
  const Route* route = FindRoute(method, path);
  return route != nullptr && (route->access == Access::kWorker || std::string_view(route->path) == "/healthz");
}
}  // namespace

// Slow, idle and greedy clients are held off by the server (server/guarded_http_server.h).
ApiServer::ApiServer(Deps deps, ConnectionLimits limits)
    : deps_(std::move(deps)), server_(std::make_unique<GuardedHttpServer>(limits)) {
  server_->SetReserved(IsReservedRoute);
  server_->SetRefusalBody([](int http_status, const std::string& detail) {
    const Status why = http_status == 429 ? Status::ResourceExhausted("", detail) : Status::Unavailable(detail);
    return api::ToJsonText(ProblemFor(why, http_status));
  });
  // Without TCP_NODELAY a small response written as headers + body meets the client's delayed
  // ACK: ~40 ms per request on loopback (bench_daemon: 173 -> thousands of cycles/s).
  server_->set_tcp_nodelay(true);
  RegisterRoutes(*server_, deps_);
}

ApiServer::~ApiServer() { Stop(); }

Status ApiServer::UseTls(const std::string& cert_file, const std::string& key_file) {
  std::string error;
  if (!server_->SetTls(cert_file, key_file, &error)) return Status::InvalidArgument("--tls-cert", error);
  return Status::Ok();
}

Result<int> ApiServer::Bind(const ListenAddress& address) {
  int port = address.port;
  if (port == 0) {
    port = server_->bind_to_any_port(address.host);
    if (port < 0) port = 0;
  } else if (!server_->bind_to_port(address.host, port)) {
    port = 0;
  }
  if (port <= 0) {
    return Status::Unavailable("cannot listen on " + address.host + ":" + std::to_string(address.port) +
                               " (address in use or not local?): pick another --listen");
  }
  if (!server_->SetBacklog(SOMAXCONN)) spdlog::warn("could not widen the listen backlog past 5 connections");
  // Before Serve(): the routes read the policy without a lock.
  deps_.host_policy.listen_host = address.host;
  deps_.host_policy.listen_port = port;
  return port;
}

void ApiServer::Serve() { server_->listen_after_bind(); }

void ApiServer::Stop() {
  if (server_) server_->stop();
}

}  // namespace sandswim
