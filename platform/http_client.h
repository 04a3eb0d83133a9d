// HTTP client: the one way the CLI and the worker speak to the daemon over HTTP, and the one
// table that turns the daemon's answers into Status values.
//
// ClientOptions says where the daemon is and how long to wait; NewHttpClient() makes a cpp-httplib
// client from them (timeouts, TCP_NODELAY, "Authorization: Bearer <token>" when a token is set).
// StatusFromHttp() reads a non-2xx answer: its code from the table below, its reason the
// problem+json "detail" (which already names the field), else "HTTP N for WHAT" and the start of
// the body; the problem's "field" is kept as the Status field.
//
//   HTTP            Status                  who sees it
//   400, other 4xx  kInvalidArgument        a request the daemon refused
//   401, 403        kUnauthenticated        no or a wrong token
//   404             kNotFound
//   409             kConflict               a lease lost, an idempotency key reused
//   413             kResourceExhausted      a body too large
//   422             kFailedPrecondition     a valid request the daemon cannot do (a point the scale cannot take)
//   500, other 5xx  kInternal               the daemon failed (its disk, its database)
//   502, 503, 504   kUnavailable            the daemon (or a proxy before it) cannot answer now
//   no answer       kUnavailable            nothing listens, or the connection broke
// Both kinds of 5xx are the daemon's trouble, not the request's: DaemonTrouble() says so, and the
// worker retries its completions through them (workers/client.h).
//
// Thread safety: free functions; one httplib::Client per thread.
#ifndef SANDSWIM_PLATFORM_HTTP_CLIENT_H_
#define SANDSWIM_PLATFORM_HTTP_CLIENT_H_

#include <memory>
#include <string>

#include "core/status.h"
#include "platform/tls.h"

namespace httplib {
class Client;
}

namespace sandswim {

inline constexpr const char* kDefaultServer = "http://127.0.0.1:8640";

struct ClientOptions {
  std::string server = kDefaultServer;  // "http://HOST:PORT" or "https://HOST:PORT"
  std::string token;                    // bearer token; "" : no Authorization header
  TlsTrust tls;                         // for https: how the daemon's certificate is checked (platform/tls.h)
  double connect_timeout_s = 3;
  double read_timeout_s = 60;
  double retry_for_s = 3600;  // how long the worker's retried calls keep trying
};

// The table above, for an HTTP status outside 2xx.
StatusCode StatusCodeForHttp(int http_status);

// A non-2xx answer as a Status (see the top of this file). `what` names the call ("POST
// /api/v1/leases") for answers without a problem document.
Status StatusFromHttp(int http_status, const std::string& body, const std::string& what);

// True for the daemon's own trouble (kUnavailable, kInternal): asking again later may succeed.
bool DaemonTrouble(const Status& status);

// A client for options.server with the options' timeouts and token, and for https:// the
// options' TLS trust.
// REQUIRES: options.server starts with "http://" or "https://".
std::unique_ptr<httplib::Client> NewHttpClient(const ClientOptions& options);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_HTTP_CLIENT_H_
