#include "cli/client.h"

#include "platform/data_dir.h"
#include "platform/tls.h"
#include "platform/token.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <netdb.h>
#include <sys/socket.h>
#include <unistd.h>

#include <httplib.h>

namespace sandswim::cli {
namespace {

using json = nlohmann::json;

constexpr const char* kStartHint = "Start one with: build/bin/sandswimd --local-workers 2";

// Why a connection to `url` fails, in words ("connection refused"): httplib only says that it
// failed, and a user needs to know whether nothing listens there or the host is wrong.
std::string WhyNoConnection(const std::string& url) {
  std::string rest = url.substr(std::string("http://").size());
  std::string host = rest, port = "80";
  if (!rest.empty() && rest[0] == '[') {
    size_t close = rest.find(']');
    host = rest.substr(1, close - 1);
    if (close + 1 < rest.size() && rest[close + 1] == ':') port = rest.substr(close + 2);
  } else if (size_t colon = rest.rfind(':'); colon != std::string::npos) {
    host = rest.substr(0, colon);
    port = rest.substr(colon + 1);
  }
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  int rc = getaddrinfo(host.c_str(), port.c_str(), &hints, &found);
  if (rc != 0) return "cannot resolve " + host + ": " + gai_strerror(rc);
  std::string why = "cannot connect";
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    int fd = socket(a->ai_family, a->ai_socktype | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    int ok = connect(fd, a->ai_addr, a->ai_addrlen);
    int saved = errno;
    close(fd);
    if (ok == 0) {
      why = "it accepted a connection but did not answer HTTP";
      break;
    }
    why = saved == ECONNREFUSED ? "connection refused" : std::strerror(saved);
  }
  freeaddrinfo(found);
  return why;
}

class HttpDaemonClient : public DaemonClient {
 public:
  explicit HttpDaemonClient(const ClientOptions& options) : options_(options), client_(NewHttpClient(options)) {
    http_.set_keep_alive(true);
  }

  const std::string& base_url() const override { return options_.server; }

  Result<json> Healthz() override { return Get("/healthz"); }

  Result<json> Submit(const json& body, const std::string& idempotency_key) override {
    httplib::Headers headers;
    if (!idempotency_key.empty()) headers.emplace("Idempotency-Key", idempotency_key);
    return Post("/api/v1/sweeps", body, headers);
  }

  Result<json> ListSweeps() override { return Paged("/api/v1/sweeps?", "sweeps", 0); }

  Result<json> GetSweep(int64_t id) override { return Get("/api/v1/sweeps/" + std::to_string(id)); }

  Result<json> SweepResults(int64_t id) override { return AllResults("/api/v1/sweeps/" + std::to_string(id) + "/results"); }

  Result<json> CancelSweep(int64_t id) override {
    return Post("/api/v1/sweeps/" + std::to_string(id) + "/cancel", json::object(), {});
  }

  Result<json> ListRuns(const RunQuery& query) override {
    std::string path = "/api/v1/runs?";
    if (query.sweep) path += "sweep=" + std::to_string(*query.sweep) + "&";
    if (query.state) path += "state=" + httplib::detail::encode_query_param(*query.state) + "&";
    return Paged(path, "runs", query.limit);
  }

  Result<json> GetRun(int64_t id) override { return Get("/api/v1/runs/" + std::to_string(id)); }

  Result<json> GetCampaignRun(int64_t id) override { return Get("/api/v1/campaign-runs/" + std::to_string(id)); }

  Result<json> CampaignRunResults(int64_t id) override {
    return AllResults("/api/v1/campaign-runs/" + std::to_string(id) + "/results");
  }

  Result<json> CampaignRunClaims(int64_t id) override {
    // The daemon analyses every sweep of the run before it answers: allow it as long as a report.
    AllowLongAnswer();
    return Get("/api/v1/campaign-runs/" + std::to_string(id) + "/claims");
  }

  Result<json> ListCampaigns() override {
    auto reply = Get("/api/v1/campaigns");
    if (!reply.ok()) return reply.status();
    return ArrayOf(*reply, "campaigns", "/api/v1/campaigns");
  }

  Result<json> ListCampaignRuns(const std::string& name, int64_t limit) override {
    const std::string path = "/api/v1/campaign-runs?campaign=" + httplib::detail::encode_query_param(name) +
                             "&limit=" + std::to_string(limit);
    auto reply = Get(path);
    if (!reply.ok()) return reply.status();
    return ArrayOf(*reply, "campaign_runs", path);
  }

  Result<json> GetCampaign(const std::string& name, int64_t version) override {
    std::string path = CampaignPath(name);
    if (version > 0) path += "?version=" + std::to_string(version);
    return Get(path);
  }

  Result<json> PutCampaign(const std::string& name, const json& definition) override {
    const std::string path = CampaignPath(name);
    return Answer(http_.Put(path.c_str(), definition.dump(), "application/json"), "PUT", path);
  }

  Status DeleteCampaign(const std::string& name) override { return Delete(CampaignPath(name)); }

  Result<json> RunCampaign(const std::string& name, const json& body) override {
    return Post(CampaignPath(name) + "/runs", body, {});
  }

  Result<json> PutSchedule(const std::string& name, const json& body) override {
    const std::string path = CampaignPath(name) + "/schedule";
    return Answer(http_.Put(path.c_str(), body.dump(), "application/json"), "PUT", path);
  }

  Status DeleteSchedule(const std::string& name) override { return Delete(CampaignPath(name) + "/schedule"); }

  Result<json> CostModel() override { return Get("/api/v1/cost-model"); }

  // With the last answer's ETag: an unchanged board is a 304 and the last one is returned.
  Result<json> Live() override {
    const std::string path = "/api/v1/live";
    httplib::Headers headers;
    if (!live_etag_.empty()) headers.emplace("If-None-Match", live_etag_);
    httplib::Result res = http_.Get(path.c_str(), headers);
    if (res && res->status == 304 && !live_last_.is_null()) return live_last_;
    Result<json> reply = Answer(res, "GET", path);
    if (!reply.ok()) return reply;
    live_etag_ = res->get_header_value("ETag");
    live_last_ = *reply;
    return reply;
  }

  Result<json> CampaignDrift(const std::string& name, const std::string& scale) override {
    std::string path = "/api/v1/campaigns/" + httplib::detail::encode_query_param(name) + "/drift";
    if (!scale.empty()) path += "?scale=" + httplib::detail::encode_query_param(scale);
    return Get(path);
  }

  Result<std::string> CampaignReport(const std::string& name, const std::string& scale,
                                     int64_t campaign_run_id) override {
    std::string path = campaign_run_id > 0
                           ? "/api/v1/campaign-runs/" + std::to_string(campaign_run_id) + "/report"
                           : "/api/v1/campaigns/" + httplib::detail::encode_query_param(name) + "/report";
    if (campaign_run_id <= 0 && !scale.empty()) path += "?scale=" + httplib::detail::encode_query_param(scale);
    // Reports draw every figure they have not drawn before: allow them longer than a JSON answer.
    AllowLongAnswer();
    httplib::Result res = http_.Get(path.c_str());
    if (res && res->status == 200) return res->body;
    auto error = Answer(res, "GET", path);
    if (!error.ok()) return error.status();
    return Status::Corruption("the daemon answered GET " + path + " with HTTP " + std::to_string(res->status));
  }

  Result<int64_t> DownloadBackup(const std::string& file) override {
    const std::string path = "/api/v1/backup";  // a POST: it makes a copy
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    if (!out) return Status::IOError("cannot write " + file);
    // The daemon copies the whole database before it answers: allow it time.
    AllowLongAnswer();
    int64_t bytes = 0;
    std::string error_body;
    int status = 0;
    httplib::Request req;
    req.method = "POST";
    req.path = path;
    req.body = "{}";
    req.set_header("Content-Type", "application/json");
    req.response_handler = [&](const httplib::Response& r) {
      status = r.status;
      return true;
    };
    req.content_receiver = [&](const char* data, size_t n, uint64_t, uint64_t) {
      if (status != 200) {
        error_body.append(data, n);  // a problem document
        return true;
      }
      out.write(data, static_cast<std::streamsize>(n));
      bytes += static_cast<int64_t>(n);
      return static_cast<bool>(out);
    };
    httplib::Result res = http_.send(req);
    if (status == 200 && !out) return Status::IOError("cannot write " + file + " (disk full?)");
    if (res && res->status == 200) {
      out.close();
      if (!out) return Status::IOError("cannot write " + file + " (disk full?)");
      return bytes;
    }
    if (res) res->body = error_body;
    auto error = Answer(res, "POST", path);
    if (!error.ok()) return error.status();
    return Status::Corruption("the daemon answered POST " + path + " with HTTP " + std::to_string(res->status));
  }

 private:
  // For answers the daemon computes at length (reports, claims, backups): at least 10 minutes.
  void AllowLongAnswer() {
    http_.set_read_timeout(std::max<time_t>(static_cast<time_t>(options_.read_timeout_s), 600), 0);
  }

  Result<json> Get(const std::string& path) { return Answer(http_.Get(path.c_str()), "GET", path); }

  Result<json> Post(const std::string& path, const json& body, const httplib::Headers& headers) {
    return Answer(http_.Post(path.c_str(), headers, body.dump(), "application/json"), "POST", path);
  }

  static std::string CampaignPath(const std::string& name) {
    return "/api/v1/campaigns/" + httplib::detail::encode_query_param(name);
  }

  Status Delete(const std::string& path) {
    auto reply = Answer(http_.Delete(path.c_str()), "DELETE", path);
    return reply.ok() ? Status::Ok() : reply.status();
  }

  // The array under `key` of an answer to GET `path`.
  static Result<json> ArrayOf(json& reply, const char* key, const std::string& path) {
    auto items = reply.find(key);
    if (items == reply.end() || !items->is_array()) {
      return Status(StatusCode::kCorruption,
                    std::string("the daemon's answer to GET ") + path + " has no \"" + key + "\" array");
    }
    return std::move(*items);
  }

  // Follows next_cursor until the end or until `limit` items (0: no limit).
  Result<json> Paged(const std::string& prefix, const char* key, int64_t limit) {
    json all = json::array();
    std::string cursor;
    while (true) {
      int64_t page = 1000;
      if (limit > 0) page = std::min<int64_t>(page, limit - static_cast<int64_t>(all.size()));
      std::string path = prefix + "limit=" + std::to_string(page);
      if (!cursor.empty()) path += "&cursor=" + httplib::detail::encode_query_param(cursor);
      auto reply = Get(path);
      if (!reply.ok()) return reply.status();
      auto items = ArrayOf(*reply, key, path);
      if (!items.ok()) return items.status();
      for (auto& item : *items) all.push_back(std::move(item));
      if (limit > 0 && static_cast<int64_t>(all.size()) >= limit) break;
      auto next = reply->find("next_cursor");
      if (next == reply->end() || next->is_null()) break;
      std::string next_cursor = next->is_string() ? next->get<std::string>() : next->dump();
      if (next_cursor == cursor || items->empty()) break;  // a daemon that repeats itself
      cursor = next_cursor;
    }
    return all;
  }

  // A results read whole: the first page's answer holding the "results" of every page, followed
  // by their "next" paths, the largest pages the daemon gives, and the "aggregates" of every page,
  // each point once (a page has those of the points of its runs: a point whose runs two pages
  // share is on both, the same; known by the smallest run id among its values).
  Result<json> AllResults(const std::string& path) {
    // The most rows a page may hold; $SANDSWIM_RESULTS_PAGE_ROWS asks for fewer (the tests read a
    // sweep over several pages that way).
    int rows = 10000;
    if (const char* env = std::getenv("SANDSWIM_RESULTS_PAGE_ROWS"); env != nullptr && std::atoi(env) > 0) {
      rows = std::min(rows, std::atoi(env));
    }
    auto all = Get(path + "?limit=" + std::to_string(rows));
    if (!all.ok()) return all.status();
    std::set<int64_t> points;
    auto point_of = [](const json& aggregate) {
      int64_t least = INT64_MAX;
      for (const json& v : aggregate.value("values", json::array())) {
        if (v.contains("run_id") && v["run_id"].is_number_integer()) least = std::min(least, v["run_id"].get<int64_t>());
      }
      return least;
    };
    if (!all->contains("aggregates") || !(*all)["aggregates"].is_array()) (*all)["aggregates"] = json::array();
    for (const json& a : (*all)["aggregates"]) points.insert(point_of(a));
    for (;;) {
      if (!all->contains("results") || !(*all)["results"].is_array()) {
        return Status(StatusCode::kCorruption, "the daemon's answer to GET " + path + " has no \"results\" array");
      }
      auto next = all->find("next");
      if (next == all->end() || !next->is_string()) break;
      const std::string next_path = next->get<std::string>();
      all->erase("next");
      all->erase("next_cursor");
      auto page = Get(next_path);
      if (!page.ok()) return page.status();
      auto rows = page->find("results");
      if (rows == page->end() || !rows->is_array() || rows->empty()) {
        return Status(StatusCode::kCorruption, "the daemon's answer to GET " + next_path + " has no rows");
      }
      for (auto& row : *rows) (*all)["results"].push_back(std::move(row));
      if (auto aggregates = page->find("aggregates"); aggregates != page->end() && aggregates->is_array()) {
        for (auto& a : *aggregates) {
          if (points.insert(point_of(a)).second) (*all)["aggregates"].push_back(std::move(a));
        }
      }
      if (page->contains("next")) (*all)["next"] = (*page)["next"];
    }
    all->erase("next_cursor");
    return all;
  }

  Result<json> Answer(const httplib::Result& res, const std::string& method, const std::string& path) {
    if (!res) {
      httplib::Error error = res.error();
      if (auto tls = TlsFailure(http_, static_cast<int>(error), options_.server); tls) return *tls;
      if (error == httplib::Error::Connection || error == httplib::Error::ConnectionTimeout) {
        std::string why =
            error == httplib::Error::ConnectionTimeout ? "connection timed out" : WhyNoConnection(options_.server);
        return Status::Unavailable("no daemon at " + options_.server + " (" + why + "). " + kStartHint);
      }
      return Status::Unavailable("the daemon at " + options_.server + " did not answer " + method + " " + path + " (" +
                                 httplib::to_string(error) + ")");
    }
    json body;
    bool parsed = false;
    if (!res->body.empty()) {
      try {
        body = json::parse(res->body);
        parsed = true;
      } catch (const json::exception&) {
      }
    }
    if (res->status >= 200 && res->status < 300) {
      if (res->body.empty()) return json::object();
      if (!parsed) {
        return Status::Corruption("the daemon's answer to " + method + " " + path + " is not JSON");
      }
      return body;
    }
    Status error = StatusFromHttp(res->status, parsed ? res->body : "", method + " " + path);
    if (res->status != 401) return error;
    return Status(error.code(),
                  error.reason() +
                      " (pass --token-file DATA/token, the daemon's --data directory's token file, "
                      "or set SANDSWIM_TOKEN)",
                  error.field());
  }

  ClientOptions options_;
  std::unique_ptr<httplib::Client> client_;
  httplib::Client& http_ = *client_;
  std::string live_etag_;  // of the last board (Live), and the board itself
  json live_last_;
};

}  // namespace

Result<ClientOptions> ResolveClientOptions(const std::string& server_flag, const std::string& token_file_flag,
                                           const std::function<const char*(const char*)>& getenv,
                                           const std::string& tls_fingerprint_flag, const std::string& tls_ca_flag) {
  ClientOptions options;
  std::string field = "--server";
  std::string url = server_flag;
  if (url.empty()) {
    const char* env = getenv("SANDSWIM_SERVER");
    if (env != nullptr && *env != '\0') {
      url = env;
      field = "SANDSWIM_SERVER";
    }
  }
  if (url.empty()) url = kDefaultServer;
  while (url.size() > 7 && url.back() == '/') url.pop_back();
  static const std::regex kUrl(R"((https?)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)(:[0-9]{1,5})?)");
  std::smatch parts;
  if (!std::regex_match(url, parts, kUrl)) {
    return Status::InvalidArgument(field, "expected http://HOST:PORT or https://HOST:PORT (e.g. " +
                                              std::string(kDefaultServer) + "), got \"" + url + "\"");
  }
  options.server = url;
  const std::string host = parts[2].str();

  auto token = LoadClientToken(token_file_flag, host, getenv);
  if (!token.ok()) return token.status();
  options.token = *token;
  auto tls = ResolveTlsTrust(tls_fingerprint_flag, tls_ca_flag, getenv);
  if (!tls.ok()) return tls.status();
  options.tls = *tls;
  const std::string own_cert = SelfSignedCertificate(DataDir(kDefaultDataDir).Tls());
  if (parts[1].str() == "https" && tls->fingerprint.empty() && tls->ca_file.empty() && IsLoopbackHost(host) &&
      access(own_cert.c_str(), R_OK) == 0) {
    auto pinned = CertificateFingerprint(own_cert);
    if (!pinned.ok()) return Status::InvalidArgument("--tls-fingerprint", pinned.status().reason());
    options.tls.fingerprint = *pinned;
  }
  return options;
}

std::unique_ptr<DaemonClient> NewDaemonClient(const ClientOptions& options) {
  return std::make_unique<HttpDaemonClient>(options);
}

}  // namespace sandswim::cli
