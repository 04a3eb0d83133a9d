// Routes of campaigns and campaign runs: the catalogue, drift reports, results and claims.
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
#include "server/store/rounds.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/claims_cache.h"
#include "server/analysis/drift_report.h"
#include "server/dashboard/dashboard_files.h"
#include "server/analysis/figures.h"
#include "server/http/guarded_http_server.h"
#include "server/http/routes.h"
#include "server/dashboard/live_feed.h"
#include "server/analysis/report.h"
#include "server/store/schema_files.h"
#include "server/jobs/campaign_edits.h"
#include "server/jobs/scheduler.h"
#include "server/jobs/submission.h"
#include "server/http/result_rows.h"

namespace sandswim {
namespace routes {
namespace {

// The scheduler's view for the routes: the daemon's own registers and ticks; this one reads and
// writes the same rows (campaign_schedules) in the daemon's local time zone, as the daemon's does.
Scheduler SchedulerOf(Call& c) { return Scheduler(c.deps.store, c.deps.clock, c.deps.engine_version); }

json ScheduleJson(const std::optional<ScheduledCampaign>& s) {
  if (!s) return nullptr;
  return {{"cron", s->cron},
          {"scale", s->scale},
          {"next_due", s->next_due ? json(*s->next_due) : json(nullptr)},
          {"source", s->source}};
}

// The current version's row of a stored campaign (what it extends); nullopt for a built-in one.
Result<std::optional<CampaignVersion>> CurrentVersion(Store& store, const CatalogueEntry& entry,
                                                      const std::string& name) {
  if (!entry.stored) return std::optional<CampaignVersion>();
  return GetCampaignVersion(store, name, entry.version);
}

json CampaignJson(const Campaign& campaign, bool builtin, bool stored, int version,
                  const std::optional<CampaignVersion>& current, const std::optional<ScheduledCampaign>& schedule) {
  json sweeps = json::array();
  for (const SweepSpec& s : campaign.sweeps) sweeps.push_back(s.name);
  const bool extends = current && !current->extends.empty();
  return {{"name", campaign.name},
          {"description", campaign.description},
          {"scale", campaign.scale},
          {"builtin", builtin},
          {"stored", stored},
          {"version", version},
          {"extends", extends ? json(current->extends) : json(nullptr)},
          {"sweeps", sweeps},
          // "schedule" is the registered one (sandswimd --schedule or PUT .../schedule); the
          // definition's own cron is "definition_schedule".
          {"schedule", ScheduleJson(schedule)},
          {"definition_schedule", campaign.schedule ? json(*campaign.schedule) : json(nullptr)},
          {"drift_tolerance_mps", campaign.drift_tolerance_mps}};
}

// Stored campaigns (a stored definition overrides the builtin one of its name), then the
// builtin campaigns nobody has stored.
void ListCampaigns(Call& c) {
  json campaigns = json::array();
  std::set<std::string> listed;
  auto schedules = SchedulerOf(c).List();
  if (!schedules.ok()) return Fail(c, schedules.status());
  auto schedule_of = [&](const std::string& name) {
    for (const ScheduledCampaign& s : *schedules)
      if (s.campaign == name && s.enabled) return std::optional<ScheduledCampaign>(s);
    return std::optional<ScheduledCampaign>();
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
    auto current = GetCampaignVersion(*c.deps.store, s.name, s.version);
    if (!current.ok()) return Fail(c, current.status());
    campaigns.push_back(CampaignJson(*campaign, IsBuiltinCampaign(s.name), /*stored=*/true, s.version, *current,
                                     schedule_of(s.name)));
    listed.insert(s.name);
  }
  for (const std::string& name : BuiltinCampaignNames()) {
    if (listed.count(name)) continue;
    auto campaign = BuiltinCampaign(name);
    if (!campaign.ok()) return Fail(c, campaign.status());
    campaigns.push_back(
        CampaignJson(*campaign, /*builtin=*/true, /*stored=*/false, /*version=*/0, std::nullopt, schedule_of(name)));
  }
  SendJson(c, 200, {{"campaigns", campaigns}});
}

// A campaign run as a campaign's page lists it: its state from its runs' counts.
json CampaignRunLine(const CampaignRunInfo& r) {
  std::string status = "done";
  if (r.counts.running > 0) {
    status = "running";
  } else if (r.counts.queued > 0) {
    status = "queued";
  } else if (r.counts.failed + r.counts.cancelled > 0) {
    status = r.counts.done > 0 ? "done with failures" : "failed";
  }
  return {{"id", r.id},
          {"campaign_version", r.campaign_version ? json(*r.campaign_version) : json(nullptr)},
          {"definition_sha256", r.definition_sha256.empty() ? json(nullptr) : json(r.definition_sha256)},
          {"scale", r.scale},
          {"trigger", r.trigger},
          {"status", status},
          {"counts", r.counts},
          {"created_at", r.created_at}};
}

// GET /api/v1/campaigns/{name}[?version=N]: the definition (as written and as it runs), its
// versions, its schedule and its campaign runs.
void GetCampaign(Call& c) {
  const std::string name = c.req.matches[1].str();
  Store& store = *c.deps.store;
  auto versions = ListCampaignVersions(store, name);
  if (!versions.ok()) return Fail(c, versions.status());
  json reply;
  std::optional<Campaign> campaign;
  std::optional<CampaignVersion> shown;  // the stored version shown (none: a built-in campaign)
  if (c.req.has_param("version")) {
    auto n = QueryInt(c, "version", 0, INT32_MAX);
    if (!n.ok()) return Fail(c, n.status());
    const int want = static_cast<int>(**n);
    std::optional<CampaignVersion> v;
    for (const CampaignVersion& each : *versions)
      if (each.version == want) v = each;
    if (!v && want == 0 && IsBuiltinCampaign(name)) {
      auto builtin = BuiltinCampaignDefinition(name);
      if (!builtin.ok()) return Fail(c, builtin.status());
      v = CampaignVersion{name, 0, *builtin, *builtin, "", 0, 0, DefinitionSha256(*builtin)};
    }
    if (!v) {
      return Fail(c, Status(StatusCode::kNotFound,
                            "campaign '" + name + "' has no version " + std::to_string(want) + " (it has " +
                                std::to_string(versions->size()) + " stored)",
                            "version"));
    }
    auto parsed = ParseCampaign(v->resolved);
    if (!parsed.ok()) return Fail(c, Status::Corruption("version " + std::to_string(want) + " of '" + name +
                                                        "' no longer parses: " + parsed.status().ToString()));
    campaign = std::move(parsed).value();
    reply = {{"version", v->version},         {"definition", v->definition},
             {"resolved", v->resolved},       {"extends", v->extends.empty() ? json(nullptr) : json(v->extends)},
             {"extends_version", v->extends.empty() ? json(nullptr) : json(v->extends_version)},
             {"definition_sha256", v->definition_sha256}};
    if (v->version > 0) shown = v;
  } else {
    auto entry = FindCampaign(store, name, "name");
    if (!entry.ok()) return Fail(c, entry.status());
    auto current = CurrentVersion(store, *entry, name);
    if (!current.ok()) return Fail(c, current.status());
    const std::optional<CampaignVersion>& v = *current;
    campaign = entry->campaign;
    reply = {{"version", entry->version},
             {"definition", v ? v->definition : entry->definition},
             {"resolved", entry->definition},
             {"extends", v && !v->extends.empty() ? json(v->extends) : json(nullptr)},
             {"extends_version", v && !v->extends.empty() ? json(v->extends_version) : json(nullptr)},
             {"definition_sha256", DefinitionSha256(entry->definition)}};
    shown = v;
  }
  // PUT's notes for this version, made again as PUT made them (campaign_edits.h NotesOf).
  std::vector<std::string> notes;
  if (shown) {
    auto made = NotesOf(store, *shown);
    if (!made.ok()) return Fail(c, made.status());
    notes = std::move(made).value();
  }
  auto stored = store.GetCampaign(name);
  if (!stored.ok()) return Fail(c, stored.status());
  auto schedule = SchedulerOf(c).Find(name);
  if (!schedule.ok()) return Fail(c, schedule.status());
  auto runs = store.ListCampaignRuns(name, 100);
  if (!runs.ok()) return Fail(c, runs.status());
  reply["name"] = name;
  reply["builtin"] = IsBuiltinCampaign(name);
  reply["stored"] = stored->has_value();
  reply["current_version"] = stored->has_value() ? json((*stored)->version) : json(IsBuiltinCampaign(name) ? 0 : -1);
  reply["notes"] = notes;
  reply["planned_runs"] = PlannedRunsAtEachScale(*campaign, c.deps.engine_version);
  reply["schedule"] = ScheduleJson(*schedule);
  reply["versions"] = *versions;
  reply["runs"] = json::array();
  for (const CampaignRunInfo& r : *runs) reply["runs"].push_back(CampaignRunLine(r));
  SendJson(c, 200, reply);
}

// PUT /api/v1/campaigns/{name}: a new campaign (201) or a new version of one (200), checked
// first (server/jobs/campaign_edits.h); nothing is stored on a refusal.
void PutCampaign(Call& c) {
  const std::string name = c.req.matches[1].str();
  auto body = ParseJsonBody(c.body, /*allow_empty=*/false);
  if (!body.ok()) return Fail(c, body.status());
  auto saved = SaveCampaign(*c.deps.store, name, *body, c.deps.engine_version, c.deps.clock->Now(),
                            c.deps.max_queued_runs);
  if (!saved.ok()) return Fail(c, saved.status());
  c.res.set_header("Location", "/api/v1/campaigns/" + name);
  SendJson(c, saved->created ? 201 : 200, *saved);
}

void DeleteCampaignRoute(Call& c) {
  const std::string name = c.req.matches[1].str();
  if (Status s = RemoveCampaign(*c.deps.store, name, c.deps.clock->Now()); !s.ok()) return Fail(c, s);
  c.res.status = 204;
}

// POST /api/v1/campaigns/{name}/runs {"scale"?, "force"?}: POST /api/v1/sweeps {"campaign": name, ...}.
void PostCampaignRun(Call& c) {
  const std::string name = c.req.matches[1].str();
  auto body = ParseJsonBody(c.body, /*allow_empty=*/true);
  if (!body.ok()) return Fail(c, body.status());
  if (!body->is_object()) return Fail(c, Status::InvalidArgument("body", "must be a JSON object {\"scale\"?, \"force\"?}"));
  for (const auto& [key, value] : body->items()) {
    if (key != "scale" && key != "force") {
      return Fail(c, Status::InvalidArgument(key, "unknown field (allowed: scale, force)"));
    }
  }
  json request = *body;
  request["campaign"] = name;
  AnswerSubmission(c, request);
}

// PUT /api/v1/campaigns/{name}/schedule {"cron", "scale"?}: stored, survives a restart.
void PutCampaignSchedule(Call& c) {
  const std::string name = c.req.matches[1].str();
  auto body = ParseJsonBody(c.body, /*allow_empty=*/false);
  if (!body.ok()) return Fail(c, body.status());
  if (!body->is_object()) return Fail(c, Status::InvalidArgument("body", "must be a JSON object {\"cron\", \"scale\"?}"));
  for (const auto& [key, value] : body->items()) {
    if (key != "cron" && key != "scale") return Fail(c, Status::InvalidArgument(key, "unknown field (allowed: cron, scale)"));
  }
  auto cron = body->find("cron");
  if (cron == body->end() || !cron->is_string()) {
    return Fail(c, Status(StatusCode::kFailedPrecondition, "must be a cron expression, e.g. \"0 2 * * *\"", "cron"));
  }
  std::optional<std::string> scale;
  if (auto it = body->find("scale"); it != body->end()) {
    if (!it->is_string()) return Fail(c, Status(StatusCode::kFailedPrecondition, "must be smoke, mini or paper", "scale"));
    scale = it->get<std::string>();
  }
  auto put = SchedulerOf(c).Put(name, cron->get<std::string>(), scale);
  if (!put.ok()) return Fail(c, put.status());
  SendJson(c, 200, {{"campaign", name}, {"cron", put->cron}, {"scale", put->scale},
                    {"next_due", put->next_due ? json(*put->next_due) : json(nullptr)}});
}

void DeleteCampaignSchedule(Call& c) {
  const std::string name = c.req.matches[1].str();
  if (Status s = SchedulerOf(c).Remove(name); !s.ok()) return Fail(c, s);
  c.res.status = 204;
}

void GetCampaignRun(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto info = c.deps.store->GetCampaignRun(*id);
  if (!info.ok()) return Fail(c, info.status());
  auto drift = LastDriftFor(*c.deps.store, *info);
  if (!drift.ok()) return Fail(c, drift.status());
  auto eta = EtaOf(c, EtaScope::kCampaignRun, *id);
  if (!eta.ok()) return Fail(c, eta.status());
  json reply = *info;
  reply["last_drift"] = drift->has_value() ? json(**drift) : json(nullptr);
  reply["eta"] = EtaJson(*eta);
  // Its rounds (server/jobs/rounds.h) when its definition runs in rounds; else none.
  auto rounds = rounds::RoundsReply(*c.deps.store, *info);
  if (!rounds.ok()) return Fail(c, rounds.status());
  reply["adaptive"] = (*rounds)["adaptive"];
  reply["rounds"] = (*rounds)["rounds"];
  SendJson(c, 200, reply);
}

// The engine rates measured so far (server/store/cost_model.h): what `sandswim expand --cost` uses.

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

void GetCampaignRunResults(Call& c) { SendResults(c, ResultsOf::kCampaignRun); }

// The verdict of each of the campaign's claims for this run (server/analysis/claim_check.h).
void GetCampaignRunClaims(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  if (c.deps.claims != nullptr) {
    auto cached = c.deps.claims->Get(*id);
    if (!cached.ok()) return Fail(c, cached.status());
    return SendJson(c, 200, CampaignRunClaimsToJson(**cached));
  }
  auto claims = CheckClaims(*c.deps.store, *id);
  if (!claims.ok()) return Fail(c, claims.status());
  SendJson(c, 200, CampaignRunClaimsToJson(*claims));
}

void ListCampaignRunsRoute(Call& c) {
  const std::string campaign = c.req.has_param("campaign") ? c.req.get_param_value("campaign") : "";
  auto limit = QueryInt(c, "limit", 1, 1000);
  if (!limit.ok()) return Fail(c, limit.status());
  auto runs = c.deps.store->ListCampaignRuns(campaign, static_cast<int>(limit->value_or(50)));
  if (!runs.ok()) return Fail(c, runs.status());
  SendJson(c, 200, {{"campaign_runs", *runs}});
}

}  // namespace

const std::vector<Route>& CampaignsRoutes() {
  // clang-format off: one route a line, in columns, as the table in routes.cc reads.
  static const std::vector<Route> kTable = {
    // method  path                                   access            body                handler
    {"GET",  "/api/v1/campaigns",                     Access::kRead,   BodyKind::kNone,    ListCampaigns},
    {"GET",  "/api/v1/campaigns/{name}",              Access::kRead,   BodyKind::kNone,    GetCampaign},
    {"PUT",  "/api/v1/campaigns/{name}",              Access::kWrite,  BodyKind::kJson,    PutCampaign},
    {"DELETE", "/api/v1/campaigns/{name}",            Access::kWrite,  BodyKind::kNone,    DeleteCampaignRoute},
    {"POST", "/api/v1/campaigns/{name}/runs",         Access::kWrite,  BodyKind::kJson,    PostCampaignRun},
    {"PUT",  "/api/v1/campaigns/{name}/schedule",     Access::kWrite,  BodyKind::kJson,    PutCampaignSchedule},
    {"DELETE", "/api/v1/campaigns/{name}/schedule",   Access::kWrite,  BodyKind::kNone,    DeleteCampaignSchedule},
    {"GET",  "/api/v1/campaigns/{name}/drift",        Access::kRead,   BodyKind::kNone,    GetCampaignDrift},
    {"GET",  "/api/v1/campaign-runs",                 Access::kRead,   BodyKind::kNone,    ListCampaignRunsRoute},
    {"GET",  "/api/v1/campaign-runs/{id}",            Access::kRead,   BodyKind::kNone,    GetCampaignRun},
    {"GET",  "/api/v1/campaign-runs/{id}/results",    Access::kRead,   BodyKind::kNone,    GetCampaignRunResults},
    {"GET",  "/api/v1/campaign-runs/{id}/claims",     Access::kRead,   BodyKind::kNone,    GetCampaignRunClaims},
  };
  // clang-format on
  return kTable;
}

}  // namespace routes

}  // namespace sandswim
