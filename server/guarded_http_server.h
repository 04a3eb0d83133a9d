// An HTTP server whose clients cannot hold its threads by being slow.
//
// The HTTP library serves a connection on one pool thread for as long as the connection lasts, and
// it times a read only per recv(): a client that sends its request a byte a second holds a thread
// for ever, and as many such clients as the pool has threads (192) leave every worker's heartbeat
// queued behind them. GuardedHttpServer serves connections with the library's own request handling,
// but reads each request through a stream with deadlines:
//  - the request head (request line and headers) must all arrive within `head_s` of its first byte;
//  - a body must arrive within `body_grace_s` plus its Content-Length at `min_body_bytes_per_s`
//    (a chunked body, whose length is not known, within `body_grace_s`); a handler ends the body's
//    deadline when it has read the body (BodyReceived());
//  - a connection that says nothing is closed after `idle_s`, between requests as before the first.
// A connection past a deadline is closed, and counted (slow_clients_closed()). What a handler does
// and how long a response streams (the live feed's events) is not limited here; a response's
// writes have the library's write timeout.
//
// Thread safety: as httplib::Server. BodyReceived() is called on the thread serving the request.
#ifndef SANDSWIM_SERVER_GUARDED_HTTP_SERVER_H_
#define SANDSWIM_SERVER_GUARDED_HTTP_SERVER_H_

#include <atomic>
#include <cstdint>

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

  // The handler serving this thread's request has read its body: its deadline ends.
  static void BodyReceived();

  // Connections closed because a request head or body came too slowly.
  int64_t slow_clients_closed() const { return slow_closed_.load(); }

 private:
  bool process_and_close_socket(socket_t sock) override;

  ConnectionLimits limits_;
  std::atomic<int64_t> slow_closed_{0};
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_GUARDED_HTTP_SERVER_H_
