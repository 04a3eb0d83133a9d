// An HTTP server whose clients cannot hold its threads by being slow, idle or many.
//
// The HTTP library serves a connection on one pool thread for as long as the connection lasts, and
// it times a read only per recv(): a client that sends its request a byte a second holds a thread
// for ever, and as many such clients as the pool has threads leave every worker's heartbeat queued
// behind them; so do as many keep-alive clients that ask for /healthz every few seconds.
// GuardedHttpServer keeps the library's request handling but owns the connections:
//  - Between requests a connection holds no thread: it is parked with every other idle connection
//    in one poller thread, which also reads its next request head. A connection gets a thread only
//    once a whole request head has arrived, for that one request, then is parked again.
//  - Deadlines: the request head must all arrive within `head_s` of its first byte; a body within
//    `body_grace_s` plus its Content-Length at `min_body_bytes_per_s` (a chunked body, or one
//    without a length, read to the end, within `body_grace_s`); a connection that says nothing is
//    closed after `idle_s`, between requests as before the first. A connection past a deadline is
//    closed, and counted (slow_clients_closed()).
//  - Threads: `threads` serve requests; `reserved_threads` more serve only the requests that
//    SetReserved()'s predicate names (the worker protocol, /healthz), so that readers -- however
//    many and however slow their handlers -- cannot take the last thread from a worker. A request
//    that is not reserved while `threads` such requests are in flight is answered 503 with
//    Retry-After at once, and its connection closed.
//  - Per client (ClientKey of the peer address, server/http/request_policy.h: an IPv4 address, an IPv6
//    /64, every loopback address together unless `loopback_clients_apart`): past
//    `max_connections_per_client` open connections, a new
//    connection is served only for reserved requests (one request, then closed) and for
//    authenticated ones (SetAuthenticated: the daemon's token); any other request on it is answered
//    429 with Retry-After and the connection closed. A connection that has carried an authenticated
//    request no longer counts against its client: the cap counts the connections of those who have
//    not shown the token, so that a local user without it (all of loopback is one client) cannot
//    lock the token's holders out by holding the cap. Workers on the same host as
//    a greedy client keep their heartbeats that way. Past `max_connections` in all, a new connection
//    is closed at once, except into the reserve: the last ReserveSlots() before it (up to 64) are
//    admitted as restricted connections, for whoever comes, and belong to no client. When every
//    slot is taken, a new connection takes the slot of the reserve's connection that has waited
//    longest without a whole request (the one its client -- the one holding most of the reserve --
//    opened first): a crowd that holds the reserve with silent or slow connections, however many
//    addresses it has and even when it is the workers' own client (all of loopback is one), cannot
//    keep a worker's next connection out; a reserve connection that has sent its request is not
//    taken. What it may ask is the predicate's (SetReserved: the worker protocol with the right
//    token, and /healthz) or any authenticated request. A slot is taken from a connection that has
//    not shown the token before one that has.
//  - A request head larger than the 16 KiB buffer is answered 431 by the poller (no thread) and the
//    connection drained and closed.
//  - TLS (SetTls): the handshake is stepped by the poller as its bytes arrive, under the head's deadline.
//  - Refusals (a slow head or body, a head past the buffer, a connection shut out) are logged at
//    most once per client and 10 s, with a count (RefusalLog, server/http/request_policy.h).
//  - Keep-alive: a connection serves at most `max_requests_per_connection` requests; while more
//    than half of `threads` are in flight, responses carry "Connection: close".
// What a handler does and how long a response streams is not limited here (deadlines are checked
// when the server reads); a response's writes have `write_timeout_s` each.
//
// Thread safety: as httplib::Server. SetReserved() before listening.
#ifndef SANDSWIM_SERVER_HTTP_GUARDED_HTTP_SERVER_H_
#define SANDSWIM_SERVER_HTTP_GUARDED_HTTP_SERVER_H_

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

#include "platform/clock.h"
#include "server/http/connection_limits.h"
#include "server/http/request_policy.h"

namespace sandswim {


class GuardedHttpServer : public httplib::Server {
 public:
  explicit GuardedHttpServer(ConnectionLimits limits = {});
  ~GuardedHttpServer() override;

  // Names the requests the reserved threads and the reserve's connections serve (a predicate on a
  // request whose head has arrived: its method, path and headers; no body). Unset: none.
  void SetReserved(std::function<bool(const httplib::Request& head)> reserved);
  // Names the requests that carry the daemon's own credential (a predicate on a request's head, as
  // SetReserved's): served past the client's connection cap and in the reserve, and their
  // connection counted apart from its client's from then on. Unset: none.
  void SetAuthenticated(std::function<bool(const httplib::Request& head)> authenticated);
  // Headers every answer the server writes itself (429, 431, 503) carries, as the routes' do.
  void SetOwnHeaders(std::vector<std::pair<std::string, std::string>> headers);
  // Renders the body of a refusal (429, 503) as the routes' problem documents are rendered; unset:
  // the detail as plain text.
  void SetRefusalBody(std::function<std::string(int http_status, const std::string& detail)> body);

  // Serves HTTPS with this certificate (chain) and key, PEM files; false with *error when they
  // cannot be used. Before listening. The TLS handshake is read by the poller like a request head
  // and within the same deadline (`head_s` from its first byte): a slow handshake holds no thread.
  bool SetTls(const std::string& cert_file, const std::string& key_file, std::string* error);

  // Lets `n` connections wait to be accepted, after bind_to_port() or bind_to_any_port(): the HTTP
  // library listens with a backlog of 5, and a burst of more clients (workers finishing together, a
  // dashboard's requests) would otherwise wait a second for their SYN to be sent again.
  bool SetBacklog(int n);

  // Serves one accepted connection on this thread until it closes, then closes it (the request
  // fuzz target hands it one end of a socketpair). Not parked, not counted per client.
  bool ServeConnection(socket_t sock);

  // Connections closed because a request head or body came too slowly.
  int64_t slow_clients_closed() const { return slow_closed_.load(); }
  // Requests answered 503 because every thread for them was taken, or 429 because their client
  // had too many connections open (or 431: a request head past the buffer).
  int64_t busy_refused() const { return busy_refused_.load(); }
  int64_t client_refused() const { return client_refused_.load(); }
  // Reserve connections closed to give their slot to a newcomer (waiting without a whole request).
  int64_t reserve_taken() const;
  // Open connections (parked, queued or served).
  int open_connections() const;

  struct Connection;  // one accepted socket, its buffered bytes and its place in the limits

 private:
  class Queue;
  friend class Queue;
  enum class After { kPark, kDrain, kClose };

  bool process_and_close_socket(socket_t sock) override;
  // When the body of `req` (its head just read) must have arrived; nullopt: it has none.
  std::optional<std::chrono::steady_clock::time_point> BodyDeadline(const httplib::Request& req) const;

  void Admit(socket_t sock);                 // the accept loop's thread: count, then park
  After ServeOne(Connection& c);  // one request, on a serving thread
  void Park(std::unique_ptr<Connection> c);  // wait for its next head in the poller
  void Enqueue(std::unique_ptr<Connection> c);
  void Close(std::unique_ptr<Connection> c);
  // Takes a parked reserve connection out of the poller to give its slot to a newcomer: of the
  // client holding most of the reserve, the one opened first. REQUIRES mu_; null when none waits.
  std::unique_ptr<Connection> TakeReserveSlotLocked();
  void UncountLocked(Connection& c);  // REQUIRES mu_
  // `c` has carried an authenticated request: it leaves its client's count (and, outside the
  // reserve, its restriction). Takes mu_.
  void Authenticated(Connection& c);
  void PollLoop();
  void ServeLoop();
  void StartThreads();
  void StopThreads();  // the accept loop has ended: every connection is closed

  ConnectionLimits limits_;
  ssl_ctx_st* tls_ = nullptr;  // SSL_CTX, owned; null: plain HTTP
  std::function<bool(const httplib::Request&)> reserved_;
  std::function<bool(const httplib::Request&)> authenticated_;
  std::string own_headers_;  // "Name: value\r\n" lines
  std::function<std::string(int, const std::string&)> refusal_body_;
  std::atomic<int64_t> slow_closed_{0}, busy_refused_{0}, client_refused_{0};
  std::atomic<int> readers_in_flight_{0};
  SystemClock clock_;
  RefusalLog refusals_{&clock_};  // slow, oversized or shut-out connections: a line per client and interval

  mutable std::mutex mu_;  // guards everything below
  std::condition_variable work_ready_;
  bool stopping_ = false;
  int epoll_fd_ = -1;
  int wake_fd_ = -1;  // an eventfd that ends the poller's wait
  std::map<int, std::unique_ptr<Connection>> parked_;
  std::deque<std::unique_ptr<Connection>> ready_;
  std::map<std::string, int> per_client_;  // by ClientKey (server/http/request_policy.h)
  std::map<std::string, int> in_reserve_;  // connections in the reserved slots, by client
  // The last open-connection slots, admitted only for reserved requests.
  int ReserveSlots() const { return std::max(4, std::min(64, max_open_ / 8)); }
  int64_t reserve_taken_ = 0;  // reserve connections whose slot a newcomer took
  int open_ = 0;
  int max_open_ = 0;
  std::thread poller_;
  std::vector<std::thread> servers_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_GUARDED_HTTP_SERVER_H_
