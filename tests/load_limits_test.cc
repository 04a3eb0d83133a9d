// No single client can starve the daemon: the real sandswimd, a real sandswim-worker whose engine
// is the STAND-IN (tests/bench/stand_in_engine.cc), a short lease TTL (3 s: a heartbeat a second),
// and one client (127.0.0.1, the worker's own address) that opens 250 keep-alive connections,
// each asking for /healthz every 3 s, and 128 dashboard event streams. The worker must keep every
// lease, a fresh client must be answered, and another client's reads must be served. A closed
// event stream must give its slot back within seconds.
//
// The limits under test (server/http/guarded_http_server.h, sandswimd --help): idle connections hold
// no thread; 64 connections per client, past which only the worker protocol and /healthz are
// served; threads reserved for those; 8 event streams per client, each writing every 2 s.
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim {
namespace load_limits {  // a unity build puts this file beside hostile_clients_test.cc
namespace {

using nlohmann::json;
namespace fs = std::filesystem;
using Steady = std::chrono::steady_clock;

double SecondsSince(Steady::time_point t) { return std::chrono::duration<double>(Steady::now() - t).count(); }

void Send(int fd, const std::string& bytes) {
  for (size_t off = 0; off < bytes.size();) {
    const ssize_t n = send(fd, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (n <= 0) return;
    off += static_cast<size_t>(n);
  }
}

// What has arrived on `fd`, without waiting; false once the daemon closed it.
bool Drain(int fd, std::string* got = nullptr) {
  char buf[8192];
  for (;;) {
    const ssize_t n = recv(fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n > 0) {
      if (got != nullptr) got->append(buf, static_cast<size_t>(n));
      continue;
    }
    return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR);
  }
}

struct Answer {
  int status = 0;  // 0: no answer
  double seconds = 0;
  std::string text;
};

// One GET on a new connection from `from`, the whole answer (the connection says close).
// `headers`: more header lines, each ending in CRLF.
Answer Ask(const std::string& listen, const std::string& from, const std::string& path, double limit_s = 60,
           const std::string& headers = "") {
  Answer a;
  const auto start = Steady::now();
  const int fd = testing::ConnectTo(listen, from);
  if (fd < 0) return a;
  Send(fd, "GET " + path + " HTTP/1.1\r\nHost: " + listen + "\r\n" + headers + "Connection: close\r\n\r\n");
  while (SecondsSince(start) < limit_s) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 100) <= 0) continue;
    if (!Drain(fd, &a.text)) break;
  }
  close(fd);
  a.seconds = SecondsSince(start);
  if (a.text.rfind("HTTP/1.1 ", 0) == 0) a.status = std::atoi(a.text.c_str() + 9);
  return a;
}

class LoadLimitsTest : public ::testing::Test {
 protected:
  void StartDaemon(std::vector<std::string> extra, bool loopback_apart = true) {
    dir_ = testing::CacheDir() + "/load-limits";
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    // 127.0.0.2 (the other reader) stands for another host
    if (loopback_apart) extra.push_back("--http-loopback-clients-apart");
    daemon_ = std::make_unique<testing::Daemon>(dir_ + "/daemon", extra);
  }
  void TearDown() override {
    if (worker_) worker_->Stop();
  }

  std::string dir_;
  std::unique_ptr<testing::Daemon> daemon_;
  std::unique_ptr<testing::ChildProcess> worker_;
};

TEST_F(LoadLimitsTest, AKeepAliveCrowdAndItsStreamsCostNoWorkerItsLease) {
  setenv("SANDSWIM_STAND_IN_SECONDS", "6", 1);  // a bed and three runs of 6 s: ~24 s of heartbeats
  StartDaemon({"--lease-ttl", "3"});
  int status = 0;
  json submitted = daemon_->Post("/api/v1/sweeps", testing::OmegaSweep("crowd", {-10, -20, -30}, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t sweep = submitted["id"].get<int64_t>();
  worker_ = testing::StartWorker(*daemon_, dir_ + "/worker", 1,
                                 {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  const std::string listen = daemon_->listen();

  // The crowd: one client, the worker's address. Each keep-alive connection asks for /healthz every
  // 3 s; one the daemon closes is opened again.
  constexpr int kKeepAlive = 250, kStreams = 128;
  std::vector<int> crowd(kKeepAlive, -1);
  std::vector<Steady::time_point> next_ask(kKeepAlive, Steady::now());
  std::vector<int> streams;
  int streams_served = 0, streams_refused = 0;
  for (int i = 0; i < kStreams; ++i) {
    const int fd = testing::ConnectTo(listen);
    ASSERT_GE(fd, 0);
    Send(fd, std::string("GET /api/v1/live/events HTTP/1.1\r\nHost: ") + listen + "\r\n\r\n");
    streams.push_back(fd);
  }
  std::vector<std::string> stream_heads(kStreams);
  int64_t crowd_answers = 0, reconnects = 0;
  std::vector<double> fresh_healthz, other_reads;
  int fresh_failed = 0, other_failed = 0;
  auto next_probe = Steady::now() + std::chrono::seconds(1);
  const auto start = Steady::now();
  bool done = false;
  while (!done && SecondsSince(start) < 150) {
    const auto now = Steady::now();
    for (int i = 0; i < kKeepAlive; ++i) {
      if (crowd[i] >= 0) {
        std::string got;
        const bool open = Drain(crowd[i], &got);
        for (size_t at = got.find("HTTP/1.1 "); at != std::string::npos; at = got.find("HTTP/1.1 ", at + 1)) ++crowd_answers;
        if (!open) {
          close(crowd[i]);
          crowd[i] = -1;
          ++reconnects;
        }
      }
      if (now < next_ask[i]) continue;
      if (crowd[i] < 0) crowd[i] = testing::ConnectTo(listen);
      if (crowd[i] < 0) continue;
      Send(crowd[i], std::string("GET /healthz HTTP/1.1\r\nHost: ") + listen + "\r\n\r\n");
      next_ask[i] = now + std::chrono::seconds(3);
    }
    for (int i = 0; i < kStreams; ++i) {
      if (streams[i] < 0) continue;
      Drain(streams[i], &stream_heads[i]);  // its status line is counted below; the rest is dropped
      if (stream_heads[i].size() > 4096) stream_heads[i].resize(4096);
    }
    if (Steady::now() >= next_probe) {
      // A fresh client from the crowd's own address (past its cap: /healthz is still served), and
      // another client's read.
      const Answer healthz = Ask(listen, "", "/healthz");
      if (healthz.status == 200) fresh_healthz.push_back(healthz.seconds);
      else ++fresh_failed;
      const Answer read = Ask(listen, "127.0.0.2", "/api/v1/sweeps/" + std::to_string(sweep));
      if (read.status == 200) {
        other_reads.push_back(read.seconds);
        const size_t body = read.text.find("\r\n\r\n");
        const json s = json::parse(read.text.substr(body + 4), nullptr, false);
        done = s.is_object() && s["counts"]["queued"] == 0 && s["counts"]["running"] == 0;
      } else {
        ++other_failed;
      }
      next_probe = Steady::now() + std::chrono::seconds(1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  for (int i = 0; i < kStreams; ++i) {
    if (stream_heads[i].rfind("HTTP/1.1 200", 0) == 0) ++streams_served;
    else if (!stream_heads[i].empty()) ++streams_refused;
  }
  for (int fd : crowd) if (fd >= 0) close(fd);
  for (int fd : streams) close(fd);
  ASSERT_TRUE(done) << "the sweep did not finish under the crowd";
  const double worst_healthz = fresh_healthz.empty() ? -1 : *std::max_element(fresh_healthz.begin(), fresh_healthz.end());
  const double worst_read = other_reads.empty() ? -1 : *std::max_element(other_reads.begin(), other_reads.end());
  std::printf("LOAD %d keep-alive + %d streams from one client for %.0f s: %lld crowd answers, %lld reconnects; "
              "streams served %d, refused %d; fresh /healthz %zu, slowest %.3f s; other client's reads %zu, "
              "slowest %.3f s\n",
              kKeepAlive, kStreams, SecondsSince(start), static_cast<long long>(crowd_answers),
              static_cast<long long>(reconnects), streams_served, streams_refused, fresh_healthz.size(),
              worst_healthz, other_reads.size(), worst_read);
  EXPECT_EQ(fresh_failed, 0) << "a fresh client's /healthz was not answered 200";
  EXPECT_EQ(other_failed, 0) << "another client's read was not answered 200";
  // A bound only to catch a stall: the crowd once made /healthz wait 22-40 s.
  EXPECT_LT(worst_healthz, 5.0);
  EXPECT_GT(crowd_answers, 0);
  EXPECT_LE(streams_served, 8) << "event streams past the per-client cap";
  EXPECT_GE(streams_served, 1);
  // The worker kept every lease: each job leased once, every run done.
  EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM runs"), "1") << "a run's lease was lost";
  EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM beds"), "1") << "the bed's lease was lost";
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM runs WHERE state = 'done'"), "3");
  EXPECT_THAT(daemon_->process().Output(), ::testing::Not(::testing::HasSubstr("lease(s) expired")));
}

// The last connection slots (the reserve) belong to the worker protocol and /healthz, not to a
// client: a local crowd -- the worker's own client, as all of loopback is one by default -- that
// holds every slot with silent connections, opens a new one as soon as one is closed, and
// hammers /healthz, costs the worker no lease. 64 connections in all, the last 8 the reserve; the
// worker's connections find it full and take the slot of the reserve's connection that has waited
// longest without a request. (Before, one client held at most 4 of the reserve: the crowd took
// those 4 and the worker, the same client, was shut out: its heartbeats failed until the lease
// expired.)
TEST_F(LoadLimitsTest, ALocalCrowdHoldingTheReserveCostsNoWorkerItsLease) {
  setenv("SANDSWIM_STAND_IN_SECONDS", "4", 1);  // a bed and three runs of 4 s: ~16 s of heartbeats
  // With a token, as a daemon starts by default: the reserve serves the worker's calls because
  // they carry it (a worker call without it is an ordinary request).
  setenv("SANDSWIM_TOKEN", "0123456789abcdef0123456789abcdef", 1);
  struct Unset {
    ~Unset() { unsetenv("SANDSWIM_TOKEN"); }
  } unset;
  StartDaemon({"--lease-ttl", "3", "--http-max-connections", "64"}, /*loopback_apart=*/false);
  int status = 0;
  json submitted = daemon_->Post("/api/v1/sweeps", testing::OmegaSweep("reserve", {-10, -20, -30}, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t sweep = submitted["id"].get<int64_t>();
  const std::string listen = daemon_->listen();
  // The crowd, from 127.0.0.1 and 127.0.0.3 (one client): 100 silent holders, more than the
  // daemon keeps open, each opened again once closed; 30 connections asking /healthz every 50 ms.
  constexpr int kHolders = 100, kHammers = 30;
  std::vector<int> holders(kHolders, -1), hammers(kHammers, -1);
  int64_t holder_opens = 0, hammer_answers = 0;
  auto tend = [&](std::vector<int>& fds, bool ask, int64_t* answers) {
    for (size_t i = 0; i < fds.size(); ++i) {
      if (fds[i] >= 0) {
        std::string got;
        const bool open = Drain(fds[i], &got);
        if (answers != nullptr) {
          for (size_t at = got.find("HTTP/1.1 200"); at != std::string::npos; at = got.find("HTTP/1.1 200", at + 1)) ++*answers;
        }
        if (!open) {
          close(fds[i]);
          fds[i] = -1;
        }
      }
      if (fds[i] < 0) {
        fds[i] = testing::ConnectTo(listen, i % 2 == 0 ? "" : "127.0.0.3");
        if (fds[i] >= 0 && !ask) ++holder_opens;
      }
      if (fds[i] >= 0 && ask) Send(fds[i], std::string("GET /healthz HTTP/1.1\r\nHost: ") + listen + "\r\n\r\n");
    }
  };
  const auto start = Steady::now();
  while (SecondsSince(start) < 2) {  // the table full before the worker comes
    tend(holders, false, nullptr);
    tend(hammers, true, &hammer_answers);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  worker_ = testing::StartWorker(*daemon_, dir_ + "/worker", 1,
                                 {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  std::vector<double> fresh_healthz;
  int fresh_failed = 0;
  auto next_probe = Steady::now() + std::chrono::seconds(1);
  bool done = false;
  while (!done && SecondsSince(start) < 120) {
    tend(holders, false, nullptr);
    tend(hammers, true, &hammer_answers);
    if (Steady::now() >= next_probe) {
      const Answer healthz = Ask(listen, "", "/healthz", 10);
      if (healthz.status == 200) fresh_healthz.push_back(healthz.seconds);
      else ++fresh_failed;
      done = daemon_->Query("SELECT count(*) FROM runs WHERE state IN ('queued', 'running')") == "0";
      next_probe = Steady::now() + std::chrono::seconds(1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  for (int fd : holders) if (fd >= 0) close(fd);
  for (int fd : hammers) if (fd >= 0) close(fd);
  std::sort(fresh_healthz.begin(), fresh_healthz.end());
  std::printf("LOAD reserve: %lld holder connections opened, %lld /healthz answered to the crowd in %.0f s; "
              "fresh /healthz %zu answered (slowest %.3f s), %d not\n",
              static_cast<long long>(holder_opens), static_cast<long long>(hammer_answers), SecondsSince(start),
              fresh_healthz.size(), fresh_healthz.empty() ? -1.0 : fresh_healthz.back(), fresh_failed);
  ASSERT_TRUE(done) << "the sweep did not finish under the crowd";
  EXPECT_GT(holder_opens, 64) << "the crowd never filled the daemon's connections";
  EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM runs"), "1") << "a run's lease was lost";
  EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM beds"), "1") << "the bed's lease was lost";
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM runs WHERE state = 'done'"), "3");
  EXPECT_THAT(daemon_->process().Output(), ::testing::Not(::testing::HasSubstr("lease(s) expired")));
  EXPECT_GT(fresh_healthz.size(), 0u) << "no fresh /healthz got a reserve slot";
  (void)sweep;
}

// A local user without the token cannot lock its holders out (issue #47, finding 1): all of
// loopback is one client, and 64 -- then 1,000 -- idle keep-alive connections of it, each asking
// /healthz every 3.5 s, hold the per-client cap. The token's holders (the CLI's GET /api/v1/sweeps
// on a fresh connection, ten a second) must all be answered 200, and the worker keep its leases.
TEST_F(LoadLimitsTest, AnIdleCrowdWithoutTheTokenLocksOutNoHolderOfIt) {
  setenv("SANDSWIM_STAND_IN_SECONDS", "4", 1);
  const std::string token = "0123456789abcdef0123456789abcdef";
  setenv("SANDSWIM_TOKEN", token.c_str(), 1);
  struct Unset {
    ~Unset() { unsetenv("SANDSWIM_TOKEN"); }
  } unset;
  StartDaemon({"--lease-ttl", "3"}, /*loopback_apart=*/false);
  int status = 0;
  json submitted = daemon_->Post("/api/v1/sweeps", testing::OmegaSweep("holders", {-10, -20, -30}, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const std::string listen = daemon_->listen();
  worker_ = testing::StartWorker(*daemon_, dir_ + "/worker", 1,
                                 {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  std::vector<int> crowd;
  std::vector<Steady::time_point> next_ask;
  int64_t crowd_refused = 0;
  auto tend = [&] {
    const auto now = Steady::now();
    for (size_t i = 0; i < crowd.size(); ++i) {
      if (crowd[i] >= 0) {
        std::string got;
        const bool open = Drain(crowd[i], &got);
        for (size_t at = got.find("HTTP/1.1 429"); at != std::string::npos; at = got.find("HTTP/1.1 429", at + 1)) {
          ++crowd_refused;
        }
        if (!open) {
          close(crowd[i]);
          crowd[i] = -1;
        }
      }
      if (now < next_ask[i]) continue;
      if (crowd[i] < 0) crowd[i] = testing::ConnectTo(listen, i % 2 == 0 ? "" : "127.0.0.3");
      if (crowd[i] < 0) continue;
      Send(crowd[i], std::string("GET /healthz HTTP/1.1\r\nHost: ") + listen + "\r\n\r\n");
      next_ask[i] = now + std::chrono::milliseconds(3500);
    }
  };
  for (const int size : {64, 1000}) {
    while (static_cast<int>(crowd.size()) < size) {
      crowd.push_back(testing::ConnectTo(listen, crowd.size() % 2 == 0 ? "" : "127.0.0.3"));
      next_ask.push_back(Steady::now());
    }
    const auto start = Steady::now();
    while (SecondsSince(start) < 1) tend();
    std::vector<double> served;
    int refused = 0;
    while (SecondsSince(start) < 11) {
      tend();
      const Answer read = Ask(listen, "", "/api/v1/sweeps", 10, "Authorization: Bearer " + token + "\r\n");
      if (read.status == 200) served.push_back(read.seconds);
      else ++refused;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    std::sort(served.begin(), served.end());
    const double p50 = served.empty() ? -1 : served[served.size() / 2];
    const double p99 = served.empty() ? -1 : served[std::min(served.size() - 1, served.size() * 99 / 100)];
    std::printf("LOAD %d idle loopback connections without the token: token holders %zu served (p50 %.1f ms, "
                "p99 %.1f ms), %d not; %lld of the crowd's requests refused 429\n",
                size, served.size(), p50 * 1e3, p99 * 1e3, refused, static_cast<long long>(crowd_refused));
    EXPECT_EQ(refused, 0) << "a token holder was refused under " << size << " idle connections";
    EXPECT_GT(served.size(), 20u);
    EXPECT_LT(p99, 2.0);
  }
  const auto start = Steady::now();
  bool done = false;
  while (!done && SecondsSince(start) < 90) {
    tend();
    done = daemon_->Query("SELECT count(*) FROM runs WHERE state IN ('queued', 'running')") == "0";
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  for (int fd : crowd) if (fd >= 0) close(fd);
  ASSERT_TRUE(done) << "the sweep did not finish under the crowd";
  EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM runs"), "1") << "a run's lease was lost";
  EXPECT_EQ(daemon_->Query("SELECT max(attempts) FROM beds"), "1") << "the bed's lease was lost";
}

// One stream per client here: a stream the page closes is noticed at the stream's next write (a
// comment line every 2 s), and its slot taken by the next page. Nothing changes on the board (no
// worker), so only those lines can notice it.
TEST_F(LoadLimitsTest, AClosedEventStreamGivesItsSlotBackWithinSeconds) {
  StartDaemon({"--live-streams-per-client", "1"});
  const std::string listen = daemon_->listen();
  auto open_stream = [&](std::string* head) {
    const int fd = testing::ConnectTo(listen);
    Send(fd, std::string("GET /api/v1/live/events HTTP/1.1\r\nHost: ") + listen + "\r\n\r\n");
    const auto start = Steady::now();
    while (SecondsSince(start) < 30 && head->find("\r\n\r\n") == std::string::npos) {
      pollfd p{fd, POLLIN, 0};
      if (poll(&p, 1, 100) > 0 && !Drain(fd, head)) break;
    }
    return fd;
  };
  std::string first;
  const int a = open_stream(&first);
  ASSERT_THAT(first, ::testing::StartsWith("HTTP/1.1 200")) << first;
  std::string second;
  const int b = open_stream(&second);
  EXPECT_THAT(second, ::testing::StartsWith("HTTP/1.1 503")) << "a second stream from the client";
  close(b);
  close(a);
  const auto closed = Steady::now();
  std::string next;
  int c = -1;
  while (SecondsSince(closed) < 60) {
    next.clear();
    c = open_stream(&next);
    if (next.rfind("HTTP/1.1 200", 0) == 0) break;
    close(c);
    c = -1;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  const double freed_after = SecondsSince(closed);
  if (c >= 0) close(c);
  std::printf("LOAD a closed event stream's slot was taken again after %.2f s\n", freed_after);
  ASSERT_THAT(next, ::testing::StartsWith("HTTP/1.1 200")) << "the slot never came back";
  // Its next comment line is at most 2 s away; the bound is generous for a loaded machine (it
  // took up to 15 s when streams wrote every 15 s, and the issue measured ~30 s).
  EXPECT_LT(freed_after, 8.0);
}

}  // namespace
}  // namespace load_limits
}  // namespace sandswim
