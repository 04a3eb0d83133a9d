// ConnectionLimits: what one HTTP client may hold of the daemon -- its deadlines, threads and
// connections -- as GuardedHttpServer (server/http/guarded_http_server.h) enforces them. A header of its
// own so that sandswimd's flags can set them without including the HTTP library.
#ifndef SANDSWIM_SERVER_HTTP_CONNECTION_LIMITS_H_
#define SANDSWIM_SERVER_HTTP_CONNECTION_LIMITS_H_

namespace sandswim {

struct ConnectionLimits {
  double idle_s = 5;       // silence allowed before a request starts (the library's keep-alive timeout)
  double head_s = 10;      // a request head, from its first byte to its blank line
  double body_grace_s = 30;
  double min_body_bytes_per_s = 256 * 1024;  // a 100 MiB bed restart may take 30 s + 400 s
  double read_timeout_s = 60;                // one read that receives nothing
  double write_timeout_s = 5;                // one write the client does not take (the library's default)
  int threads = 192;                         // requests of any kind in flight at once
  int reserved_threads = 16;                 // more, for reserved requests only
  int max_connections_per_client = 64;       // open connections per client before it is restricted
  bool loopback_clients_apart = false;       // each loopback address its own client (else all one: ClientKey)
  int max_connections = 4096;                // open connections in all (and at most the fd limit allows)
  int max_requests_per_connection = 1000;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_CONNECTION_LIMITS_H_
