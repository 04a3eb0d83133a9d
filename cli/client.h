// Client: what `sandswim` asks the daemon over REST (/api/v1, /healthz), as an interface so that
// the commands and the watch loop can be tested against a fake without a server.
// HttpDaemonClient (client.cc) is the real one and the only CLI code that includes httplib.h.
//
// Answers are the daemon's JSON bodies, unchanged, except that list calls follow the cursors and
// return the concatenated array. Errors are Status values whose reason is one line a user can
// act on:
//   - no daemon at the URL: kUnavailable, "no daemon at http://127.0.0.1:8640 (connection
//     refused). Start one with: build/bin/sandswimd --local-workers 2";
//   - a problem+json answer: the code its HTTP status stands for (platform/http_client.h's one
//     table, shared with the worker), the reason being its "detail".
//
// Where the daemon is: --server, else $SANDSWIM_SERVER, else http://127.0.0.1:8640. The bearer
// token: platform/token.h's client rule (--token-file, else $SANDSWIM_TOKEN, else, for a daemon on
// loopback, ./var/data/token, the token file of a daemon started with its default --data).
//
// Thread safety: one client per thread.
#ifndef SANDSWIM_CLI_CLIENT_H_
#define SANDSWIM_CLI_CLIENT_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "platform/http_client.h"

namespace sandswim::cli {

struct RunQuery {
  std::optional<int64_t> sweep;
  std::optional<std::string> state;  // queued | running | done | failed | cancelled
  int64_t limit = 0;                 // at most this many runs; 0: all of them
};

class DaemonClient {
 public:
  virtual ~DaemonClient() = default;
  virtual const std::string& base_url() const = 0;

  virtual Result<nlohmann::json> Healthz() = 0;
  // POST /api/v1/sweeps; `idempotency_key` empty: none sent.
  virtual Result<nlohmann::json> Submit(const nlohmann::json& body, const std::string& idempotency_key) = 0;
  // Every sweep (all pages): the concatenated "sweeps" arrays.
  virtual Result<nlohmann::json> ListSweeps() = 0;
  virtual Result<nlohmann::json> GetSweep(int64_t id) = 0;
  // Every page of GET .../results followed: {"id","results":[every row],"aggregates":[...]}.
  virtual Result<nlohmann::json> SweepResults(int64_t id) = 0;
  virtual Result<nlohmann::json> CancelSweep(int64_t id) = 0;
  // The runs matching `query` (pages followed up to query.limit): the concatenated "runs".
  virtual Result<nlohmann::json> ListRuns(const RunQuery& query) = 0;
  virtual Result<nlohmann::json> GetRun(int64_t id) = 0;
  virtual Result<nlohmann::json> GetCampaignRun(int64_t id) = 0;
  // GET /api/v1/live: the daemon's progress board (server/dashboard/live_feed.h), one request for
  // the counts, ETAs and runs in flight of the newest sweeps and campaign runs. Unavailable from a
  // client or daemon without one.
  virtual Result<nlohmann::json> Live() { return Status::Unavailable("this client cannot read the progress board"); }
  virtual Result<nlohmann::json> CampaignRunResults(int64_t id) = 0;  // as SweepResults
  // GET /api/v1/campaign-runs/{id}/claims: the verdict of each claim the campaign states.
  virtual Result<nlohmann::json> CampaignRunClaims(int64_t id) {
    (void)id;
    return Status::Unavailable("this client cannot fetch claims");
  }
  // GET /api/v1/campaigns/{name}/drift[?scale=]: the latest drift report (kNotFound: none yet).
  virtual Result<nlohmann::json> CampaignDrift(const std::string& name, const std::string& scale) {
    (void)scale;
    return Status::NotFound("no drift report for campaign '" + name + "'");
  }
  // The HTML report (server/analysis/report.h) of campaign run `campaign_run_id` when it is > 0, else of
  // the latest run of campaign `name` (at `scale`, or any scale when empty).
  virtual Result<std::string> CampaignReport(const std::string& name, const std::string& scale,
                                             int64_t campaign_run_id) {
    (void)name, (void)scale, (void)campaign_run_id;
    return Status::Unavailable("this client cannot fetch reports");
  }
  // ---- Campaigns as data (GET/PUT/DELETE /api/v1/campaigns/{name}) -------------------------------
  // GET /api/v1/campaigns: the "campaigns" array (built-in and stored; version, extends, schedule).
  virtual Result<nlohmann::json> ListCampaigns() { return Status::Unavailable("this client cannot list campaigns"); }
  // GET /api/v1/campaign-runs?campaign=NAME&limit=N: the "campaign_runs" array, newest first.
  virtual Result<nlohmann::json> ListCampaignRuns(const std::string& name, int64_t limit) {
    (void)name, (void)limit;
    return Status::Unavailable("this client cannot list campaign runs");
  }
  // GET /api/v1/campaigns/{name}[?version=N] (`version` 0: the current one): definition, resolved,
  // versions, runs, schedule.
  virtual Result<nlohmann::json> GetCampaign(const std::string& name, int64_t version) {
    (void)name, (void)version;
    return Status::Unavailable("this client cannot fetch campaigns");
  }
  // PUT /api/v1/campaigns/{name}: {name, version, unchanged, notes, planned_runs}.
  virtual Result<nlohmann::json> PutCampaign(const std::string& name, const nlohmann::json& definition) {
    (void)name, (void)definition;
    return Status::Unavailable("this client cannot store campaigns");
  }
  // DELETE /api/v1/campaigns/{name}.
  virtual Status DeleteCampaign(const std::string& name) {
    (void)name;
    return Status::Unavailable("this client cannot remove campaigns");
  }
  // POST /api/v1/campaigns/{name}/runs {"scale"?, "force"?}: the answer of a submission (Submit).
  virtual Result<nlohmann::json> RunCampaign(const std::string& name, const nlohmann::json& body) {
    (void)name, (void)body;
    return Status::Unavailable("this client cannot run campaigns");
  }
  // PUT /api/v1/campaigns/{name}/schedule {"cron", "scale"?}: {campaign, cron, scale, next_due}.
  virtual Result<nlohmann::json> PutSchedule(const std::string& name, const nlohmann::json& body) {
    (void)name, (void)body;
    return Status::Unavailable("this client cannot schedule campaigns");
  }
  // DELETE /api/v1/campaigns/{name}/schedule (kNotFound: none).
  virtual Status DeleteSchedule(const std::string& name) {
    (void)name;
    return Status::Unavailable("this client cannot schedule campaigns");
  }
  // GET /api/v1/cost-model: the engine rates the daemon has measured (server/store/cost_model.h).
  virtual Result<nlohmann::json> CostModel() { return Status::Unavailable("this client cannot fetch the cost model"); }
  // POST /api/v1/backup, streamed into the file at `path` (created or truncated): a consistent copy
  // of the daemon's database. Returns the bytes written.
  virtual Result<int64_t> DownloadBackup(const std::string& path) {
    (void)path;
    return Status::Unavailable("this client cannot fetch backups");
  }
};

// Resolves the daemon's URL and token from the flags and the environment (`getenv` is injected
// for tests). Errors name the flag or variable ("--server", "--token-file", "SANDSWIM_TOKEN").
// For an https:// URL, how its certificate is trusted (platform/tls.h): --tls-fingerprint or
// $SANDSWIM_TLS_FINGERPRINT, --tls-ca or $SANDSWIM_TLS_CA; else, for a daemon on loopback, the
// fingerprint of the default data directory's self-signed certificate (./var/data/tls/cert.pem)
// when it exists, as the token; else the system's CAs.
Result<ClientOptions> ResolveClientOptions(const std::string& server_flag, const std::string& token_file_flag,
                                           const std::function<const char*(const char*)>& getenv,
                                           const std::string& tls_fingerprint_flag = "",
                                           const std::string& tls_ca_flag = "");

// The REST client over cpp-httplib. REQUIRES: options.server starts with "http://" or "https://".
std::unique_ptr<DaemonClient> NewDaemonClient(const ClientOptions& options);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_CLIENT_H_
