#include "platform/http_client.h"

#include <chrono>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "platform/http_status.h"

namespace sandswim {
namespace {

// A real server on a loopback port that answers /status/N with HTTP N: a problem document for
// N = 400..499 and 500, plain text otherwise.
class StatusServer {
 public:
  StatusServer() {
    server_.Get(R"(/status/(\d+))", [](const httplib::Request& req, httplib::Response& res) {
      const int code = std::stoi(req.matches[1]);
      res.status = code;
      if ((code >= 400 && code < 500) || code == 500) {
        res.set_content(R"({"type":"urn:sandswim:problem:x","title":"t","status":)" + std::to_string(code) +
                            R"(,"detail":"A: must be > 0","field":"A"})",
                        "application/problem+json");
      } else {
        res.set_content("upstream trouble", "text/plain");
      }
    });
    port_ = server_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    // stop() before the loop runs would be lost: wait until it runs.
    for (int i = 0; i < 5000 && !server_.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ~StatusServer() {
    server_.stop();
    thread_.join();
  }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }

 private:
  httplib::Server server_;
  std::thread thread_;
  int port_ = 0;
};

Status Ask(const StatusServer& server, int code) {
  ClientOptions options;
  options.server = server.url();
  auto client = NewHttpClient(options);
  const std::string path = "/status/" + std::to_string(code);
  httplib::Result res = client->Get(path);
  EXPECT_TRUE(res) << path;
  if (!res) return Status::Unavailable("no answer");
  return StatusFromHttp(res->status, res->body, "GET " + path);
}

TEST(HttpClientTest, EveryStatusMapsAsTheTableSays) {
  StatusServer server;
  const std::pair<int, StatusCode> table[] = {
      {400, StatusCode::kInvalidArgument}, {401, StatusCode::kUnauthenticated},
      {403, StatusCode::kUnauthenticated}, {404, StatusCode::kNotFound},
      {409, StatusCode::kConflict},        {413, StatusCode::kResourceExhausted},
      {418, StatusCode::kInvalidArgument}, {422, StatusCode::kFailedPrecondition},
      {500, StatusCode::kInternal},        {501, StatusCode::kInternal},
      {502, StatusCode::kUnavailable},     {503, StatusCode::kUnavailable},
      {504, StatusCode::kUnavailable},
  };
  for (const auto& [http, code] : table) {
    Status s = Ask(server, http);
    EXPECT_EQ(s.code(), code) << "HTTP " << http << ": " << s.ToString();
    EXPECT_EQ(StatusCodeForAnswer(http), code) << http;
    // 5xx is the daemon's trouble, never the request's.
    EXPECT_EQ(DaemonTrouble(s), http >= 500) << http;
  }
}

TEST(HttpClientTest, AProblemKeepsItsDetailAndField) {
  StatusServer server;
  Status s = Ask(server, 422);
  // The detail "A: must be > 0" names its field; the Status holds field and reason apart, so
  // whatever prints both names the field once.
  EXPECT_EQ(s.reason(), "must be > 0");
  EXPECT_EQ(s.field(), "A");
  EXPECT_THAT(s.ToString(), ::testing::EndsWith(": A: must be > 0"));
  EXPECT_EQ(s.ToString().find("A: A:"), std::string::npos);
  // Without a problem document: the status, the call and the start of the body.
  Status plain = Ask(server, 503);
  EXPECT_EQ(plain.reason(), "HTTP 503 for GET /status/503: upstream trouble");
  EXPECT_EQ(plain.field(), "");
}

// The CLI printed "Authorization: Authorization: this daemon has a token ..." for a refusal: the
// detail's leading field is taken off once, and only when it is the problem's field followed by ": ".
TEST(HttpClientTest, ADetailNamesItsFieldOnce) {
  auto problem = [](const std::string& detail, const std::string& field) {
    return R"({"type":"urn:sandswim:problem:unauthenticated","status":401,"detail":")" + detail +
           R"(","field":")" + field + R"("})";
  };
  Status s = StatusFromHttp(401, problem("Authorization: this daemon has a token", "Authorization"), "GET /x");
  EXPECT_EQ(s.reason(), "this daemon has a token");
  EXPECT_EQ(s.field(), "Authorization");
  // A detail that does not start with its field is kept whole.
  EXPECT_EQ(StatusFromHttp(422, problem("axes[0].values: A: must be > 0", "A"), "GET /x").reason(),
            "axes[0].values: A: must be > 0");
  EXPECT_EQ(StatusFromHttp(422, problem("Ab: must be > 0", "A"), "GET /x").reason(), "Ab: must be > 0");
  // Nothing after the field: the answer's own words stand.
  EXPECT_EQ(StatusFromHttp(422, problem("A: ", "A"), "GET /x").reason(), "A: ");
  EXPECT_EQ(StatusFromHttp(422, problem("no field here", ""), "GET /x").reason(), "no field here");
}

TEST(HttpClientTest, NoDaemonIsNoAnswer) {
  // A port nothing listens on: the server is stopped before the call.
  std::string url;
  { url = StatusServer().url(); }
  ClientOptions options;
  options.server = url;
  options.connect_timeout_s = 1;
  httplib::Result res = NewHttpClient(options)->Get("/status/200");
  EXPECT_FALSE(res);
}

}  // namespace
}  // namespace sandswim
