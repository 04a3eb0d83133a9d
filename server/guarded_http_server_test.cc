#include "server/guarded_http_server.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

using Steady = std::chrono::steady_clock;

double SecondsSince(Steady::time_point t) { return std::chrono::duration<double>(Steady::now() - t).count(); }

// A server with deadlines short enough to test: 0.5 s of silence, 0.5 s for a head, a body in
// 0.5 s + its length at 1 MB/s.
class GuardedHttpServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ConnectionLimits limits;
    limits.idle_s = 0.5;
    limits.head_s = 0.5;
    limits.body_grace_s = 0.5;
    limits.min_body_bytes_per_s = 1e6;
    server_ = std::make_unique<GuardedHttpServer>(limits);
    server_->Get("/hello", [](const httplib::Request&, httplib::Response& res) { res.set_content("hi", "text/plain"); });
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
    server_->stop();
    thread_.join();
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
  EXPECT_GE(closed_after, 0.3);
  EXPECT_GE(closed_after, 0) << "a head sent a byte each 0.1 s was not cut off in 10 s";
  EXPECT_LT(closed_after, 4);
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

}  // namespace
}  // namespace sandswim
