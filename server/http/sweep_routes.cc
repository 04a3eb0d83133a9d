// Routes of sweeps, runs and beds: submit, list, read, results (JSON or CSV), cancel.
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

void AnswerSubmission(Call& c, const json& body) {
  auto request = ParseSubmitRequest(body);
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

namespace {

// ---- Handlers: parse -> call -> render ---------------------------------------------------------

void SubmitSweeps(Call& c) {
  auto body = ParseJsonBody(c.body, /*allow_empty=*/false);
  if (!body.ok()) return Fail(c, body.status());
  AnswerSubmission(c, *body);
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
  auto eta = EtaOf(c, EtaScope::kSweep, *id);
  if (!eta.ok()) return Fail(c, eta.status());
  json reply = *sweep;
  reply["eta"] = EtaJson(*eta);
  SendJson(c, 200, reply);
}

void GetSweepResults(Call& c) { SendResults(c, ResultsOf::kSweep); }

void CancelSweep(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  if (Status s = EmptyOrObject(c.body); !s.ok()) return Fail(c, s);
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
  if (c.req.has_param("state")) {
    const std::string text = c.req.get_param_value("state");
    filter.state = ParseJobState(text);
    if (!filter.state) {
      return Fail(c, Status::InvalidArgument("state", "'" + text + "' is not one of " + std::string(JobStateNames())));
    }
  }
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

}  // namespace

const std::vector<Route>& SweepsRoutes() {
  // clang-format off: one route a line, in columns, as the table in routes.cc reads.
  static const std::vector<Route> kTable = {
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
  };
  // clang-format on
  return kTable;
}

}  // namespace routes

}  // namespace sandswim
