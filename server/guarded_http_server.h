// An HTTP server whose clients cannot hold its threads by being slow.
//
// The HTTP library serves a connection on one pool thread for as long as the connection lasts, and
// it times a read only per recv(): a client that sends its request a byte a second holds a thread
// for ever, and as many such clients as the pool has threads (192) leave every worker's heartbeat
// queued behind them. GuardedHttpServer serves connections with the library's own request handling,
// but reads each request through a stream with deadlines:
//  - the request head (request line and headers) must all arrive within `head_s` of its first byte;
//  - a body must arrive within `body_grace_s` plus its Content-Length at `min_body_bytes_per_s`
//    (a chunked body, or one without a length, read to the end, within `body_grace_s`);
//  - a connection that says nothing is closed after `idle_s`, between requests as before the first.
// A connection past a deadline is closed, and counted (slow_clients_closed()). What a handler does
// and how long a response streams (the live feed's events) is not limited here (deadlines are
// checked when the server reads); a response's writes have the library's write timeout.
//
// Thread safety: as httplib::Server.
#ifndef SANDSWIM_SERVER_GUARDED_HTTP_SERVER_H_
#define SANDSWIM_SERVER_GUARDED_HTTP_SERVER_H_

#include <atomic>
#include <chrono>
#include <cstdint>
#include <optional>

#include <httplib.h>

namespace sandswim {

struct ConnectionLimits {
  double idle_s = 5;       // silence allowed before a request starts (the library's keep-alive timeout)
  double head_s = 10;      // a request head, from its first byte to its blank line
  double body_grace_s = 30;
  double min_body_bytes_per_s = 256 * 1024;  // a 100 MiB bed restart may take 30 s + 400 s
  double read_timeout_s = 60;                // one read that receives nothing
  double write_timeout_s = 5;                // one write the client does not take (the library's default)
};

class GuardedHttpServer : public httplib::Server {
 public:
  explicit GuardedHttpServer(ConnectionLimits limits = {}) : limits_(limits) {}

  // Lets `n` connections wait to be accepted, after bind_to_port() or bind_to_any_port(): the HTTP
  // library listens with a backlog of 5, and a burst of more clients (workers finishing together, a
  // dashboard's requests) would otherwise wait a second for their SYN to be sent again.
  bool SetBacklog(int n);

  // Serves one accepted connection on this thread until it closes, then closes it (what the
  // accept loop runs on a pool thread; the request fuzz target hands it one end of a socketpair).
  bool ServeConnection(socket_t sock);

  // Connections closed because a request head or body came too slowly.
  int64_t slow_clients_closed() const { return slow_closed_.load(); }

 private:
  bool process_and_close_socket(socket_t sock) override;
  // When the body of `req` (its head just read) must have arrived; nullopt: it has none.
  std::optional<std::chrono::steady_clock::time_point> BodyDeadline(const httplib::Request& req) const;

  ConnectionLimits limits_;
  std::atomic<int64_t> slow_closed_{0};
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_GUARDED_HTTP_SERVER_H_
