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
