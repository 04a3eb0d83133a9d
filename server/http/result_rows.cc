#include "server/http/result_rows.h"

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
#include "core/job_state.h"
#include "core/aggregate.h"
#include "core/materials.h"
#include "core/result_fields.h"
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
#include "server/http/guarded_http_server.h"
#include "server/http/routes.h"
#include "server/dashboard/live_feed.h"
#include "server/analysis/report.h"
#include "server/store/schema_files.h"
#include "server/jobs/submission.h"
#include "server/http/result_rows.h"

namespace sandswim {
namespace routes {

// ---- Result rows (JSON objects and CSV rows share the columns) ---------------------------------

json ResultRowJson(const ResultRow& row, ResultsOf of) {
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
    j["Uz_text"] = DescribeUz(row.result->result, false);
    for (const ResultField& f : ResultFields()) {
      if (!f.row_key.empty()) j[f.row_key] = f.get(*row.result);
    }
  }
  if (of == ResultsOf::kCampaignRun) j["sweeps"] = row.sweeps;
  return j;
}

namespace {

// A row as one replicate of its point (core/aggregate.h).
ReplicateValue ReplicateOf(const ResultRow& row) {
  ReplicateValue v;
  v.run_id = row.run_id;
  v.replicate = row.replicate;
  v.bed_id = row.bed_id;
  v.state = row.state;
  if (row.state == JobState::kDone && row.result) {  // a requeued run's old result is not averaged
    const api::RunResult& r = row.result->result;
    v.conclusive = r.conclusive;
    v.uz = r.uz;
    v.uz_stderr = r.uz_stderr;
    v.uz_ci95 = r.uz_ci95;
  }
  return v;
}

// The per-point aggregates of the points of `page`'s runs, each over every run of that point in
// `of` `id` (Store::ResultsOfDrives: a point whose runs a page boundary splits gets its whole
// aggregate on both pages), with its point's fields, in the set's order, as JSON text (an array,
// written an aggregate at a time).
Result<std::string> AggregatesText(Store& store, ResultsOf of, int64_t id, const std::vector<ResultRow>& page) {
  std::vector<Point> points;
  points.reserve(page.size());
  for (const ResultRow& row : page) points.push_back(row.point);
  auto rows = store.ResultsOfDrives(of, id, points);
  if (!rows.ok()) return rows.status();
  std::vector<std::pair<Point, ReplicateValue>> runs;
  runs.reserve(rows->size());
  for (const ResultRow& row : *rows) runs.emplace_back(row.point, ReplicateOf(row));
  std::string text = "[";
  bool first = true;
  for (const PointAggregate& a : AggregateByPoint(runs)) {
    json j = PointToJson(a.point);
    j.erase("duration_s");
    j.update(AggregateToJson(a.aggregate));
    if (!first) text += ',';
    first = false;
    text += api::ToJsonText(j);
  }
  return text + "]";
}

// A cursor as clients see it (opaque to them): a sweep's "POSITION", a campaign run's
// "SWEEP.POSITION".
std::string CursorText(ResultsOf of, const ResultCursor& cursor) {
  if (of == ResultsOf::kSweep) return std::to_string(cursor.position);
  return std::to_string(cursor.sweep_id) + "." + std::to_string(cursor.position);
}

Result<ResultCursor> ParseCursor(ResultsOf of, const std::string& text) {
  const char* kWhat = "must be the next_cursor of the page before";
  ResultCursor cursor;
  const size_t dot = text.find('.');
  if ((of == ResultsOf::kSweep) != (dot == std::string::npos)) {
    return Status::InvalidArgument("cursor", std::string(kWhat) + ", got \"" + text + "\"");
  }
  if (dot != std::string::npos) {
    auto sweep = ParseInt(text.substr(0, dot), "cursor", 0, INT64_MAX);
    if (!sweep.ok()) return Status::InvalidArgument("cursor", std::string(kWhat) + ", got \"" + text + "\"");
    cursor.sweep_id = *sweep;
  }
  auto position = ParseInt(dot == std::string::npos ? text : text.substr(dot + 1), "cursor", 0, INT64_MAX);
  if (!position.ok()) return Status::InvalidArgument("cursor", std::string(kWhat) + ", got \"" + text + "\"");
  cursor.position = *position;
  return cursor;
}

std::string ResultsPath(ResultsOf of, int64_t id) {
  return std::string(of == ResultsOf::kSweep ? "/api/v1/sweeps/" : "/api/v1/campaign-runs/") + std::to_string(id) +
         "/results";
}

std::vector<std::string> CsvColumns(ResultsOf of) {
  std::vector<std::string> columns = ResultCsvColumns();
  if (of == ResultsOf::kCampaignRun) columns.push_back("sweeps");
  return columns;
}

// The CSV lines of a page's rows; the header line only with `header`.
std::string CsvLines(const std::vector<ResultRow>& rows, ResultsOf of, bool header) {
  std::vector<json> objects;
  objects.reserve(rows.size());
  for (const ResultRow& row : rows) objects.push_back(ResultCsvRow(ResultRowJson(row, of)));
  std::string text = RowsToCsv(objects, CsvColumns(of));
  if (!header) text.erase(0, text.find('\n') + 1);
  return text;
}

// Rows of a CSV stream's page: small enough that a stream holds little, large enough that its
// read transactions cost little.
constexpr int kCsvPageRows = 1000;

void StreamCsv(Call& c, ResultsOf of, int64_t id) {
  auto first = c.deps.store->ResultsPage(of, id, ResultCursor{}, kCsvPageRows);
  if (!first.ok()) return Fail(c, first.status());
  struct Stream {
    Store* store;
    ResultsOf of;
    int64_t id;
    std::string pending;               // the first page's lines, read before the answer began
    std::optional<ResultCursor> next;  // where the next page starts; none: the last was sent
  };
  auto stream = std::make_shared<Stream>(Stream{c.deps.store, of, id, CsvLines(first->rows, of, true), first->next});
  c.res.status = 200;
  c.res.set_chunked_content_provider("text/csv; charset=utf-8", [stream](size_t, httplib::DataSink& sink) {
    if (!stream->pending.empty()) {
      std::string text = std::move(stream->pending);
      stream->pending.clear();
      if (!sink.write(text.data(), text.size())) return false;
    }
    if (!stream->next) {
      sink.done();
      return true;
    }
    auto page = stream->store->ResultsPage(stream->of, stream->id, *stream->next, kCsvPageRows);
    if (!page.ok()) {
      spdlog::error("results of {} as CSV: stopped mid-stream: {}", ResultsPath(stream->of, stream->id),
                    page.status().ToString());
      return false;  // the connection closes without the stream's last chunk
    }
    stream->pending = CsvLines(page->rows, stream->of, false);
    stream->next = page->next;
    return true;
  });
}

}  // namespace

void SendResults(Call& c, ResultsOf of) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  if (WantsCsv(c)) return StreamCsv(c, of, *id);
  auto limit = QueryInt(c, "limit", 1, kMaxResultsPage);
  if (!limit.ok()) return Fail(c, limit.status());
  const int rows = static_cast<int>(limit->value_or(kDefaultResultsPage));
  ResultCursor after;
  if (c.req.has_param("cursor")) {
    auto cursor = ParseCursor(of, c.req.get_param_value("cursor"));
    if (!cursor.ok()) return Fail(c, cursor.status());
    after = *cursor;
  }
  auto page = c.deps.store->ResultsPage(of, *id, after, rows);
  if (!page.ok()) return Fail(c, page.status());
  json reply = {{"id", *id}, {"next_cursor", nullptr}, {"material_fields", MaterialFieldsJson()}};
  if (page->next) {
    const std::string cursor = CursorText(of, *page->next);
    const std::string next = ResultsPath(of, *id) + "?cursor=" + cursor + "&limit=" + std::to_string(rows);
    reply["next_cursor"] = cursor;
    reply["next"] = next;
    c.res.set_header("Link", "<" + next + ">; rel=\"next\"");
  }
  // The rows (and aggregates) are written as text one at a time: a page of 10,000 rows as one
  // JSON tree took ten times its 11 MB of text.
  reply["aggregates_of"] = kAggregatesOf;
  std::string text = api::ToJsonText(reply);
  text.pop_back();  // its closing brace
  auto aggregates = AggregatesText(*c.deps.store, of, *id, page->rows);
  if (!aggregates.ok()) return Fail(c, aggregates.status());
  text += ",\"aggregates\":" + *aggregates;
  text += ",\"results\":[";
  for (size_t i = 0; i < page->rows.size(); ++i) {
    if (i > 0) text += ',';
    text += api::ToJsonText(ResultRowJson(page->rows[i], of));
  }
  text += "]}";
  c.res.status = 200;
  c.res.set_content("", 0, "application/json");
  c.res.body = std::move(text);  // not copied: the library's set_content takes a copy
}

}  // namespace routes
}  // namespace sandswim
