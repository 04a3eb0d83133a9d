#include "server/http/guarded_http_server.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/resource.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include <openssl/err.h>
#include <openssl/ssl.h>
#include <spdlog/spdlog.h>

#include "server/http/request_policy.h"

namespace sandswim {

namespace {

using Steady = std::chrono::steady_clock;

Steady::duration Seconds(double s) { return std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(s)); }

// Waits until `fd` has `events` or `until` passes; true when it has them.
bool PollUntil(int fd, short events, Steady::time_point until) {
  for (;;) {
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(until - Steady::now()).count();  // past `until`
    if (left <= 0) return false;
    pollfd p{fd, events, 0};
    const int n = poll(&p, 1, static_cast<int>(std::min<int64_t>(left, 1000 * 1000)));
    if (n > 0) return true;
    if (n < 0 && errno != EINTR) return false;
  }
}

void AddressOf(int fd, bool peer, std::string& ip, int& port) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  const int rc = peer ? getpeername(fd, reinterpret_cast<sockaddr*>(&addr), &len)
                      : getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  if (rc != 0) return;
  char host[NI_MAXHOST], serv[NI_MAXSERV];
  if (getnameinfo(reinterpret_cast<sockaddr*>(&addr), len, host, sizeof host, serv, sizeof serv,
                  NI_NUMERICHOST | NI_NUMERICSERV) == 0) {
    ip = host;
    port = std::atoi(serv);
  }
}

// One connection's socket, read and written by the library's request handling, with the
// deadline of the part of a request now arriving (none while a handler works or a response
// streams). Between requests the poller fills its buffer (ReadAvailable) until a whole head is in.
//
// Over TLS (`ssl` set; its socket non-blocking) the same, through the TLS session: what arrives is
// decrypted into the buffer, and a read or write the session cannot finish yet waits on the socket.
class DeadlineStream final : public httplib::Stream {
 public:
  DeadlineStream(int fd, const ConnectionLimits& limits) : fd_(fd), limits_(limits) {}
  ~DeadlineStream() override {
    if (ssl_ != nullptr) SSL_free(ssl_);
  }
  void set_ssl(SSL* ssl) { ssl_ = ssl; }
  SSL* ssl() const { return ssl_; }

  void set_deadline(std::optional<Steady::time_point> d, const char* what) {
    deadline_ = d;
    what_ = what;
    missed_ = "";
  }
  // What missed its deadline ("" when nothing did).
  const char* missed() const { return missed_; }
  // Bytes received and not yet read.
  bool has_buffered() const { return begin_ < end_ || (ssl_ != nullptr && SSL_pending(ssl_) > 0); }
  // Bytes the library has read, in all.
  uint64_t consumed() const { return consumed_; }
  // Drops what has arrived, without waiting, adding its size to `*dropped`: false once the peer
  // closed (or the socket failed).
  bool Discard(uint64_t* dropped) {
    begin_ = end_ = 0;
    char sink[16 * 1024];
    for (;;) {
      const ssize_t n = recv(fd_, sink, sizeof sink, MSG_DONTWAIT);
      if (n > 0) {
        *dropped += static_cast<uint64_t>(n);
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
    }
  }
  bool full() const { return begin_ == 0 && end_ == sizeof buffer_; }
  // TLS: the bytes the session has decrypted and not handed out yet, into the buffer (the socket
  // will not say they are there).
  void TakePending() {
    while (ssl_ != nullptr && SSL_pending(ssl_) > 0 && ReadAvailable() > 0) {
    }
  }
  // Sends what fits without waiting (a refusal from the poller thread).
  void SendNow(const std::string& bytes) {
    if (ssl_ != nullptr) {
      (void)SSL_write(ssl_, bytes.data(), static_cast<int>(bytes.size()));
    } else {
      (void)send(fd_, bytes.data(), bytes.size(), MSG_DONTWAIT | MSG_NOSIGNAL);
    }
  }
  // Ends what this side sends: TLS's close_notify, then FIN.
  void ShutdownWrite() {
    if (ssl_ != nullptr) (void)SSL_shutdown(ssl_);
    shutdown(fd_, SHUT_WR);
  }
  // The buffer holds a request line and headers up to their blank line.
  bool has_whole_head() const {
    const std::string_view v(buffer_ + begin_, end_ - begin_);
    return v.find("\n\r\n") != std::string_view::npos || v.find("\n\n") != std::string_view::npos;
  }
  // Takes what has arrived without waiting: > 0 bytes taken, 0 the peer closed, < 0 nothing
  // (errno says why; EAGAIN: nothing yet).
  ssize_t ReadAvailable() {
    if (begin_ > 0) {
      std::copy(buffer_ + begin_, buffer_ + end_, buffer_);
      end_ -= begin_;
      begin_ = 0;
    }
    if (end_ == sizeof buffer_) {
      errno = ENOBUFS;
      return -1;
    }
    ssize_t n;
    if (ssl_ != nullptr) {
      n = TlsRead(buffer_ + end_, sizeof buffer_ - end_);
    } else {
      do n = recv(fd_, buffer_ + end_, sizeof buffer_ - end_, MSG_DONTWAIT);
      while (n < 0 && errno == EINTR);
    }
    if (n > 0) end_ += static_cast<size_t>(n);
    return n;
  }
  // TLS: one step of the server's handshake, without waiting. 1 done, 0 more bytes needed (or
  // room to send: *want_write), -1 failed.
  int Handshake(bool* want_write) {
    ERR_clear_error();
    const int r = SSL_do_handshake(ssl_);
    if (r == 1) return 1;
    const int e = SSL_get_error(ssl_, r);
    *want_write = e == SSL_ERROR_WANT_WRITE;
    return e == SSL_ERROR_WANT_READ || e == SSL_ERROR_WANT_WRITE ? 0 : -1;
  }

  bool is_readable() const override {
    return has_buffered() || PollUntil(fd_, POLLIN, ReadUntil());
  }
  bool is_writable() const override {
    if (!PollUntil(fd_, POLLOUT, Steady::now() + Seconds(limits_.write_timeout_s))) return false;
    // A socket the peer closed reads as readable with nothing to read.
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, 0) > 0) {
      char c;
      if (recv(fd_, &c, 1, MSG_PEEK | MSG_DONTWAIT) == 0) return false;
    }
    return true;
  }
  ssize_t read(char* ptr, size_t size) override {
    // Checked before every read, not only when one waits: a client dribbling bytes never waits.
    if (deadline_ && Steady::now() >= *deadline_) {
      missed_ = what_;
      return -1;
    }
    while (begin_ == end_) {
      if (!has_buffered() && !PollUntil(fd_, POLLIN, ReadUntil())) {
        if (deadline_ && Steady::now() >= *deadline_) missed_ = what_;
        return -1;
      }
      ssize_t n;
      if (ssl_ != nullptr) {
        n = TlsRead(buffer_, sizeof buffer_);
        if (n < 0 && errno == EAGAIN) continue;  // a part of a record: wait for the rest
      } else {
        do n = recv(fd_, buffer_, sizeof buffer_, 0);
        while (n < 0 && errno == EINTR);
      }
      if (n <= 0) return n;
      begin_ = 0;
      end_ = static_cast<size_t>(n);
    }
    const size_t take = std::min(size, end_ - begin_);
    std::copy(buffer_ + begin_, buffer_ + begin_ + take, ptr);
    begin_ += take;
    consumed_ += take;
    return static_cast<ssize_t>(take);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (ssl_ != nullptr) {
      for (;;) {
        if (!PollUntil(fd_, POLLOUT, Steady::now() + Seconds(limits_.write_timeout_s))) return -1;
        ERR_clear_error();
        const int n = SSL_write(ssl_, ptr, static_cast<int>(std::min<size_t>(size, 1 << 30)));
        if (n > 0) return n;
        const int e = SSL_get_error(ssl_, n);
        if (e != SSL_ERROR_WANT_WRITE && e != SSL_ERROR_WANT_READ) return -1;
      }
    }
    if (!PollUntil(fd_, POLLOUT, Steady::now() + Seconds(limits_.write_timeout_s))) return -1;
    ssize_t n;
    do n = send(fd_, ptr, size, MSG_NOSIGNAL);
    while (n < 0 && errno == EINTR);
    return n;
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override { AddressOf(fd_, true, ip, port); }
  void get_local_ip_and_port(std::string& ip, int& port) const override { AddressOf(fd_, false, ip, port); }
  socket_t socket() const override { return fd_; }

 private:
  // SSL_read without waiting: > 0 bytes, 0 the peer ended the session, -1 with errno EAGAIN (nothing
  // whole yet) or EIO.
  ssize_t TlsRead(char* into, size_t room) {
    ERR_clear_error();
    const int n = SSL_read(ssl_, into, static_cast<int>(std::min<size_t>(room, 1 << 30)));
    if (n > 0) return n;
    const int e = SSL_get_error(ssl_, n);
    if (e == SSL_ERROR_ZERO_RETURN) return 0;
    errno = e == SSL_ERROR_WANT_READ || e == SSL_ERROR_WANT_WRITE ? EAGAIN : EIO;
    return -1;
  }

  Steady::time_point ReadUntil() const {
    const Steady::time_point timeout = Steady::now() + Seconds(limits_.read_timeout_s);
    return deadline_ ? std::min(timeout, *deadline_) : timeout;
  }

  int fd_;
  SSL* ssl_ = nullptr;  // owned
  const ConnectionLimits& limits_;
  std::optional<Steady::time_point> deadline_;
  const char* what_ = "";
  const char* missed_ = "";
  char buffer_[16 * 1024];
  size_t begin_ = 0, end_ = 0;
  uint64_t consumed_ = 0;
};

// How long a connection answered before its request body was read (a refusal) goes on being
// drained, so that the client, still sending, reads the answer instead of a reset.
constexpr double kDrainS = 2;
constexpr uint64_t kDrainBytes = 8 << 20;  // past them the client is not reading: closed

// A request refused after its head was read, before any handler ran: answered here, and the
// connection closed (thrown out of the library's setup callback, which runs outside its handlers'
// exception handling).
struct Refused {
  int status;
  int retry_after_s;
  std::string detail;
};

}  // namespace

bool GuardedHttpServer::SetBacklog(int n) {
  const socket_t sock = svr_sock_;
  return sock != INVALID_SOCKET && ::listen(sock, n) == 0;  // a second listen() sets the backlog anew
}

// The library reads a body as it is framed: chunked first, else by Content-Length, else -- for
// the methods that carry one -- until the client closes. A chunked body, or one read to the end,
// has no length to allow time for: the grace alone. A length is trusted only up to the largest
// body the server takes (a larger one is refused before it is read).
std::optional<std::chrono::steady_clock::time_point> GuardedHttpServer::BodyDeadline(const httplib::Request& req) const {
  const auto now = Steady::now();
  const std::string encoding = req.get_header_value("Transfer-Encoding");
  if (!encoding.empty() && encoding.find("chunked") != std::string::npos) return now + Seconds(limits_.body_grace_s);
  if (req.has_header("Content-Length")) {
    const std::string text = req.get_header_value("Content-Length");
    errno = 0;
    char* end = nullptr;
    const unsigned long long n = std::strtoull(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || errno != 0 || text[0] == '-') return now + Seconds(limits_.body_grace_s);
    if (n == 0) return std::nullopt;
    const double bytes = std::min(static_cast<double>(n), static_cast<double>(payload_max_length_));
    return now + Seconds(std::min(limits_.body_grace_s + bytes / limits_.min_body_bytes_per_s, 86400.0));
  }
  const std::string& m = req.method;
  if (m == "POST" || m == "PUT" || m == "PATCH" || m == "PRI") return now + Seconds(limits_.body_grace_s);
  return std::nullopt;
}

struct GuardedHttpServer::Connection {
  Connection(int socket, const ConnectionLimits& limits) : fd(socket), stream(socket, limits) {}
  int fd;
  std::string peer = "?";
  std::string client;  // ClientKey(peer): what the per-client limits count
  int port = 0;
  DeadlineStream stream;
  bool counted = false;     // in open_ and per_client_
  bool restricted = false;  // opened past its client's connection cap, or in the reserve: reserved requests only
  bool in_reserve = false;  // one of the last connection slots (ReserveSlots)
  bool authenticated = false;  // has carried a request with the daemon's credential: not in per_client_
  bool handshaking = false;  // TLS: the session is not set up yet
  bool want_write = false;   // TLS: the handshake waits for room to send
  bool draining = false;    // answered and half-closed: what still arrives is dropped until idle_until
  uint64_t drained = 0;     // bytes dropped so far
  int served = 0;
  Steady::time_point opened;                      // when it was accepted
  Steady::time_point idle_until;                  // parked without a byte: closed then
  std::optional<Steady::time_point> head_started;  // the next head's first byte
};

// The library hands each accepted socket to a task queue. This one admits it on the accept
// loop's own thread (Admit: a few system calls, never a wait) and ends the server's threads when
// the accept loop ends.
class GuardedHttpServer::Queue final : public httplib::TaskQueue {
 public:
  explicit Queue(GuardedHttpServer* server) : server_(server) { server_->StartThreads(); }
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override { server_->StopThreads(); }

 private:
  GuardedHttpServer* server_;
};

GuardedHttpServer::GuardedHttpServer(ConnectionLimits limits) : limits_(limits) {
  new_task_queue = [this] { return new Queue(this); };
  // What the library's Keep-Alive header announces: these limits, not its own defaults (max=5),
  // which this server does not apply.
  set_keep_alive_max_count(static_cast<size_t>(std::max(1, limits_.max_requests_per_connection)));
  set_keep_alive_timeout(static_cast<time_t>(std::max(1.0, limits_.idle_s)));
}

GuardedHttpServer::~GuardedHttpServer() {
  StopThreads();
  if (tls_ != nullptr) SSL_CTX_free(tls_);
}

bool GuardedHttpServer::SetTls(const std::string& cert_file, const std::string& key_file, std::string* error) {
  SSL_CTX* ctx = SSL_CTX_new(TLS_server_method());
  auto fail = [&](const std::string& what) {
    const unsigned long e = ERR_get_error();
    char text[256] = "no detail from OpenSSL";
    if (e != 0) ERR_error_string_n(e, text, sizeof text);
    ERR_clear_error();
    *error = what + ": " + text;
    if (ctx != nullptr) SSL_CTX_free(ctx);
    return false;
  };
  if (ctx == nullptr) return fail("cannot make a TLS context");
  SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION);
  SSL_CTX_set_options(ctx, SSL_OP_NO_COMPRESSION | SSL_OP_NO_RENEGOTIATION);
  SSL_CTX_set_mode(ctx, SSL_MODE_ENABLE_PARTIAL_WRITE | SSL_MODE_ACCEPT_MOVING_WRITE_BUFFER);
  if (SSL_CTX_use_certificate_chain_file(ctx, cert_file.c_str()) != 1) return fail("cannot use " + cert_file);
  if (SSL_CTX_use_PrivateKey_file(ctx, key_file.c_str(), SSL_FILETYPE_PEM) != 1) return fail("cannot use " + key_file);
  if (SSL_CTX_check_private_key(ctx) != 1) return fail(key_file + " is not " + cert_file + "'s key");
  if (tls_ != nullptr) SSL_CTX_free(tls_);
  tls_ = ctx;
  return true;
}

void GuardedHttpServer::SetReserved(std::function<bool(const httplib::Request&)> reserved) {
  reserved_ = std::move(reserved);
}

void GuardedHttpServer::SetAuthenticated(std::function<bool(const httplib::Request&)> authenticated) {
  authenticated_ = std::move(authenticated);
}

void GuardedHttpServer::SetOwnHeaders(std::vector<std::pair<std::string, std::string>> headers) {
  own_headers_.clear();
  for (const auto& [name, value] : headers) own_headers_ += name + ": " + value + "\r\n";
}

void GuardedHttpServer::SetRefusalBody(std::function<std::string(int, const std::string&)> body) {
  refusal_body_ = std::move(body);
}

int GuardedHttpServer::open_connections() const {
  std::lock_guard<std::mutex> lock(mu_);
  return open_;
}

int64_t GuardedHttpServer::reserve_taken() const {
  std::lock_guard<std::mutex> lock(mu_);
  return reserve_taken_;
}

void GuardedHttpServer::StartThreads() {
  std::lock_guard<std::mutex> lock(mu_);
  stopping_ = false;
  max_open_ = std::max(1, limits_.max_connections);
  // Every open connection is a file descriptor: leave room for the database, uploads and renderers.
  rlimit files{};
  if (getrlimit(RLIMIT_NOFILE, &files) == 0 && files.rlim_cur != RLIM_INFINITY) {
    max_open_ = std::max(16, std::min<int>(max_open_, static_cast<int>(files.rlim_cur) - 256));
  }
  epoll_fd_ = epoll_create1(EPOLL_CLOEXEC);
  wake_fd_ = eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
  epoll_event wake{};
  wake.events = EPOLLIN;
  wake.data.fd = wake_fd_;
  epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, wake_fd_, &wake);
  poller_ = std::thread([this] { PollLoop(); });
  const int n = std::max(1, limits_.threads) + std::max(0, limits_.reserved_threads);
  for (int i = 0; i < n; ++i) servers_.emplace_back([this] { ServeLoop(); });
}

void GuardedHttpServer::StopThreads() {
  std::vector<std::unique_ptr<Connection>> dropped;
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!poller_.joinable()) return;
    stopping_ = true;
    for (auto& [fd, c] : parked_) dropped.push_back(std::move(c));
    parked_.clear();
    for (auto& c : ready_) dropped.push_back(std::move(c));
    ready_.clear();
  }
  for (auto& c : dropped) Close(std::move(c));
  const uint64_t one = 1;
  (void)!::write(wake_fd_, &one, sizeof one);
  work_ready_.notify_all();
  poller_.join();
  for (std::thread& t : servers_) t.join();  // requests in flight end first (streams: when their feed stops)
  servers_.clear();
  std::lock_guard<std::mutex> lock(mu_);
  close(epoll_fd_);
  close(wake_fd_);
  epoll_fd_ = wake_fd_ = -1;
}

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  Admit(sock);
  return true;
}

void GuardedHttpServer::Admit(socket_t sock) {
  auto c = std::make_unique<Connection>(sock, limits_);
  AddressOf(sock, /*peer=*/true, c->peer, c->port);
  if (tls_ != nullptr) {
    // The handshake is stepped by the poller as its bytes arrive: no thread waits on it.
    SSL* ssl = SSL_new(tls_);
    const int flags = fcntl(sock, F_GETFL);
    if (ssl == nullptr || flags < 0 || fcntl(sock, F_SETFL, flags | O_NONBLOCK) != 0 || SSL_set_fd(ssl, sock) != 1) {
      if (ssl != nullptr) SSL_free(ssl);
      return Close(std::move(c));
    }
    SSL_set_accept_state(ssl);
    c->stream.set_ssl(ssl);
    c->handshaking = true;
  }
  c->client = ClientKey(c->peer, limits_.loopback_clients_apart);
  c->opened = Steady::now();
  std::unique_ptr<Connection> taken;  // a reserve connection whose slot this one gets
  {
    std::lock_guard<std::mutex> lock(mu_);
    // The last slots are kept for the worker protocol and /healthz, for whoever comes: when every
    // slot is taken, the newcomer takes the slot of the reserve connection that has waited longest
    // without a request, so that a crowd holding the reserve cannot keep a worker out.
    const bool reserve = open_ >= max_open_ - ReserveSlots();
    if (!stopping_ && open_ >= max_open_) {
      taken = TakeReserveSlotLocked();
      if (taken) ++reserve_taken_;
    }
    if (!stopping_ && open_ < max_open_) {
      ++open_;
      const int n = ++per_client_[c->client];
      c->counted = true;
      c->in_reserve = reserve;
      if (reserve) ++in_reserve_[c->client];
      c->restricted = reserve || n > limits_.max_connections_per_client;
    }
  }
  if (taken) Close(std::move(taken));  // already uncounted: its slot is this connection's
  if (!c->counted) {  // past the fd budget: no thread, no read, no answer
    client_refused_.fetch_add(1);
    refusals_.Refused(c->client, "connections", [&] {
      return "closed a connection from " + c->peer + " at once: " + std::to_string(max_open_) +
             " connections are open, the most this daemon keeps (its last " + std::to_string(ReserveSlots()) +
             " for the worker protocol, the token's holders and /healthz), and every one of those is in use";
    });
    return Close(std::move(c));
  }
  c->idle_until = Steady::now() + Seconds(limits_.idle_s);
  Park(std::move(c));
}

void GuardedHttpServer::Park(std::unique_ptr<Connection> c) {
  if (!c->draining && !c->handshaking) {
    c->stream.TakePending();
    if (c->stream.has_whole_head()) return Enqueue(std::move(c));
    if (c->stream.full()) {
      // A request head larger than the buffer: answered here, without a thread, and drained.
      client_refused_.fetch_add(1);
      refusals_.Refused(c->client, "large head",
                        [&] { return "refused a request from " + c->peer + ": its head is larger than 16 KiB (431)"; });
      const std::string detail = "the request's line and headers are larger than 16 KiB: send fewer or shorter headers";
      const std::string body = refusal_body_ ? refusal_body_(431, detail) : detail;
      c->stream.SendNow("HTTP/1.1 431 Request Header Fields Too Large\r\nContent-Type: " +
                        std::string(refusal_body_ ? "application/problem+json" : "text/plain") +
                        "\r\n" + own_headers_ + "Connection: close\r\nContent-Length: " + std::to_string(body.size()) +
                        "\r\n\r\n" + body);
      c->stream.ShutdownWrite();
      c->draining = true;
      c->head_started.reset();
      c->idle_until = Steady::now() + Seconds(kDrainS);
      uint64_t dropped = 0;
      c->stream.Discard(&dropped);
    }
  }
  std::unique_lock<std::mutex> lock(mu_);
  if (stopping_) {
    lock.unlock();
    return Close(std::move(c));
  }
  epoll_event ev{};
  ev.events = EPOLLIN | EPOLLONESHOT | (c->want_write ? static_cast<uint32_t>(EPOLLOUT) : 0u);
  ev.data.fd = c->fd;
  const int fd = c->fd;
  parked_[fd] = std::move(c);
  if (epoll_ctl(epoll_fd_, EPOLL_CTL_ADD, fd, &ev) != 0) {
    auto failed = std::move(parked_[fd]);
    parked_.erase(fd);
    lock.unlock();
    Close(std::move(failed));
  }
}

void GuardedHttpServer::Enqueue(std::unique_ptr<Connection> c) {
  std::unique_lock<std::mutex> lock(mu_);
  if (stopping_) {
    lock.unlock();
    return Close(std::move(c));
  }
  ready_.push_back(std::move(c));
  lock.unlock();
  work_ready_.notify_one();
}

void GuardedHttpServer::Close(std::unique_ptr<Connection> c) {
  shutdown(c->fd, SHUT_RDWR);
  close(c->fd);
  if (!c->counted) return;
  std::lock_guard<std::mutex> lock(mu_);
  UncountLocked(*c);
}

void GuardedHttpServer::UncountLocked(Connection& c) {
  if (!c.counted) return;
  c.counted = false;
  --open_;
  if (!c.authenticated) {
    auto it = per_client_.find(c.client);
    if (it != per_client_.end() && --it->second <= 0) per_client_.erase(it);
  }
  if (c.in_reserve) {
    auto r = in_reserve_.find(c.client);
    if (r != in_reserve_.end() && --r->second <= 0) in_reserve_.erase(r);
  }
}

void GuardedHttpServer::Authenticated(Connection& c) {
  std::lock_guard<std::mutex> lock(mu_);
  if (!c.in_reserve) c.restricted = false;
  if (c.authenticated || !c.counted) return;
  c.authenticated = true;
  auto it = per_client_.find(c.client);
  if (it != per_client_.end() && --it->second <= 0) per_client_.erase(it);
}

std::unique_ptr<GuardedHttpServer::Connection> GuardedHttpServer::TakeReserveSlotLocked() {
  // Parked reserve connections wait for (the rest of) a request head, or drain after a refusal:
  // neither is being served. Of the client holding most of the reserve (a crowd before a worker
  // on another host), the one opened first (a crowd's before a worker's newest).
  Connection* pick = nullptr;
  for (auto& [fd, c] : parked_) {
    if (!c->in_reserve) continue;
    if (pick == nullptr) {
      pick = c.get();
      continue;
    }
    // Those who have not shown the token first.
    if (c->authenticated != pick->authenticated) {
      if (!c->authenticated) pick = c.get();
      continue;
    }
    const int mine = in_reserve_[c->client], theirs = in_reserve_[pick->client];
    if (mine > theirs || (mine == theirs && c->opened < pick->opened)) pick = c.get();
  }
  if (pick == nullptr) return nullptr;
  auto it = parked_.find(pick->fd);
  std::unique_ptr<Connection> taken = std::move(it->second);
  parked_.erase(it);
  epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, taken->fd, nullptr);
  UncountLocked(*taken);
  return taken;
}

// Waits for parked connections' bytes; a connection whose head is whole goes to a serving thread.
// Every 0.1 s, the parked connections past their deadlines are closed.
void GuardedHttpServer::PollLoop() {
  epoll_event events[256];
  Steady::time_point next_sweep = Steady::now();
  for (;;) {
    const int n = epoll_wait(epoll_fd_, events, 256, 100);
    {
      std::lock_guard<std::mutex> lock(mu_);
      if (stopping_) return;
    }
    for (int i = 0; i < n; ++i) {
      const int fd = events[i].data.fd;
      if (fd == wake_fd_) continue;
      std::unique_ptr<Connection> c;
      {
        std::lock_guard<std::mutex> lock(mu_);
        auto it = parked_.find(fd);
        if (it == parked_.end()) continue;
        c = std::move(it->second);
        parked_.erase(it);
        epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, fd, nullptr);
      }
      if (c->draining) {
        if (c->stream.Discard(&c->drained) && c->drained <= kDrainBytes) {
          Park(std::move(c));
        } else {
          Close(std::move(c));  // the client has read the answer and closed
        }
        continue;
      }
      if (c->handshaking) {
        if (!c->head_started) c->head_started = Steady::now();  // the head's deadline counts the handshake's time
        const int step = c->stream.Handshake(&c->want_write);
        if (step < 0) {
          spdlog::debug("TLS handshake with {} failed", c->peer);
          Close(std::move(c));
          continue;
        }
        c->handshaking = step == 0;
        if (c->handshaking) {
          Park(std::move(c));
          continue;
        }
        c->want_write = false;
      }
      const ssize_t got = c->stream.ReadAvailable();
      if (got == 0 || (got < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != ENOBUFS)) {
        Close(std::move(c));  // the client closed (or the socket failed) between requests
        continue;
      }
      if (got > 0 && !c->head_started) c->head_started = Steady::now();
      Park(std::move(c));  // to a serving thread once its head is whole
    }
    const Steady::time_point now = Steady::now();
    if (now < next_sweep) continue;
    next_sweep = now + std::chrono::milliseconds(100);
    std::vector<std::unique_ptr<Connection>> slow, idle;
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (auto it = parked_.begin(); it != parked_.end();) {
        Connection& c = *it->second;
        const bool head_late = !c.draining && c.head_started && now >= *c.head_started + Seconds(limits_.head_s);
        const bool idle_over = !c.head_started && now >= c.idle_until;
        if (!head_late && !idle_over) {
          ++it;
          continue;
        }
        epoll_ctl(epoll_fd_, EPOLL_CTL_DEL, c.fd, nullptr);
        (head_late ? slow : idle).push_back(std::move(it->second));
        it = parked_.erase(it);
      }
    }
    for (auto& c : slow) {
      slow_closed_.fetch_add(1);
      refusals_.Refused(c->client, "slow", [&] {
        return fmt::format("closed a connection from {}: its request head did not arrive in time (a slow or stalled "
                           "client; limit: {} s from its first byte)",
                           c->peer, limits_.head_s);
      });
      Close(std::move(c));
    }
    for (auto& c : idle) Close(std::move(c));
  }
}

void GuardedHttpServer::ServeLoop() {
  for (;;) {
    std::unique_ptr<Connection> c;
    {
      std::unique_lock<std::mutex> lock(mu_);
      work_ready_.wait(lock, [this] { return stopping_ || !ready_.empty(); });
      if (ready_.empty()) return;  // stopping
      c = std::move(ready_.front());
      ready_.pop_front();
    }
    const After after = ServeOne(*c);
    if (after == After::kPark) {
      c->head_started.reset();
      if (c->stream.has_buffered()) c->head_started = Steady::now();  // the next request, sent behind this one
      c->idle_until = Steady::now() + Seconds(limits_.idle_s);
      Park(std::move(c));
    } else if (after == After::kDrain) {
      c->stream.ShutdownWrite();  // the answer is sent whole; then FIN
      c->draining = true;
      c->head_started.reset();
      c->idle_until = Steady::now() + Seconds(kDrainS);
      Park(std::move(c));
    } else {
      Close(std::move(c));
    }
  }
}

GuardedHttpServer::After GuardedHttpServer::ServeOne(Connection& c) {
  DeadlineStream& stream = c.stream;
  const Steady::time_point head_from = c.head_started.value_or(Steady::now());
  stream.set_deadline(head_from + Seconds(limits_.head_s), "request head");
  ++c.served;
  // Keep-alive ends when the readers' threads are more than half taken (clients then reconnect
  // instead of holding a connection each while the daemon is loaded), after the last request a
  // connection may carry, and for a connection past its client's cap.
  const bool busy = readers_in_flight_.load() * 2 > limits_.threads;
  const bool last = c.restricted || busy || c.served >= limits_.max_requests_per_connection ||
                    svr_sock_ == INVALID_SOCKET;
  bool holds_reader = false;
  bool connection_closed = false;
  bool ret = false;
  // Whether the handler read the whole body: a connection with body bytes left unread cannot carry
  // another request (they would be read as one).
  uint64_t body_from = 0;
  std::optional<uint64_t> body_length;
  bool body_unframed = false;  // chunked, or read to the end: never kept alive
  try {
    ret = process_request(stream, last, connection_closed, [&](httplib::Request& req) {
      const bool reserved = reserved_ && reserved_(req);
      const bool authenticated = authenticated_ && authenticated_(req);
      if (authenticated) Authenticated(c);
      if (!reserved) {
        if (c.restricted && !authenticated) {
          throw Refused{429, 2,
                        c.in_reserve ? std::string("the daemon's connections are nearly all taken (the last are kept "
                                                   "for workers and /healthz): retry shortly")
                                     : "this client has more than " +
                                           std::to_string(limits_.max_connections_per_client) +
                                           " connections open: reuse one, or close some and retry"};
        }
        if (readers_in_flight_.fetch_add(1) >= limits_.threads) {
          readers_in_flight_.fetch_sub(1);
          throw Refused{503, 1,
                        "all " + std::to_string(limits_.threads) +
                            " request threads are busy (the worker protocol and /healthz have threads of their own): "
                            "retry shortly"};
        }
        holds_reader = true;
      }
      stream.set_deadline(BodyDeadline(req), "request body");
      body_from = stream.consumed();
      if (req.has_header("Content-Length")) {
        body_length = std::strtoull(req.get_header_value("Content-Length").c_str(), nullptr, 10);
      } else if (req.has_header("Transfer-Encoding") || req.method == "POST" || req.method == "PUT" ||
                 req.method == "PATCH") {
        body_unframed = true;
      }
    });
  } catch (const Refused& r) {
    if (holds_reader) readers_in_flight_.fetch_sub(1);
    (r.status == 429 ? client_refused_ : busy_refused_).fetch_add(1);
    const std::string body = refusal_body_ ? refusal_body_(r.status, r.detail) : r.detail;
    const std::string head = "HTTP/1.1 " + std::to_string(r.status) +
                             (r.status == 429 ? " Too Many Requests" : " Service Unavailable") +
                             "\r\nContent-Type: " + (refusal_body_ ? "application/problem+json" : "text/plain") +
                             "\r\nRetry-After: " + std::to_string(r.retry_after_s) + "\r\n" + own_headers_ +
                             "Connection: close\r\nContent-Length: " + std::to_string(body.size()) + "\r\n\r\n";
    stream.set_deadline(std::nullopt, "");
    stream.write(head.data(), head.size());
    stream.write(body.data(), body.size());
    return After::kDrain;
  }
  if (holds_reader) readers_in_flight_.fetch_sub(1);
  if (*stream.missed() != '\0') {
    slow_closed_.fetch_add(1);
    refusals_.Refused(c.client, "slow", [&] {
      return fmt::format("closed a connection from {}: its {} did not arrive in time (a slow or stalled client; "
                         "limits: head {} s, body {} s + {} KiB/s)",
                         c.peer, stream.missed(), limits_.head_s, limits_.body_grace_s,
                         limits_.min_body_bytes_per_s / 1024);
    });
    return After::kClose;
  }
  stream.set_deadline(std::nullopt, "");
  const bool body_left = body_unframed || (body_length && stream.consumed() - body_from < *body_length);
  if (ret && body_left) return After::kDrain;  // answered before its body was read (e.g. a refused upload)
  return !ret || connection_closed || last ? After::kClose : After::kPark;
}

bool GuardedHttpServer::ServeConnection(socket_t sock) {
  Connection c(sock, limits_);
  AddressOf(sock, /*peer=*/true, c.peer, c.port);
  for (;;) {
    // Silence before a request: a tenth of a second at a time, so that a stopping server ends it.
    const Steady::time_point idle_until = Steady::now() + Seconds(limits_.idle_s);
    bool readable = c.stream.has_buffered();  // a request sent right behind the last one
    while (!readable && Steady::now() < idle_until) {
      readable = PollUntil(sock, POLLIN, std::min(idle_until, Steady::now() + std::chrono::milliseconds(100)));
    }
    if (!readable) break;
    c.head_started = Steady::now();
    if (ServeOne(c) != After::kPark) break;
  }
  shutdown(sock, SHUT_RDWR);
  close(sock);
  return true;
}

}  // namespace sandswim
