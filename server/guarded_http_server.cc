#include "server/guarded_http_server.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>

#include <spdlog/spdlog.h>

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
// streams).
class DeadlineStream final : public httplib::Stream {
 public:
  DeadlineStream(int fd, const ConnectionLimits& limits) : fd_(fd), limits_(limits) {}

  void set_deadline(std::optional<Steady::time_point> d, const char* what) {
    deadline_ = d;
    what_ = what;
  }
  // What missed its deadline ("" when nothing did).
  const char* missed() const { return missed_; }
  // Bytes received and not yet read.
  bool has_buffered() const { return begin_ < end_; }

  bool is_readable() const override {
    return begin_ < end_ || PollUntil(fd_, POLLIN, ReadUntil());
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
    if (begin_ == end_) {
      if (!PollUntil(fd_, POLLIN, ReadUntil())) {
        if (deadline_ && Steady::now() >= *deadline_) missed_ = what_;
        return -1;
      }
      ssize_t n;
      do n = recv(fd_, buffer_, sizeof buffer_, 0);
      while (n < 0 && errno == EINTR);
      if (n <= 0) return n;
      begin_ = 0;
      end_ = static_cast<size_t>(n);
    }
    const size_t take = std::min(size, end_ - begin_);
    std::copy(buffer_ + begin_, buffer_ + begin_ + take, ptr);
    begin_ += take;
    return static_cast<ssize_t>(take);
  }
  ssize_t write(const char* ptr, size_t size) override {
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
  Steady::time_point ReadUntil() const {
    const Steady::time_point timeout = Steady::now() + Seconds(limits_.read_timeout_s);
    return deadline_ ? std::min(timeout, *deadline_) : timeout;
  }

  int fd_;
  const ConnectionLimits& limits_;
  std::optional<Steady::time_point> deadline_;
  const char* what_ = "";
  const char* missed_ = "";
  char buffer_[16 * 1024];
  size_t begin_ = 0, end_ = 0;
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

bool GuardedHttpServer::ServeConnection(socket_t sock) { return process_and_close_socket(sock); }

bool GuardedHttpServer::process_and_close_socket(socket_t sock) {
  DeadlineStream stream(sock, limits_);
  bool ret = false;
  std::string peer = "?";
  int port = 0;
  AddressOf(sock, /*peer=*/true, peer, port);
  for (size_t count = keep_alive_max_count_; count > 0 && svr_sock_ != INVALID_SOCKET; --count) {
    // Silence before a request: a tenth of a second at a time, so that a stopping server ends it.
    const Steady::time_point idle_until = Steady::now() + Seconds(limits_.idle_s);
    bool readable = stream.has_buffered();  // a request sent right behind the last one
    while (!readable && svr_sock_ != INVALID_SOCKET && Steady::now() < idle_until) {
      readable = PollUntil(sock, POLLIN, std::min(idle_until, Steady::now() + std::chrono::milliseconds(100)));
    }
    if (!readable) break;
    stream.set_deadline(Steady::now() + Seconds(limits_.head_s), "request head");
    bool connection_closed = false;
    ret = process_request(stream, /*close_connection=*/count == 1, connection_closed,
                          [&](httplib::Request& req) { stream.set_deadline(BodyDeadline(req), "request body"); });
    if (*stream.missed() != '\0') {
      slow_closed_.fetch_add(1);
      spdlog::warn("closed a connection from {}: its {} did not arrive in time (a slow or stalled client; "
                   "limits: head {} s, body {} s + {} KiB/s)",
                   peer, stream.missed(), limits_.head_s, limits_.body_grace_s, limits_.min_body_bytes_per_s / 1024);
      break;
    }
    stream.set_deadline(std::nullopt, "");
    if (!ret || connection_closed) break;
  }
  shutdown(sock, SHUT_RDWR);
  close(sock);
  return ret;
}

}  // namespace sandswim
