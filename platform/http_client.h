// HTTP client: the one way the CLI and the worker speak to the daemon over HTTP, and the one
// table that turns the daemon's answers into Status values.
//
// ClientOptions says where the daemon is and how long to wait; NewHttpClient() makes a cpp-httplib
// client from them (timeouts, TCP_NODELAY, "Authorization: Bearer <token>" when a token is set).
// StatusFromHttp() reads a non-2xx answer: its code from the problem's type, else its HTTP status
// (platform/http_status.h holds that one table, both ways), its reason the problem+json "detail"
// without the "FIELD: " the daemon starts it with, else "HTTP N for WHAT" and the start of the
// body; the problem's "field" is kept as the Status field (so Status::ToString() and the CLI name
// the field once). No answer at all is kUnavailable (nothing listens, or the
// connection broke).
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


// A non-2xx answer as a Status (see the top of this file). `what` names the call ("POST
// /api/v1/leases") for answers without a problem document.
Status StatusFromHttp(int http_status, const std::string& body, const std::string& what);

// True for the daemon's own trouble (a code it answers with a 5xx: kUnavailable, kInternal, kIOError,
// kCorruption): asking again later may succeed.
bool DaemonTrouble(const Status& status);

// A client for options.server with the options' timeouts and token, and for https:// the
// options' TLS trust.
// REQUIRES: options.server starts with "http://" or "https://".
std::unique_ptr<httplib::Client> NewHttpClient(const ClientOptions& options);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_HTTP_CLIENT_H_
