#include "server/http/guarded_http_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "platform/http_client.h"
#include "platform/tls.h"

namespace sandswim {
namespace {

using Steady = std::chrono::steady_clock;

double SecondsSince(Steady::time_point t) { return std::chrono::duration<double>(Steady::now() - t).count(); }

// A server with deadlines short enough to test: 0.5 s of silence, 0.5 s for a head, a body in
// 0.5 s + its length at 1 MB/s.
class GuardedHttpServerTest : public ::testing::Test {
 protected:
  // What a fixture changes of the limits below.
  virtual void Adjust(ConnectionLimits&) {}
  // What a fixture sets on the server before it listens.
  virtual void Configure(GuardedHttpServer&) {}

  void SetUp() override {
    ConnectionLimits limits;
    limits.idle_s = 0.5;
    limits.head_s = 0.5;
    limits.body_grace_s = 0.5;
    limits.min_body_bytes_per_s = 1e6;
    Adjust(limits);
    server_ = std::make_unique<GuardedHttpServer>(limits);
    Configure(*server_);
    server_->SetReserved([](const httplib::Request& head) { return head.path == "/reserved"; });
    server_->Get("/hello", [](const httplib::Request&, httplib::Response& res) { res.set_content("hi", "text/plain"); });
    server_->Get("/reserved", [](const httplib::Request&, httplib::Response& res) { res.set_content("yes", "text/plain"); });
    // Holds its thread until Release().
    server_->Get("/block", [this](const httplib::Request&, httplib::Response& res) {
      std::unique_lock<std::mutex> lock(gate_mu_);
      ++blocked_;
      gate_.notify_all();
      gate_.wait(lock, [this] { return released_; });
      res.set_content("released", "text/plain");
    });
    // Reads its body, then works for longer than any deadline.
    server_->Post("/body", [](const httplib::Request&, httplib::Response& res, const httplib::ContentReader& reader) {
      size_t n = 0;
      reader([&](const char*, size_t len) {
        n += len;
        return true;
      });
      std::this_thread::sleep_for(std::chrono::milliseconds(1200));
      res.set_content(std::to_string(n), "text/plain");
    });
    // Streams for longer than any deadline: 15 chunks, 0.1 s apart.
    server_->Get("/stream", [](const httplib::Request&, httplib::Response& res) {
      res.set_chunked_content_provider("text/plain", [](size_t offset, httplib::DataSink& sink) {
        if (offset >= 15) {
          sink.done();
          return true;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        return sink.write("x", 1);
      });
    });
    port_ = server_->bind_to_any_port("127.0.0.1");
    ASSERT_GT(port_, 0);
    thread_ = std::thread([this] { server_->listen_after_bind(); });
    for (int i = 0; i < 5000 && !server_->is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  void TearDown() override {
    Release();
    server_->stop();
    thread_.join();
  }
  void WaitBlocked(int n) {
    std::unique_lock<std::mutex> lock(gate_mu_);
    gate_.wait(lock, [&] { return blocked_ >= n; });
  }
  void Release() {
    std::lock_guard<std::mutex> lock(gate_mu_);
    released_ = true;
    gate_.notify_all();
  }
  // One request on a connection of its own; the whole answer (the server closes after it).
  std::string Ask(const std::string& path) {
    const int fd = Connect();
    Send(fd, "GET " + path + " HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    std::string got;
    char buf[4096];
    ssize_t n;
    while ((n = recv(fd, buf, sizeof buf, 0)) > 0) got.append(buf, static_cast<size_t>(n));
    close(fd);
    return got;
  }

  int Connect() {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(port_));
    inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    return fd;
  }
  // A connection from another loopback address than Connect()'s 127.0.0.1.
  int ConnectFrom(const char* address) {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in from{};
    from.sin_family = AF_INET;
    inet_pton(AF_INET, address, &from.sin_addr);
    EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&from), sizeof from), 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<uint16_t>(port_));
    inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
    return fd;
  }
  static void Send(int fd, const std::string& bytes) { send(fd, bytes.data(), bytes.size(), MSG_NOSIGNAL); }
  // Reads until the server closes the connection; the seconds that took, or -1 past `limit_s`.
  // `dribble`: a byte sent every 0.1 s meanwhile, as a slow client does.
  static double SecondsUntilClosed(int fd, double limit_s, const std::string& dribble = "") {
    const auto start = Steady::now();
    while (SecondsSince(start) < limit_s) {
      if (!dribble.empty()) Send(fd, dribble);
      pollfd p{fd, POLLIN, 0};
      if (poll(&p, 1, 100) > 0) {
        char buf[4096];
        const ssize_t n = recv(fd, buf, sizeof buf, 0);
        if (n <= 0) return SecondsSince(start);
      }
    }
    return -1;
  }

  std::unique_ptr<GuardedHttpServer> server_;
  int port_ = 0;
  std::thread thread_;
  std::mutex gate_mu_;
  std::condition_variable gate_;
  int blocked_ = 0;
  bool released_ = false;
};

TEST_F(GuardedHttpServerTest, ARequestHeadSentSlowlyIsCutOffWhileOthersAreServed) {
  const int slow = Connect();
  Send(slow, "GET /hello HTTP/1.1\r\nHost: x\r\nX-Slow: ");
  std::thread other([this] {
    httplib::Client c("127.0.0.1", port_);
    for (int i = 0; i < 5; ++i) {
      auto r = c.Get("/hello");
      ASSERT_TRUE(r);
      EXPECT_EQ(r->status, 200);
    }
  });
  const double closed_after = SecondsUntilClosed(slow, 10, "a");
  other.join();
  close(slow);
  // The head's 0.5 s, from its first byte (sent before the clock started); the upper bound leaves
  // room for a machine busy with other tests.
  EXPECT_GE(closed_after, 0) << "a head sent a byte each 0.1 s was not cut off in 10 s";
  if (closed_after >= 0) {
    EXPECT_GE(closed_after, 0.3) << "cut off before the head's 0.5 s were up";
    EXPECT_LT(closed_after, 4) << "cut off, but long after the head's 0.5 s";
  }
  EXPECT_EQ(server_->slow_clients_closed(), 1);
}

TEST_F(GuardedHttpServerTest, ASilentConnectionIsClosedAfterItsIdleTime) {
  const int idle = Connect();
  const double closed_after = SecondsUntilClosed(idle, 10);
  close(idle);
  EXPECT_GE(closed_after, 0.4);
  EXPECT_LT(closed_after, 4);
  EXPECT_EQ(server_->slow_clients_closed(), 0);  // silence is not slowness
}

TEST_F(GuardedHttpServerTest, ABodyThatLiesAboutItsLengthIsCutOff) {
  const int liar = Connect();
  // 100,000 bytes promised (0.5 s + 0.1 s allowed), 10 sent.
  Send(liar, "POST /body HTTP/1.1\r\nHost: x\r\nContent-Length: 100000\r\n\r\n0123456789");
  const double closed_after = SecondsUntilClosed(liar, 10);
  close(liar);
  EXPECT_GE(closed_after, 0.4);
  EXPECT_LT(closed_after, 4);
  EXPECT_EQ(server_->slow_clients_closed(), 1);
}

// A body with no length is read until the client closes: it gets the grace alone, and so does a
// chunked one whatever length it also claims.
TEST_F(GuardedHttpServerTest, BodiesWithoutALengthHaveTheGraceAlone) {
  const int unframed = Connect();
  Send(unframed, "POST /body HTTP/1.1\r\nHost: x\r\n\r\n0123");
  const int chunked = Connect();
  Send(chunked, "POST /body HTTP/1.1\r\nHost: x\r\nTransfer-Encoding: chunked\r\n"
                "Content-Length: 1000000000000000000000\r\n\r\n4\r\nabcd\r\n");
  std::thread t([&] {
    const double chunked_after = SecondsUntilClosed(chunked, 10, "");
    EXPECT_GE(chunked_after, 0.3);
    EXPECT_LT(chunked_after, 4) << "a chunked body's claimed length bought it time";
  });
  const double unframed_after = SecondsUntilClosed(unframed, 10, "");
  t.join();
  close(unframed);
  close(chunked);
  EXPECT_GE(unframed_after, 0.3);
  EXPECT_LT(unframed_after, 4) << "a body without a length was read without a deadline";
  EXPECT_EQ(server_->slow_clients_closed(), 2);
}

// A request sent right behind the last one on the same connection is answered at once.
TEST_F(GuardedHttpServerTest, PipelinedRequestsAreAnswered) {
  const int fd = Connect();
  Send(fd, "GET /hello HTTP/1.1\r\nHost: x\r\n\r\nGET /hello HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  const auto start = Steady::now();
  std::string got;
  char buf[4096];
  ssize_t n;
  while ((n = recv(fd, buf, sizeof buf, 0)) > 0) got.append(buf, static_cast<size_t>(n));
  close(fd);
  size_t answers = 0;
  for (size_t at = got.find("HTTP/1.1 200"); at != std::string::npos; at = got.find("HTTP/1.1 200", at + 1)) ++answers;
  EXPECT_EQ(answers, 2u) << got;
  EXPECT_LT(SecondsSince(start), 0.4) << "the second request waited for the idle time";
}

TEST_F(GuardedHttpServerTest, HandlersAndStreamsLongerThanTheDeadlinesAreNotCutOff) {
  httplib::Client c("127.0.0.1", port_);
  auto r = c.Post("/body", std::string(1000, 'b'), "application/octet-stream");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200);
  EXPECT_EQ(r->body, "1000");
  auto streamed = c.Get("/stream");  // 1.5 s
  ASSERT_TRUE(streamed);
  EXPECT_EQ(streamed->body, std::string(15, 'x'));
  EXPECT_EQ(server_->slow_clients_closed(), 0);
}

TEST_F(GuardedHttpServerTest, OneConnectionServesRequestAfterRequest) {
  httplib::Client c("127.0.0.1", port_);
  c.set_keep_alive(true);
  for (int i = 0; i < 20; ++i) {
    auto r = c.Get("/hello");
    ASSERT_TRUE(r) << "request " << i;
    EXPECT_EQ(r->body, "hi");
  }
}

// Two threads for any request, one more for reserved ones; keep-alive connections kept 30 s.
class GuardedHttpServerPoolTest : public GuardedHttpServerTest {
 protected:
  void Adjust(ConnectionLimits& limits) override {
    limits.threads = 2;
    limits.reserved_threads = 1;
    limits.idle_s = 30;
    limits.max_requests_per_connection = 3;
  }
};

// Readers hold every thread they may have: the next reader is answered 503 at once, and a reserved
// request (the worker protocol, /healthz in the daemon) is served on the thread kept for it.
TEST_F(GuardedHttpServerPoolTest, ReservedRequestsAreServedWhileReadersHoldEveryOtherThread) {
  std::vector<std::thread> readers;
  for (int i = 0; i < 2; ++i) {
    readers.emplace_back([this] {
      httplib::Client c("127.0.0.1", port_);
      c.set_read_timeout(60, 0);
      auto r = c.Get("/block");
      ASSERT_TRUE(r);
      EXPECT_EQ(r->body, "released");
    });
  }
  WaitBlocked(2);
  const std::string busy = Ask("/hello");
  EXPECT_THAT(busy, ::testing::StartsWith("HTTP/1.1 503")) << busy;
  EXPECT_THAT(busy, ::testing::HasSubstr("Retry-After: 1"));
  EXPECT_THAT(busy, ::testing::HasSubstr("request threads are busy"));
  const std::string reserved = Ask("/reserved");
  EXPECT_THAT(reserved, ::testing::StartsWith("HTTP/1.1 200")) << reserved;
  EXPECT_EQ(server_->busy_refused(), 1);
  Release();
  for (std::thread& t : readers) t.join();
  EXPECT_THAT(Ask("/hello"), ::testing::StartsWith("HTTP/1.1 200"));
}

// 40 idle keep-alive connections on a server of three threads: none of them holds a thread, so a
// new client is served at once, and they are still open.
TEST_F(GuardedHttpServerPoolTest, IdleKeepAliveConnectionsHoldNoThread) {
  // The server may end a keep-alive when its pool looks busy (on a loaded machine it sometimes
  // does): only the connections it kept open are idle ones, and they must outnumber the threads.
  std::vector<std::unique_ptr<httplib::Client>> idle;
  int kept = 0;
  for (int i = 0; i < 40; ++i) {
    idle.push_back(std::make_unique<httplib::Client>("127.0.0.1", port_));
    idle.back()->set_keep_alive(true);
    auto r = idle.back()->Get("/hello");
    ASSERT_TRUE(r) << "client " << i;
    if (r->get_header_value("Connection") != "close") ++kept;
  }
  ASSERT_GT(kept, 2) << "fewer idle connections than threads prove nothing";
  EXPECT_THAT(Ask("/hello"), ::testing::StartsWith("HTTP/1.1 200"));
  EXPECT_GE(server_->open_connections(), kept);
}

// A connection carries at most max_requests_per_connection requests: the last says so.
TEST_F(GuardedHttpServerPoolTest, AConnectionCarriesALimitedNumberOfRequests) {
  httplib::Client c("127.0.0.1", port_);
  c.set_keep_alive(true);
  for (int i = 1; i <= 3; ++i) {
    auto r = c.Get("/hello");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->get_header_value("Connection"), i == 3 ? "close" : "") << "request " << i;
    // What it announces is what it keeps (the library's own default said max=5).
    if (i < 3) EXPECT_THAT(r->get_header_value("Keep-Alive"), ::testing::HasSubstr("max=3")) << "request " << i;
  }
}

// The server's own answers (here a 431, written by the poller) carry the headers the routes' do.
class GuardedHttpServerOwnHeadersTest : public GuardedHttpServerTest {
 protected:
  void Configure(GuardedHttpServer& server) override {
    server.SetOwnHeaders({{"X-Content-Type-Options", "nosniff"}, {"X-Frame-Options", "DENY"}});
  }
};

TEST_F(GuardedHttpServerOwnHeadersTest, ItsOwnRefusalsCarryTheOwnHeaders) {
  const int fd = Connect();
  Send(fd, "GET /hello HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(17 * 1024, 'a') + "\r\n\r\n");
  std::string got;
  char buf[4096];
  ssize_t n;
  while ((n = recv(fd, buf, sizeof buf, 0)) > 0) got.append(buf, static_cast<size_t>(n));
  close(fd);
  EXPECT_THAT(got, ::testing::StartsWith("HTTP/1.1 431")) << got;
  EXPECT_THAT(got, ::testing::HasSubstr("\r\nX-Content-Type-Options: nosniff\r\n"));
  EXPECT_THAT(got, ::testing::HasSubstr("\r\nX-Frame-Options: DENY\r\n"));
}

// Three connections per client; past them, a connection is served only for reserved requests.
class GuardedHttpServerClientCapTest : public GuardedHttpServerTest {
 protected:
  void Adjust(ConnectionLimits& limits) override {
    limits.idle_s = 30;
    limits.max_connections_per_client = 3;
  }
};

TEST_F(GuardedHttpServerClientCapTest, AClientPastItsConnectionsIsServedOnlyReservedRequests) {
  std::vector<int> held;
  for (int i = 0; i < 3; ++i) held.push_back(Connect());
  const std::string refused = Ask("/hello");
  EXPECT_THAT(refused, ::testing::StartsWith("HTTP/1.1 429")) << refused;
  EXPECT_THAT(refused, ::testing::HasSubstr("Retry-After: 2"));
  EXPECT_THAT(refused, ::testing::HasSubstr("more than 3 connections open"));
  const std::string reserved = Ask("/reserved");
  EXPECT_THAT(reserved, ::testing::StartsWith("HTTP/1.1 200")) << reserved;
  EXPECT_EQ(server_->client_refused(), 1);
  for (int fd : held) close(fd);
  for (int i = 0; i < 500 && server_->open_connections() > 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_THAT(Ask("/hello"), ::testing::StartsWith("HTTP/1.1 200")) << "the client's connections were closed";
}

// A client that holds its cap without the credential cannot keep out one that shows it: the
// credential's request is served past the cap, and its connection counts no more against the
// client (so three of them leave room for three silent ones again).
class GuardedHttpServerAuthenticatedTest : public GuardedHttpServerClientCapTest {
 protected:
  void Configure(GuardedHttpServer& server) override {
    server.SetAuthenticated(
        [](const httplib::Request& head) { return head.get_header_value("Authorization") == "Bearer right"; });
  }
  // One GET with `authorization` on the keep-alive connection `fd`: the status line's code.
  static int AskOn(int fd, const std::string& path, const std::string& authorization) {
    Send(fd, "GET " + path + " HTTP/1.1\r\nHost: x\r\nAuthorization: " + authorization + "\r\n\r\n");
    std::string got;
    char buf[4096];
    while (got.find("\r\n\r\n") == std::string::npos) {
      pollfd p{fd, POLLIN, 0};
      if (poll(&p, 1, 5000) <= 0) break;
      const ssize_t n = recv(fd, buf, sizeof buf, 0);
      if (n <= 0) break;
      got.append(buf, static_cast<size_t>(n));
    }
    return got.rfind("HTTP/1.1 ", 0) == 0 ? std::atoi(got.c_str() + 9) : 0;
  }
};

TEST_F(GuardedHttpServerAuthenticatedTest, TheCredentialIsServedPastACapHeldWithoutIt) {
  // Three holders first: once they have shown the credential they are not the client's.
  std::vector<int> holders, crowd;
  for (int i = 0; i < 3; ++i) {
    holders.push_back(Connect());
    EXPECT_EQ(AskOn(holders.back(), "/hello", "Bearer right"), 200) << i;
  }
  for (int i = 0; i < 3; ++i) {
    crowd.push_back(Connect());
    EXPECT_EQ(AskOn(crowd.back(), "/hello", "none"), 200) << "a holder's connection was counted against the cap";
  }
  // The cap is the crowd's now: a fourth without the credential is refused, one with it served.
  const int wrong = Connect();
  EXPECT_EQ(AskOn(wrong, "/hello", "Bearer wrong"), 429);
  close(wrong);
  const int right = Connect();
  EXPECT_EQ(AskOn(right, "/hello", "Bearer right"), 200);
  close(right);
  // Not asserted yet: that a holder's idle keep-alive connection survives the newcomer. About half
  // the runs here find it closed (status 0) a moment after `right` is served; why is open (issue 47's
  // note). A holder that finds its connection closed reconnects and is served, as `right` was.
  EXPECT_EQ(server_->client_refused(), 1);
  for (int fd : holders) close(fd);
  for (int fd : crowd) close(fd);
}

// A local user is one client whichever loopback addresses it connects from, unless the operator
// sets them apart.
TEST_F(GuardedHttpServerClientCapTest, EveryLoopbackAddressCountsAsOneClient) {
  std::vector<int> held;
  for (const char* from : {"127.0.0.1", "127.0.0.2", "127.9.8.7"}) held.push_back(ConnectFrom(from));
  for (int i = 0; i < 500 && server_->open_connections() < 3; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  const int fd = ConnectFrom("127.0.0.3");
  Send(fd, "GET /hello HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  std::string got;
  char buf[4096];
  ssize_t n;
  while ((n = recv(fd, buf, sizeof buf, 0)) > 0) got.append(buf, static_cast<size_t>(n));
  close(fd);
  EXPECT_THAT(got, ::testing::StartsWith("HTTP/1.1 429")) << got;
  for (int held_fd : held) close(held_fd);
}

class GuardedHttpServerLoopbackApartTest : public GuardedHttpServerClientCapTest {
 protected:
  void Adjust(ConnectionLimits& limits) override {
    GuardedHttpServerClientCapTest::Adjust(limits);
    limits.loopback_clients_apart = true;
  }
};

TEST_F(GuardedHttpServerLoopbackApartTest, EachLoopbackAddressIsItsOwnClientWhenTheOperatorSaysSo) {
  std::vector<int> held;
  for (int i = 0; i < 3; ++i) held.push_back(ConnectFrom("127.0.0.2"));
  for (int i = 0; i < 500 && server_->open_connections() < 3; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_THAT(Ask("/hello"), ::testing::StartsWith("HTTP/1.1 200")) << "127.0.0.1 was counted with 127.0.0.2";
  const int fd = ConnectFrom("127.0.0.2");
  Send(fd, "GET /hello HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
  std::string got;
  char buf[4096];
  ssize_t n;
  while ((n = recv(fd, buf, sizeof buf, 0)) > 0) got.append(buf, static_cast<size_t>(n));
  close(fd);
  EXPECT_THAT(got, ::testing::StartsWith("HTTP/1.1 429")) << got;
  for (int held_fd : held) close(held_fd);
}

// 48 connections in all, the last 6 kept for reserved requests; no per-client cap in the way.
class GuardedHttpServerReserveTest : public GuardedHttpServerTest {
 protected:
  void Adjust(ConnectionLimits& limits) override {
    limits.idle_s = 30;
    limits.max_connections = 48;
    limits.max_connections_per_client = 1000;
    limits.loopback_clients_apart = true;  // 127.0.0.2 below stands for another host
  }
  void WaitOpen(int n) {
    for (int i = 0; i < 500 && server_->open_connections() < n; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_EQ(server_->open_connections(), n);
  }
};

TEST_F(GuardedHttpServerReserveTest, TheLastSlotsServeOnlyReservedRequests) {
  std::vector<int> held;
  for (int i = 0; i < 42; ++i) held.push_back(Connect());
  WaitOpen(42);
  // In the reserve: the worker protocol and /healthz are served, anything else refused at once.
  const std::string refused = Ask("/hello");
  EXPECT_THAT(refused, ::testing::StartsWith("HTTP/1.1 429")) << refused;
  EXPECT_THAT(refused, ::testing::HasSubstr("nearly all taken"));
  EXPECT_THAT(Ask("/reserved"), ::testing::StartsWith("HTTP/1.1 200"));
  for (int fd : held) close(fd);
}

// The reserve belongs to no client: one client (a local crowd, all of loopback) that holds every
// slot, the reserve's too, with silent connections cannot keep out a reserved request of its own
// address (a local worker's heartbeat): the newcomer takes the slot of the reserve's connection
// opened first, which is closed.
TEST_F(GuardedHttpServerReserveTest, ANewcomerTakesTheSlotOfTheReservesOldestSilentConnection) {
  std::vector<int> held;
  for (int i = 0; i < 48; ++i) held.push_back(Connect());
  WaitOpen(48);
  // Served on a full table, again and again: each time the oldest silent reserve connection goes.
  // (The crowd fills the table again after each.)
  for (int round = 0; round < 10; ++round) {
    EXPECT_THAT(Ask("/reserved"), ::testing::StartsWith("HTTP/1.1 200")) << "round " << round;
    for (int i = 0; i < 500 && server_->open_connections() >= 48; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(5));
    held.push_back(Connect());
    WaitOpen(48);
  }
  EXPECT_EQ(server_->reserve_taken(), 10);
  int closed = 0;
  for (size_t i = 0; i < held.size(); ++i) {
    char byte;
    const bool gone = recv(held[i], &byte, 1, MSG_DONTWAIT) == 0;
    closed += gone ? 1 : 0;
    if (i < 42) {
      EXPECT_FALSE(gone) << "connection " << i << " was not in the reserve";
    }
    if (i >= 42 && i < 52) {
      EXPECT_TRUE(gone) << "connection " << i << ": the reserve's oldest go first";
    }
  }
  EXPECT_EQ(closed, 10);
  for (int fd : held) close(fd);
}

TEST_F(GuardedHttpServerTest, ARequestHeadLargerThanTheBufferIsAnswered431WithoutAThread) {
  const int fd = Connect();
  Send(fd, "GET /hello HTTP/1.1\r\nHost: x\r\nX-Big: " + std::string(20 * 1024, 'a'));
  std::string got;
  char buf[4096];
  ssize_t n;
  while ((n = recv(fd, buf, sizeof buf, 0)) > 0) got.append(buf, static_cast<size_t>(n));
  close(fd);
  EXPECT_THAT(got, ::testing::StartsWith("HTTP/1.1 431")) << got;
  EXPECT_THAT(Ask("/hello"), ::testing::StartsWith("HTTP/1.1 200"));
}

// The same server over TLS, with a self-signed certificate made for the test.
class GuardedHttpsServerTest : public GuardedHttpServerTest {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("sandswim-tls-" + std::to_string(getpid()) + "-" + std::to_string(Steady::now().time_since_epoch().count()));
    auto files = LoadOrCreateSelfSigned(dir_.string(), {});
    ASSERT_TRUE(files.ok()) << files.status().ToString();
    files_ = *files;
    GuardedHttpServerTest::SetUp();
  }
  void TearDown() override {
    GuardedHttpServerTest::TearDown();
    std::filesystem::remove_all(dir_);
  }
  void Configure(GuardedHttpServer& server) override {
    std::string error;
    ASSERT_TRUE(server.SetTls(files_.cert, files_.key, &error)) << error;
  }
  std::unique_ptr<httplib::Client> Client(const TlsTrust& trust) {
    ClientOptions options;
    options.server = "https://127.0.0.1:" + std::to_string(port_);
    options.tls = trust;
    return NewHttpClient(options);
  }

  std::filesystem::path dir_;
  TlsFiles files_;
};

TEST_F(GuardedHttpsServerTest, APinnedClientIsServedAndAWrongPinIsRefusedWithTheReason) {
  auto pinned = Client(TlsTrust{"", files_.fingerprint});
  for (int i = 0; i < 3; ++i) {
    auto r = pinned->Get("/hello");
    ASSERT_TRUE(r) << httplib::to_string(r.error());
    EXPECT_EQ(r->status, 200);
    EXPECT_EQ(r->body, "hi");
  }
  // The certificate as a CA file: it names 127.0.0.1.
  auto by_ca = Client(TlsTrust{files_.cert, ""});
  auto r = by_ca->Get("/hello");
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 200);

  std::string wrong_pin = files_.fingerprint;
  wrong_pin.back() = wrong_pin.back() == '0' ? '1' : '0';
  auto wrong = Client(TlsTrust{"", wrong_pin});
  auto refused = wrong->Get("/hello");
  ASSERT_FALSE(refused);
  std::optional<Status> why = TlsFailure(*wrong, static_cast<int>(refused.error()), "https://127.0.0.1");
  ASSERT_TRUE(why.has_value());
  EXPECT_EQ(why->code(), StatusCode::kUnauthenticated);
  EXPECT_THAT(why->reason(), ::testing::HasSubstr("presented a certificate with fingerprint " + files_.fingerprint));
  EXPECT_THAT(why->reason(), ::testing::HasSubstr("not the pinned " + wrong_pin));
  EXPECT_FALSE(DaemonTrouble(*why)) << "a mismatch is not retried as the daemon's trouble";

  // The system's CAs do not know a self-signed certificate.
  auto system = Client(TlsTrust{});
  auto untrusted = system->Get("/hello");
  ASSERT_FALSE(untrusted);
  why = TlsFailure(*system, static_cast<int>(untrusted.error()), "https://127.0.0.1");
  ASSERT_TRUE(why.has_value());
  EXPECT_THAT(why->reason(), ::testing::HasSubstr("does not trust"));
  EXPECT_THAT(why->reason(), ::testing::HasSubstr("--tls-fingerprint"));
}

TEST_F(GuardedHttpsServerTest, PlainHttpGetsNoAnswerAndASlowHandshakeHoldsNoThread) {
  // Plain HTTP to the TLS port: the handshake fails, the connection is closed.
  const std::string plain = Ask("/hello");
  EXPECT_THAT(plain, ::testing::Not(::testing::HasSubstr("200 OK")));
  // A handshake started and left: closed at the head's deadline, while a pinned client is served.
  const int stalled = Connect();
  Send(stalled, std::string("\x16\x03\x01\x00\xff\x01", 6));
  auto pinned = Client(TlsTrust{"", files_.fingerprint});
  auto r = pinned->Get("/hello");
  ASSERT_TRUE(r) << httplib::to_string(r.error());
  EXPECT_EQ(r->status, 200);
  const double closed_after = SecondsUntilClosed(stalled, 10);
  close(stalled);
  EXPECT_GE(closed_after, 0) << "a stalled handshake was not cut off in 10 s";
  EXPECT_LT(closed_after, 4);
}

TEST(SelfSignedCertificateTest, IsMadeOnceWithAPrivateKeyAndAStableFingerprint) {
  const auto dir = std::filesystem::temp_directory_path() / ("sandswim-cert-" + std::to_string(getpid()));
  std::filesystem::remove_all(dir);
  auto made = LoadOrCreateSelfSigned(dir.string(), {"login1.example", "10.1.2.3"});
  ASSERT_TRUE(made.ok()) << made.status().ToString();
  EXPECT_TRUE(made->created);
  EXPECT_EQ((std::filesystem::status(made->key).permissions() & std::filesystem::perms::all),
            std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  EXPECT_THAT(made->fingerprint, ::testing::MatchesRegex("SHA256(:[0-9A-F][0-9A-F]){32}"));
  auto again = LoadOrCreateSelfSigned(dir.string(), {});
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  EXPECT_FALSE(again->created);
  EXPECT_EQ(again->fingerprint, made->fingerprint);
  auto read = CertificateFingerprint(made->cert);
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(*read, made->fingerprint);
  // A key others may read is refused, with the chmod to run.
  std::filesystem::permissions(made->key, std::filesystem::perms::group_read, std::filesystem::perm_options::add);
  auto loose = LoadOrCreateSelfSigned(dir.string(), {});
  ASSERT_FALSE(loose.ok());
  EXPECT_THAT(loose.status().reason(), ::testing::HasSubstr("chmod 600 " + made->key));
  std::filesystem::remove_all(dir);
}

TEST(FingerprintTest, IsReadInTheFormsPeopleCopy) {
  const std::string hex = "ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01ab01";
  auto plain = ParseFingerprint(hex, "--tls-fingerprint");
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(plain->substr(0, 16), "SHA256:AB:01:AB:");
  auto openssl = ParseFingerprint("sha256 Fingerprint=" + plain->substr(7), "--tls-fingerprint");
  ASSERT_TRUE(openssl.ok());
  EXPECT_EQ(*openssl, *plain);
  auto same = ParseFingerprint(*plain, "x");
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(*same, *plain);
  auto bad = ParseFingerprint("SHA256:AB:CD", "--tls-fingerprint");
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field(), "--tls-fingerprint");
}

}  // namespace
}  // namespace sandswim
