// Routes of operations: the API description, health, metrics, the cost model and online backups;
// and the scratch directories under DATA that requests in flight write to.
#include "server/http/call.h"

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
#include "core/job_state.h"
#include "core/result_table.h"
#include "core/snapshot.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "platform/data_dir.h"
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
namespace {

// A consistent copy of the database, made while the daemon serves (Database::BackupTo) under
// DATA/backups/ and streamed; the file is removed once sent. A POST: it writes a file and costs a
// whole copy, which no link or image of another page may start.
void PostBackup(Call& c) {
  if (Status s = EmptyOrObject(c.body); !s.ok()) return Fail(c, s);
  const std::string dir = DataDir(c.deps.data_dir).Backups();
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

void GetCostModel(Call& c) {
  auto model = ReadCostModel(*c.deps.store, c.deps.clock->Now());
  if (!model.ok()) return Fail(c, model.status());
  json reply = *model;
  reply["engine_slots"] = c.deps.engine_slots;
  SendJson(c, 200, reply);
}

// The latest drift report of a campaign (?scale= narrows it to one scale).

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
    for (JobState s : kJobStates) out << name << "{state=\"" << JobStateName(s) << "\"} " << c[s] << "\n";
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

}  // namespace

const std::vector<Route>& OperationsRoutes() {
  // clang-format off: one route a line, in columns, as the table in routes.cc reads.
  static const std::vector<Route> kTable = {
    // method  path                                   access            body                handler
    {"POST", "/api/v1/backup",                        Access::kWrite,  BodyKind::kJson,    PostBackup},
    {"GET",  "/api/v1/openapi.json",                  Access::kPublic, BodyKind::kNone,    OpenApi},
    {"GET",  "/healthz",                              Access::kPublic, BodyKind::kNone,    Healthz},
    {"GET",  "/metrics",                              Access::kRead,   BodyKind::kNone,    GetMetrics},
    {"GET",  "/api/v1/cost-model",                    Access::kRead,   BodyKind::kNone,    GetCostModel},
  };
  // clang-format on
  return kTable;
}

}  // namespace routes

Result<int> ClearScratchDirs(const std::string& data_dir) {
  int removed = 0;
  for (const std::string& dir : {DataDir(data_dir).Backups(), DataDir(data_dir).Uploads()}) {
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

}  // namespace sandswim
