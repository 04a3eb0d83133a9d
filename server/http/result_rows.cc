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
                                          std::vector<ResultRow>* distinct) {
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

}  // namespace routes
}  // namespace sandswim
