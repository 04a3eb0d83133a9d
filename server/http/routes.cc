#include "server/http/routes.h"

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
#include "server/dashboard/help_files.h"
#include "server/analysis/figures.h"
#include "server/http/call.h"
#include "server/http/guarded_http_server.h"
#include "server/dashboard/live_feed.h"
#include "server/analysis/report.h"
#include "server/store/schema_files.h"
#include "server/jobs/submission.h"

namespace sandswim {
namespace routes {
namespace {

// ---- The route table ---------------------------------------------------------------------------

// Every route, resource by resource.
const std::vector<Route>& AllRoutes() {
  static const std::vector<Route> kAll = [] {
    std::vector<Route> all;
    for (const auto* table : {&SweepsRoutes(), &CampaignsRoutes(), &FiguresRoutes(), &LiveRoutes(), &WorkerRoutes(),
                              &OperationsRoutes()}) {
      all.insert(all.end(), table->begin(), table->end());
    }
    return all;
  }();
  return kAll;
}

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
    for (const Route& r : AllRoutes()) v.push_back({&r, std::regex(PathRegex(r.path))});
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
  if (throttle.Failed(ClientKey(req.remote_addr, deps.loopback_clients_apart), req.method + " " + req.path) == FailedAuthThrottle::Verdict::kBusy) {
    return Refusal{
        Status(StatusCode::kResourceExhausted,
               "too many requests with a wrong token from " + req.remote_addr + "; try again later", "Authorization"),
        429};
  }
  return Refusal{Status(StatusCode::kUnauthenticated, "the bearer token is not the daemon's token", "Authorization"),
                 401};
}

// Empty when the request may reach its route; otherwise why not (server/http/request_policy.h).
std::optional<Refusal> CheckRequest(const Deps& deps, const Route& route, const httplib::Request& req,
                                    FailedAuthThrottle& throttle, RefusalLog& refusals) {
  if (std::string_view(route.method) != "GET") {
    if (auto cross = CrossSiteRefusal(deps.host_policy, req.get_header_value("Origin"),
                                      req.get_header_value("Sec-Fetch-Site"))) {
      refusals.Refused(ClientKey(req.remote_addr, deps.loopback_clients_apart), "cross-site", [&] {
        return "refused " + req.method + " " + req.path + " from " + req.remote_addr + ": " + cross->reason();
      });
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
  std::optional<Refusal> denied = CheckRequest(deps, route, req, *counters->auth_failures, *counters->refusals);
  if (denied && denied->http_status == 429) res.set_header("Retry-After", "1");
  if (denied) {
    // Not a byte of a refused body is read on a request thread (a client sending it a byte a
    // minute would hold the thread for hours): the answer goes at once, and the server drains what
    // the client still sends for a moment before closing (server/http/guarded_http_server.cc).
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
}  // namespace routes

using routes::AllRoutes;
using routes::CompiledRoute;
using routes::CompiledRoutes;
using routes::DispatchCounted;
using routes::FindRoute;
using routes::HttpCounters;
using routes::HttpTitle;
using routes::json;
using routes::kDrainCapBytes;
using routes::kProblemType;
using routes::ParseInt;
using routes::PathRegex;
using routes::Route;
using routes::SendProblem;

// ---- Public ------------------------------------------------------------------------------------

std::vector<RouteInfo> RouteTable() {
  std::vector<RouteInfo> table;
  for (const Route& r : AllRoutes()) table.push_back({r.method, r.path, r.access, r.body});
  return table;
}

json ProblemFor(const Status& status, int http_status) {
  return {{"type", ProblemTypeFor(status.code())},
          {"title", HttpTitle(http_status)},
          {"status", http_status},
          {"detail", status.field().empty() ? status.reason() : status.field() + ": " + status.reason()},
          {"field", status.field()}};
}

namespace {

using Counters = std::shared_ptr<HttpCounters>;

// Every route of the table, each through the dispatcher (auth, body limits, counting).
void RegisterTable(httplib::Server& server, Deps* d, const Counters& counters) {
  for (const Route& route : AllRoutes()) {
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
    else if (method == "DELETE")
      server.Delete(pattern, plain);
  }
}

void RegisterDashboard(httplib::Server& server, const Counters& counters) {
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
  server.Get("/new-campaign", page);
  server.Get(R"(/api-reference(/[a-z-]{1,40})?)", page);  // the REST API, rendered from /api/v1/openapi.json
  // The docs' help pages: the page at /help/docs/..., the Markdown it renders under /help-files/.
  server.Get(R"(/help(/docs/[A-Za-z0-9_./-]{1,200}\.md)?)", page);
  server.Get(R"(/help-files/(docs/[A-Za-z0-9_./-]{1,200}\.md))",
             [counters](const httplib::Request& req, httplib::Response& res) {
               const std::string name = req.matches[1].str();
               std::optional<std::string_view> bytes = HelpFile(name);
               if (!bytes) {
                 SendProblem(res, Status::NotFound("no docs page \"" + name + "\""));
                 counters->Count(404);
                 return;
               }
               res.set_header("Cache-Control", "no-cache");
               res.status = 200;
               res.set_content(bytes->data(), bytes->size(), "text/markdown; charset=utf-8");
               counters->Count(200);
             });
  server.Get(R"(/campaigns(/[A-Za-z0-9._-]{1,64}(/edit)?)?)", page);
  server.Get(R"(/(campaign-runs|sweeps|runs|beds)(/[0-9]+)?)", page);
  server.Get(R"(/ui/([A-Za-z0-9_-][A-Za-z0-9._-]*))",
             [dashboard_file](const httplib::Request& req, httplib::Response& res) {
               dashboard_file(req.matches[1].str(), res);
             });
}

void RegisterOptions(httplib::Server& server, const Counters& counters) {
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
}

void RefuseBeforeRouting(httplib::Server& server, Deps* d, const Counters& counters) {
  // Refuse a Host that does not name this daemon (DNS rebinding), and what cannot be drained,
  // before any byte of the body is read.
  server.set_pre_routing_handler([d, counters](const httplib::Request& req, httplib::Response& res) {
    if (!HostAllowed(d->host_policy, req.get_header_value("Host"))) {
      counters->refusals->Refused(ClientKey(req.remote_addr, d->loopback_clients_apart), "host", [&] {
        return "refused " + req.method + " " + req.path + " from " + req.remote_addr + ": Host \"" +
               req.get_header_value("Host") + "\" does not name this daemon";
      });
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
}

void RegisterBackstops(httplib::Server& server, const Counters& counters) {
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
    for (const auto& [name, value] : SecurityHeaders()) {
      if (name != "Content-Security-Policy" || !res.has_header(name)) res.set_header(name, value);
    }
  });

  server.set_logger([](const httplib::Request& req, const httplib::Response& res) {
    spdlog::debug("{} {} -> {}", req.method, req.path, res.status);
  });
}

}  // namespace

const std::vector<std::pair<std::string, std::string>>& SecurityHeaders() {
  static const std::vector<std::pair<std::string, std::string>> kHeaders = {
      {"Content-Security-Policy", "default-src 'self'; frame-ancestors 'none'"},  // a route may set a stricter one
      {"X-Frame-Options", "DENY"},
      {"X-Content-Type-Options", "nosniff"},
      {"Referrer-Policy", "no-referrer"},
  };
  return kHeaders;
}

void RegisterRoutes(httplib::Server& server, Deps& deps) {
  Deps* d = &deps;
  auto counters = std::make_shared<HttpCounters>();
  counters->auth_failures = std::make_unique<FailedAuthThrottle>(deps.clock, FailedAuthThrottle::Options{});
  counters->refusals = std::make_unique<RefusalLog>(deps.clock);
  RegisterTable(server, d, counters);
  RegisterDashboard(server, counters);
  RegisterOptions(server, counters);
  RefuseBeforeRouting(server, d, counters);
  server.set_payload_max_length(std::max(deps.max_restart_body, kDrainCapBytes) + 1);
  RegisterBackstops(server, counters);
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
// The worker protocol with the daemon's token (any, when it has none), and /healthz: what the
// reserved threads and the reserve's connections serve (server/http/guarded_http_server.h), so that
// no reader can cost a worker its lease. A worker call with a wrong or no token is an ordinary
// request (and is refused 401 there): a guesser holds no reserved thread while its failure is slowed.
// A request head whose Authorization header carries the daemon's token (none has it when the
// daemon has no token: then nobody has shown one).
bool CarriesToken(const std::string& token, const httplib::Request& head) {
  if (token.empty()) return false;
  const std::string header = head.get_header_value("Authorization");
  const std::string prefix = "Bearer ";
  if (header.rfind(prefix, 0) != 0 || header.size() - prefix.size() != token.size()) return false;
  return CRYPTO_memcmp(header.data() + prefix.size(), token.data(), token.size()) == 0;
}

bool IsReservedRequest(const std::string& token, const httplib::Request& head) {
  const Route* route = FindRoute(head.method, head.path);
  if (route == nullptr) return false;
  if (std::string_view(route->path) == "/healthz") return true;
  if (route->access != Access::kWorker) return false;
  return token.empty() || CarriesToken(token, head);
}
}  // namespace

// Slow, idle and greedy clients are held off by the server (server/http/guarded_http_server.h).
ApiServer::ApiServer(Deps deps, ConnectionLimits limits)
    : deps_(std::move(deps)), server_(std::make_unique<GuardedHttpServer>(limits)) {
  deps_.loopback_clients_apart = limits.loopback_clients_apart;  // one rule for "which client": the limits'
  server_->SetReserved([this](const httplib::Request& head) { return IsReservedRequest(deps_.token, head); });
  // The token's holders (the CLI, workers, scripts) are served past a crowd that has not shown it.
  server_->SetAuthenticated([this](const httplib::Request& head) { return CarriesToken(deps_.token, head); });
  server_->SetOwnHeaders(SecurityHeaders());
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
  deps_.host_policy.tls = true;  // before Serve(), as Bind's policy
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
