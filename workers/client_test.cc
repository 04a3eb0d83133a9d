// HttpServerClient against a real httplib server on an ephemeral port of 127.0.0.1.
#include "workers/client.h"

#include <arpa/inet.h>
#include <httplib.h>
#include <netinet/in.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <fstream>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "platform/clock.h"

namespace sandswim::worker {
namespace {

class FakeDaemon {
 public:
  FakeDaemon() {
    port_ = server_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    // The socket already listens (bind_to_any_port), so early connections queue; still, wait.
    for (int i = 0; i < 10000 && !server_.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (!server_.is_running()) ADD_FAILURE() << "the fake daemon did not start listening within 10 s";
  }
  ~FakeDaemon() {
    server_.stop();
    thread_.join();
  }
  httplib::Server& server() { return server_; }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }

 private:
  httplib::Server server_;
  int port_ = 0;
  std::thread thread_;
};

ClientOptions ClientOptionsFor(const std::string& url) {
  ClientOptions o;
  o.server = url;
  o.token = "secret";
  o.retry_for_s = 5;
  o.connect_timeout_s = 1;
  o.read_timeout_s = 5;
  return o;
}

TEST(ClientTest, LeaseSendsTheTokenAndReadsTheGrant) {
  FakeDaemon d;
  std::string auth;
  std::atomic<int> calls{0};
  d.server().Post("/api/v1/leases", [&](const httplib::Request& req, httplib::Response& res) {
    auth = req.get_header_value("Authorization");
    auto r = nlohmann::json::parse(req.body).get<api::LeaseRequest>();
    if (calls++ > 0) {
      res.status = 204;
      return;
    }
    api::LeaseGrant g;
    g.token = "t1";
    g.id = 5;
    g.deck = "deck for " + r.worker;
    res.set_content(nlohmann::json{{"lease", g}}.dump(), "application/json");
  });
  HttpServerClient client(ClientOptionsFor(d.url()));
  auto lease = client.Lease(api::LeaseRequest{"w:1", "h", 1});
  ASSERT_TRUE(lease.ok()) << lease.status().ToString();
  ASSERT_TRUE(lease->has_value());
  EXPECT_EQ((*lease)->token, "t1");
  EXPECT_EQ((*lease)->deck, "deck for w:1");
  EXPECT_EQ(auth, "Bearer secret");
  auto none = client.Lease(api::LeaseRequest{"w:1", "h", 1});
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
}

TEST(ClientTest, HeartbeatConflictIsLeaseLost) {
  FakeDaemon d;
  d.server().Post(R"(/api/v1/leases/([^/]+)/heartbeat)", [&](const httplib::Request& req, httplib::Response& res) {
    if (req.matches[1] == "gone") {
      res.status = 409;
      res.set_content(R"({"error":"lease lost"})", "application/json");
      return;
    }
    res.set_content(R"({"ttl_s":30,"cancel":true})", "application/json");
  });
  HttpServerClient client(ClientOptionsFor(d.url()));
  auto ok = client.Heartbeat("t1", api::Heartbeat{0.1, -0.01, 100});
  ASSERT_TRUE(ok.ok());
  EXPECT_TRUE(ok->cancel);
  auto lost = client.Heartbeat("gone", api::Heartbeat{});
  EXPECT_EQ(lost.status().code(), StatusCode::kConflict);
}

TEST(ClientTest, CompleteRetriesWhileTheDaemonAnswers503) {
  FakeDaemon d;
  std::atomic<int> calls{0};
  d.server().Post(R"(/api/v1/leases/([^/]+)/complete)", [&](const httplib::Request& req, httplib::Response& res) {
    if (calls++ < 2) {
      res.status = 503;
      return;
    }
    auto c = nlohmann::json::parse(req.body).get<api::Completion>();
    res.set_content(nlohmann::json{{"state", c.ok ? "done" : "failed"}}.dump(), "application/json");
  });
  FakeClock clock;  // the waits between tries move it; nothing waits in real time
  HttpServerClient client(ClientOptionsFor(d.url()), nullptr, &clock);
  api::Completion c;
  c.ok = true;
  auto reply = client.Complete("t1", c);
  ASSERT_TRUE(reply.ok()) << reply.status().ToString();
  EXPECT_EQ(reply->state, "done");
  EXPECT_EQ(calls.load(), 3);
  EXPECT_NEAR(clock.Monotonic(), 0.2 + 0.4, 1e-9);  // the backoff doubles from 0.2 s
}

// A daemon that answers 503 for good: the completion is tried until retry_for_s (5 s) of the
// clock has passed, the wait doubling (0.2, 0.4, 0.8, 1.6, 3.2 s), and then reported Unavailable.
TEST(ClientTest, RetriesEndWhenRetryForHasPassed) {
  FakeDaemon d;
  std::atomic<int> calls{0};
  d.server().Post(R"(/api/v1/leases/([^/]+)/complete)", [&](const httplib::Request&, httplib::Response& res) {
    ++calls;
    res.status = 503;
  });
  FakeClock clock;
  HttpServerClient client(ClientOptionsFor(d.url()), nullptr, &clock);
  auto reply = client.Complete("t1", api::Completion{});
  EXPECT_EQ(reply.status().code(), StatusCode::kUnavailable) << reply.status().ToString();
  EXPECT_EQ(calls.load(), 6);  // at 0, 0.2, 0.6, 1.4, 3.0 and 6.2 s
  EXPECT_NEAR(clock.Monotonic(), 6.2, 1e-9);
}

// Engine text that is not valid UTF-8 (LIGGGHTS has printed stray bytes after an ERROR line)
// reaches the daemon as valid JSON, the bad bytes replaced by U+FFFD; it never throws.
TEST(ClientTest, CompletionWithInvalidUtf8FromTheEngineIsSentReplaced) {
  FakeDaemon d;
  std::string log_tail, message;
  d.server().Post(R"(/api/v1/leases/([^/]+)/complete)", [&](const httplib::Request& req, httplib::Response& res) {
    auto c = nlohmann::json::parse(req.body).get<api::Completion>();  // throws on invalid UTF-8
    log_tail = c.log_tail;
    message = c.failure ? c.failure->message : "";
    res.set_content(R"({"state": "failed"})", "application/json");
  });
  HttpServerClient client(ClientOptionsFor(d.url()));
  api::Completion c;
  c.ok = false;
  c.failure = api::Failure{"deck_error", "ERROR: Invalid pair style \xF4oU` (./src/force.cpp:247)"};
  c.log_tail = "ERROR: Invalid pair style (./src/force.cpp:247)\n \xF4oU`\x05 (./src/force.cpp:247)\n";
  auto reply = client.Complete("t1", c);
  ASSERT_TRUE(reply.ok()) << reply.status().ToString();
  EXPECT_EQ(reply->state, "failed");
  EXPECT_EQ(log_tail, "ERROR: Invalid pair style (./src/force.cpp:247)\n \xEF\xBF\xBDoU`\x05 (./src/force.cpp:247)\n");
  EXPECT_NE(message.find("\xEF\xBF\xBDoU`"), std::string::npos) << message;
}

TEST(ClientTest, DaemonDownIsUnavailableAndRetriesStopWhenStopping) {
  // A port nobody listens on: bind one, then close it.
  int port = 0;
  {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ASSERT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
    socklen_t len = sizeof(addr);
    getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
    port = ntohs(addr.sin_port);
    close(fd);  // bound, never listened, now closed: connections are refused
  }
  std::atomic<bool> stopping{true};
  HttpServerClient client(ClientOptionsFor("http://127.0.0.1:" + std::to_string(port)), &stopping);
  auto lease = client.Lease(api::LeaseRequest{});
  EXPECT_EQ(lease.status().code(), StatusCode::kUnavailable);
  auto reply = client.Complete("t", api::Completion{});
  EXPECT_EQ(reply.status().code(), StatusCode::kUnavailable);
}

TEST(ClientTest, BedDownloadAndUpload) {
  FakeDaemon d;
  std::string uploaded, sha_header, token_param;
  d.server().Get("/api/v1/beds/3/restart", [](const httplib::Request&, httplib::Response& res) {
    res.set_content(std::string(100000, 'b'), "application/octet-stream");
  });
  d.server().Get("/api/v1/beds/4/restart", [](const httplib::Request&, httplib::Response& res) {
    res.status = 404;
    res.set_content("no such bed", "text/plain");
  });
  d.server().Put("/api/v1/beds/3/restart", [&](const httplib::Request& req, httplib::Response& res) {
    uploaded = req.body;
    sha_header = req.get_header_value("X-Sha256");
    token_param = req.get_param_value("token");
    res.set_content("{}", "application/json");
  });
  HttpServerClient client(ClientOptionsFor(d.url()));
  char tmpl[] = "/tmp/sandswim-client-XXXXXX";
  std::string dir = mkdtemp(tmpl);
  ASSERT_TRUE(client.DownloadBed(api::BedRef{3, "", ""}, dir + "/bed").ok());
  std::ifstream in(dir + "/bed", std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), std::string(100000, 'b'));
  Status missing = client.DownloadBed(api::BedRef{4, "", "/api/v1/beds/4/restart"}, dir + "/bed4");
  EXPECT_EQ(missing.code(), StatusCode::kNotFound);
  ASSERT_TRUE(client.UploadBed(3, "tok", dir + "/bed", "abc").ok());
  EXPECT_EQ(uploaded.size(), 100000u);
  EXPECT_EQ(sha_header, "abc");
  EXPECT_EQ(token_param, "tok");
}

}  // namespace
}  // namespace sandswim::worker
