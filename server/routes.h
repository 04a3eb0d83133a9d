// Routes: the REST API of sandswimd (/api/v1, /healthz, /metrics) over cpp-httplib. This is the
// only server file, with the server it runs on (guarded_http_server.h), that includes httplib.h;
// everything else speaks Status and values.
//
// Every route stands in one table (RouteTable(), in routes.cc, read top to bottom): method, path
// in OpenAPI form ("/api/v1/sweeps/{id}"), who may call it, what body it takes, and its handler.
// schema/openapi.json describes exactly these routes (a test keeps the two equal). Handlers parse
// the request, call Store / LeaseQueue / Submit, and render; they hold no business logic.
//
// Errors are RFC 9457 application/problem+json: {"type","title","status","detail","field"}, with
// the HTTP status from one table (HttpStatusFor, platform/http_status.h). An exception handler and an error handler are
// the backstop, so nothing a client sends produces anything but a problem document.
//
// Before a route runs (server/request_policy.h): a Host header that does not name this daemon is
// refused (421, every path); a request that changes state (POST, PUT) from a web page of another
// site is refused (403), and one whose route takes JSON must say Content-Type: application/json
// (415). No GET changes state. OPTIONS answers 204 with Allow and no CORS approval. Every response
// carries Content-Security-Policy (default-src 'self'; frame-ancestors 'none'; a stricter one with
// inline styles for the HTML report and SVG figures), X-Frame-Options DENY, X-Content-Type-Options
// nosniff and Referrer-Policy no-referrer. A 5xx names no file path (the log does).
//
// Auth: when Deps::token is non-empty, every route but the public ones (/healthz, the OpenAPI
// document, the dashboard's files) needs "Authorization: Bearer <token>" (401 otherwise); reads
// (GET) may carry it as ?access_token= instead (what the dashboard's images and links do), and
// need none when Deps::public_reads. Wrong tokens are logged and slowed per peer
// (FailedAuthThrottle; 429 when too many wait at once); a correct token is never slowed.
// Body limits: JSON bodies at most Deps::max_json_body bytes, bed restart uploads at most
// Deps::max_restart_body (streamed to a file under data_dir); past the limit: 413.
//
// Ownership: Deps points at objects the caller owns; they must outlive the server.
// Thread safety: handlers run on httplib's thread pool; Store and LeaseQueue are thread-safe.
#ifndef SANDSWIM_SERVER_ROUTES_H_
#define SANDSWIM_SERVER_ROUTES_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "platform/clock.h"
#include "platform/token.h"
#include "server/connection_limits.h"
#include "server/jobs/lease_queue.h"
#include "server/request_policy.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"

namespace httplib {
class Server;
}

namespace sandswim {

inline constexpr size_t kMaxJsonBodyBytes = size_t{1} << 20;     // 1 MiB
inline constexpr size_t kMaxRestartBodyBytes = size_t{2} << 30;  // 2 GiB
inline constexpr int kDefaultPort = 8640;

class LiveFeed;
class PlotRenderer;

struct Deps {
  Store* store = nullptr;
  LeaseQueue* leases = nullptr;
  Clock* clock = nullptr;
  std::string data_dir;        // beds' restart files and upload temp files live under it
  std::string engine_version;  // enters every content key (Submit)
  std::string token;           // bearer token; empty: no auth
  bool public_reads = false;   // reads need no token (--public-reads)
  // Which Host headers name this daemon; ApiServer::Bind fills in the address and port it got.
  HostPolicy host_policy;
  size_t max_json_body = kMaxJsonBodyBytes;
  size_t max_restart_body = kMaxRestartBodyBytes;
  int64_t max_queued_runs = kMaxQueuedRuns;  // submissions past it: 503 (server/jobs/submission.h)
  // Draws figures not drawn before (server/analysis/plot_renderer.h): sandswimd's runs sandswim-render, a
  // process of its own, so that a plotting error cannot end the daemon. nullptr: in this process.
  PlotRenderer* renderer = nullptr;
  // The dashboard's live snapshots and trails (server/dashboard/live_feed.h); nullptr: /api/v1/live* answer 503.
  LiveFeed* live = nullptr;
  // Engines this daemon knows will work (its local workers): the ETA spreads work over at least
  // this many (server/store/cost_model.h ReadEta), more when more are in flight.
  int engine_slots = 0;
};

// Who may call a route when a token is configured.
enum class Access {
  kPublic,  // always open (/healthz, /api/v1/openapi.json)
  kRead,    // needs the token, unless Deps::public_reads
  kWrite,   // needs the token
  kWorker,  // needs the token (the worker protocol)
};

// What a route reads from the request body.
enum class BodyKind { kNone, kJson, kRestart };

struct RouteInfo {
  std::string method;  // "GET", "POST", "PUT"
  std::string path;    // OpenAPI form: "/api/v1/sweeps/{id}"
  Access access;
  BodyKind body;
};

// Every route RegisterRoutes() installs, in table order.
std::vector<RouteInfo> RouteTable();

// Installs the routes, the problem+json error and exception handlers, auth and body limits.
void RegisterRoutes(httplib::Server& server, Deps& deps);

// Scratch directories under DATA hold only what a request in flight writes, removed when it ends:
// POST /api/v1/backup's copy (DATA/backups/) and an upload's body before it is checked and stored
// (DATA/uploads/: bed restarts, snapshots). A daemon that died mid-request leaves its file there:
// the next start empties both, returning how many files it removed.
std::string BackupDir(const std::string& data_dir);
std::string UploadDir(const std::string& data_dir);
Result<int> ClearScratchDirs(const std::string& data_dir);

// The RFC 9457 body for a Status: {"type","title","status","detail","field"}.
nlohmann::json ProblemFor(const Status& status, int http_status);

// "HOST:PORT" (or "[v6]:PORT", or ":PORT" for 127.0.0.1). Port 0 asks for an ephemeral port.
struct ListenAddress {
  std::string host;
  int port = kDefaultPort;
};
Result<ListenAddress> ParseListenAddress(const std::string& text);
// Refuses a non-loopback address without a token, or without TLS unless `plain_http_ok`
// (--plain-http: a TLS proxy or a private network in front), field "--listen"; IsLoopbackHost is
// platform/token.h's.
Status CheckListenPolicy(const ListenAddress& address, bool have_token, bool tls = false, bool plain_http_ok = false);

class GuardedHttpServer;  // server/guarded_http_server.h

// The daemon's HTTP server: owns the httplib::Server so main.cc never sees httplib. Clients are
// held to `limits` (server/guarded_http_server.h); the worker protocol and /healthz are the
// requests its reserved threads serve.
class ApiServer {
 public:
  explicit ApiServer(Deps deps, ConnectionLimits limits = {});
  ~ApiServer();
  ApiServer(const ApiServer&) = delete;
  ApiServer& operator=(const ApiServer&) = delete;

  // Serves HTTPS with these PEM files (server/guarded_http_server.h SetTls). Before Bind().
  Status UseTls(const std::string& cert_file, const std::string& key_file);
  // Binds and listens; returns the bound port (the real one when address.port is 0).
  Result<int> Bind(const ListenAddress& address);
  // Serves until Stop(). REQUIRES: Bind() succeeded.
  void Serve();
  // Safe from any thread (and repeatedly); Serve() returns soon after.
  void Stop();

 private:
  Deps deps_;
  std::unique_ptr<GuardedHttpServer> server_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ROUTES_H_
