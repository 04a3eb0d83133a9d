// Routes: the REST API of sandswimd (/api/v1, /healthz, /metrics) over cpp-httplib. Only the http
// room (server/http/) includes httplib.h, and this header does not: main.cc and the other rooms
// speak Status and values.
//
// Every route stands in one table, a part per resource (sweep_routes.cc, campaign_routes.cc,
// figure_routes.cc, live_routes.cc, worker_routes.cc, operations_routes.cc; RouteTable() lists them
// all): method, path in OpenAPI form ("/api/v1/sweeps/{id}"), who may call it, what body it takes,
// and its handler (server/http/call.h Route).
// schema/openapi.json describes exactly these routes (a test keeps the two equal). Handlers parse
// the request, call Store / LeaseQueue / Submit, and render; they hold no business logic.
//
// Errors are RFC 9457 application/problem+json: {"type","title","status","detail","field"}, with
// the HTTP status from one table (HttpStatusFor, platform/http_status.h). An exception handler and an error handler are
// the backstop, so nothing a client sends produces anything but a problem document.
//
// Before a route runs (server/http/request_policy.h): a Host header that does not name this daemon is
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
// Deps::max_restart_body, and so are snapshot uploads (streamed to a file under DATA/uploads, then
// renamed into place by the lease queue); past the limit: 413.
//
// Ownership: Deps points at objects the caller owns; they must outlive the server.
// Thread safety: handlers run on httplib's thread pool; Store and LeaseQueue are thread-safe.
#ifndef SANDSWIM_SERVER_HTTP_ROUTES_H_
#define SANDSWIM_SERVER_HTTP_ROUTES_H_

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "platform/clock.h"
#include "platform/token.h"
#include "server/http/connection_limits.h"
#include "server/http/deps.h"
#include "server/jobs/lease_queue.h"
#include "server/http/request_policy.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"

namespace httplib {
class Server;
}

namespace sandswim {

struct RouteInfo {
  std::string method;  // "GET", "POST", "PUT"
  std::string path;    // OpenAPI form: "/api/v1/sweeps/{id}"
  Access access;
  BodyKind body;
};

// Every route RegisterRoutes() installs, in table order.
std::vector<RouteInfo> RouteTable();

// Installs the routes, the problem+json error and exception handlers, auth and body limits.
// The headers every answer carries, the routes' and the server's own refusals alike: no framing,
// no sniffing, no referrer, and only the daemon's own scripts, styles and images.
const std::vector<std::pair<std::string, std::string>>& SecurityHeaders();

void RegisterRoutes(httplib::Server& server, Deps& deps);

// Scratch directories under DATA hold only what a request in flight writes, removed when it ends:
// POST /api/v1/backup's copy (DATA/backups/) and an upload's body before it is checked and renamed into place
// (DATA/uploads/: bed restarts, snapshots). A daemon that died mid-request leaves its file there:
// the next start empties both, returning how many files it removed.
Result<int> ClearScratchDirs(const std::string& data_dir);


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

class GuardedHttpServer;  // server/http/guarded_http_server.h

// The daemon's HTTP server: owns the httplib::Server so main.cc never sees httplib. Clients are
// held to `limits` (server/http/guarded_http_server.h); the worker protocol and /healthz are the
// requests its reserved threads serve.
class ApiServer {
 public:
  explicit ApiServer(Deps deps, ConnectionLimits limits = {});
  ~ApiServer();
  ApiServer(const ApiServer&) = delete;
  ApiServer& operator=(const ApiServer&) = delete;

  // Serves HTTPS with these PEM files (server/http/guarded_http_server.h SetTls). Before Bind().
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

#endif  // SANDSWIM_SERVER_HTTP_ROUTES_H_
