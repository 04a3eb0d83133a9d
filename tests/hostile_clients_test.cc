// Hostile clients: the real sandswimd, a real sandswim-worker whose engine is the
// STAND-IN (tests/bench/stand_in_engine.cc: it simulates nothing, so that only the service is
// under test), and clients that try to take the daemon's threads or feed it what no client should:
// more slow and silent connections than it has threads, deeply nested JSON, a body larger than any
// allowed, a body that says it is shorter than it is. Throughout, the daemon must keep answering
// other clients and the worker's heartbeats (no lease lost, every run done once), and none of it
// may reach the database.
//
// The daemon's limits (server/http/guarded_http_server.h): a request head within --http-head-timeout
// (10 s; 3 s here, to keep the test short) of its first byte, silence 5 s, a body at 256 KiB/s
// after 30 s; 192 request threads and 16 more for the worker protocol; idle connections (and
// heads still arriving) wait in one poller and hold no thread.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <thread>

#include <httplib.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using Steady = std::chrono::steady_clock;

double SecondsSince(Steady::time_point t) { return std::chrono::duration<double>(Steady::now() - t).count(); }

// The hostile connections come from 127.0.0.2: one client past its connection cap (64), which
// the daemon serves only /healthz and the worker protocol, while the status queries below come
// from 127.0.0.1, another client.
int Connect(const std::string& listen) { return testing::ConnectTo(listen, "127.0.0.2"); }

void Send(int fd, const std::string& bytes) {
  for (size_t off = 0; off < bytes.size();) {
    const ssize_t n = send(fd, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (n <= 0) return;
    off += static_cast<size_t>(n);
  }
}

// Everything the daemon answers on `fd` until it closes the connection or `limit_s` passes.
std::string ReadUntilClosed(int fd, double limit_s) {
  std::string got;
  const auto start = Steady::now();
  while (SecondsSince(start) < limit_s) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 100) <= 0) continue;
    char buf[4096];
    const ssize_t n = recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    got.append(buf, static_cast<size_t>(n));
  }
  return got;
}

class HostileClientsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::CacheDir() + "/hostile-clients";
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    starts_log_ = dir_ + "/engine-starts.log";
    setenv("SANDSWIM_STAND_IN_STARTS", starts_log_.c_str(), 1);
    setenv("SANDSWIM_STAND_IN_SECONDS", "1", 1);
    daemon_ = std::make_unique<testing::Daemon>(
        dir_ + "/daemon", std::vector<std::string>{"--lease-ttl", "30", "--http-head-timeout", std::to_string(kHeadS),
                                                   // 127.0.0.2 (the hostile client) stands for another host
                                                   "--http-loopback-clients-apart"});
    int status = 0;
    std::vector<double> omegas;
    for (int i = 0; i < kRuns; ++i) omegas.push_back(-10.0 - i);
    json submitted = daemon_->Post("/api/v1/sweeps", testing::OmegaSweep("hostile", omegas, 0.05, 20), &status);
    ASSERT_EQ(status, 201) << submitted.dump();
    sweep_ = submitted["id"].get<int64_t>();
    worker_ = testing::StartWorker(*daemon_, dir_ + "/worker", 1,
                                   {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  }

  // Every run done, once, with no lease lost; nothing else stored.
  void ExpectTheSweepFinishedUntouched() {
    const json s = daemon_->WaitForSweep(sweep_, 120);
    worker_->Stop();
    EXPECT_EQ(s["counts"]["done"], kRuns) << s.dump() << "\n" << worker_->Output();
    EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM runs"), "1") << "a lease was lost";
    EXPECT_EQ(daemon_->Query("SELECT count(*) FROM results"), std::to_string(kRuns));
    EXPECT_EQ(daemon_->Query("SELECT count(*) FROM sweeps"), "1");
    EXPECT_EQ(daemon_->Query("SELECT count(*) FROM runs"), std::to_string(kRuns));
    EXPECT_EQ(daemon_->Query("PRAGMA integrity_check"), "ok");
    EXPECT_TRUE(daemon_->process().running());
  }

  static constexpr int kRuns = 5;
  static constexpr double kHeadS = 3;
  std::string dir_, starts_log_;
  std::unique_ptr<testing::Daemon> daemon_;
  std::unique_ptr<testing::ChildProcess> worker_;
  int64_t sweep_ = 0;
};

// 250 clients sending their request head a byte each half second and 100 that say nothing: more
// connections than the daemon has threads. Each is closed at its deadline, the daemon answers a
// status query meanwhile within one head deadline, and the worker's heartbeats keep its lease.
TEST_F(HostileClientsTest, SlowAndSilentConnectionsBeyondThePoolDelayOthersBoundedly) {
  const std::string listen = daemon_->listen();
  constexpr int kSlow = 250, kSilent = 100;
  std::vector<int> slow, silent;
  for (int i = 0; i < kSlow; ++i) {
    slow.push_back(Connect(listen));
    ASSERT_GE(slow.back(), 0);
    Send(slow.back(), "GET /api/v1/sweeps HTTP/1.1\r\nHost: " + listen + "\r\nX-Slow: ");
  }
  for (int i = 0; i < kSilent; ++i) {
    silent.push_back(Connect(listen));
    ASSERT_GE(silent.back(), 0);
  }
  httplib::Client patient(daemon_->url());  // one that waits as long as the deadlines may make it
  patient.set_read_timeout(30, 0);
  const auto start = Steady::now();
  std::vector<double> closed_at(kSlow + kSilent, -1);
  double worst_query_s = 0;
  int queries = 0;
  auto next_query = Steady::now();
  while (SecondsSince(start) < 40 && std::count(closed_at.begin(), closed_at.end(), -1.0) > 0) {
    for (int i = 0; i < kSlow + kSilent; ++i) {
      if (closed_at[i] >= 0) continue;
      const int fd = i < kSlow ? slow[i] : silent[i - kSlow];
      if (i < kSlow) Send(fd, "a");
      char buf[4096];  // what the daemon says before it closes (a 400 for a head cut off mid-headers)
      ssize_t n;
      while ((n = recv(fd, buf, sizeof buf, MSG_DONTWAIT)) > 0) {
      }
      if (n == 0 || (n < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) closed_at[i] = SecondsSince(start);
    }
    if (Steady::now() >= next_query) {  // another client's status query, timed
      const auto q = Steady::now();
      auto r = patient.Get("/api/v1/sweeps/" + std::to_string(sweep_));
      ASSERT_TRUE(r) << "a status query failed: " << httplib::to_string(r.error());
      EXPECT_EQ(r->status, 200);
      worst_query_s = std::max(worst_query_s, SecondsSince(q));
      ++queries;
      next_query = Steady::now() + std::chrono::milliseconds(500);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  for (int fd : slow) close(fd);
  for (int fd : silent) close(fd);
  const double last_slow = *std::max_element(closed_at.begin(), closed_at.begin() + kSlow);
  const double last_silent = *std::max_element(closed_at.begin() + kSlow, closed_at.end());
  EXPECT_EQ(std::count(closed_at.begin(), closed_at.end(), -1.0), 0) << "connections the daemon never closed";
  // Heads arrive in the poller, not on threads: all 250 are cut at one deadline; the silent ones
  // after their 5 s of silence.
  EXPECT_LT(last_slow, 2 * kHeadS + 5);
  EXPECT_LT(worst_query_s, kHeadS + 2) << "another client waited longer than one head deadline";
  EXPECT_THAT(daemon_->process().Output(),
              ::testing::HasSubstr("its request head did not arrive in time (a slow or stalled client"));
  const double first_slow = *std::min_element(closed_at.begin(), closed_at.begin() + kSlow);
  // None before its deadline: a connection reset early was dropped, not served.
  EXPECT_GT(first_slow, kHeadS - 1);
  std::printf("HOSTILE %d slow + %d silent connections: slow ones closed from %.1f s to %.1f s, the last silent "
              "one after %.1f s; %d status queries meanwhile, the slowest %.2f s\n",
              kSlow, kSilent, first_slow, last_slow, last_silent, queries, worst_query_s);
  ExpectTheSweepFinishedUntouched();
}

// Bodies no client should send: each answered with a problem naming the body (or the connection
// closed), none stored, and the daemon serves on.
TEST_F(HostileClientsTest, BodiesThatNestLieOrOverflowChangeNothing) {
  const std::string listen = daemon_->listen();
  auto post = [&](const std::string& body, const std::string& length) {
    const int fd = Connect(listen);
    Send(fd, "POST /api/v1/sweeps HTTP/1.1\r\nHost: " + listen +
                 "\r\nContent-Type: application/json\r\n"
                 "Connection: close\r\nContent-Length: " +
                 length + "\r\n\r\n" + body);
    std::string answer = ReadUntilClosed(fd, 15);
    close(fd);
    return answer;
  };
  // 100,000 nested arrays, and a sweep whose axes nest 10,000 deep.
  const std::string arrays = std::string(100000, '[') + std::string(100000, ']');
  std::string nested = post(arrays, std::to_string(arrays.size()));
  EXPECT_THAT(nested, ::testing::StartsWith("HTTP/1.1 4")) << nested.substr(0, 300);
  EXPECT_THAT(nested, ::testing::HasSubstr("application/problem+json"));
  json sweep = testing::OmegaSweep("nested", {-5}, 0.05, 20);
  std::string deep = sweep.dump();
  deep.insert(deep.rfind('}'), ",\"deep\":" + std::string(10000, '[') + std::string(10000, ']'));
  std::string deep_answer = post(deep, std::to_string(deep.size()));
  EXPECT_THAT(deep_answer, ::testing::StartsWith("HTTP/1.1 4")) << deep_answer.substr(0, 300);
  // Larger than any body allowed: refused before a byte of it is read.
  std::string huge = post("", "2000000000");
  EXPECT_THAT(huge, ::testing::StartsWith("HTTP/1.1 413")) << huge.substr(0, 300);
  EXPECT_THAT(huge, ::testing::HasSubstr("\"field\":\"body\""));
  // A length shorter than the body: the sweep is cut where the length says (bad JSON); its tail is
  // never read.
  const std::string whole = testing::OmegaSweep("cut", {-5}, 0.05, 20).dump();
  std::string cut = post(whole, std::to_string(whole.size() - 20));
  EXPECT_THAT(cut, ::testing::StartsWith("HTTP/1.1 400")) << cut.substr(0, 300);
  EXPECT_THAT(cut, ::testing::HasSubstr("malformed JSON"));
  int status = 0;
  daemon_->Get("/api/v1/sweeps/" + std::to_string(sweep_), &status);
  EXPECT_EQ(status, 200);
  std::printf("HOSTILE bodies: nested %s | deep %s | huge %s | cut %s\n", nested.substr(0, 12).c_str(),
              deep_answer.substr(0, 12).c_str(), huge.substr(0, 12).c_str(), cut.substr(0, 12).c_str());
  ExpectTheSweepFinishedUntouched();
}

}  // namespace
}  // namespace sandswim
