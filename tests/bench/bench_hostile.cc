// bench_hostile: what a greedy client costs everyone else, on the real sandswimd. One client
// (127.0.0.1) holds `--connections` keep-alive connections (default 250), each asking for /healthz
// every 3 s and opened again when the daemon closes it, while:
//  - a fresh client asks for /healthz every 0.2 s, on a new connection each time (latency);
//  - a worker holds a bed lease and heartbeats it every second, each heartbeat on a new connection
//    (as after any pause longer than the daemon's keep-alive), with a 6 s lease TTL (latency, and
//    whether the lease was lost: a heartbeat answered 409);
//  - `--readers` threads (default 4), another client (127.0.0.2), read a large sweep's results over
//    and over (GET /api/v1/sweeps/{id}/results of a `--read-runs`-run sweep, default 100,000,
//    following its pages (`Link: <...>; rel="next"`) to the end when the daemon pages, asking
//    `limit=--page` rows a page): the time and bytes of each whole read.
// The big sweep is written into the daemon's store before the daemon starts (Submit, as a POST
// would; a 100,000-value POST body is past the daemon's body limit), its runs queued. The daemon's
// resident memory is sampled every 0.1 s (peak, and at the start of the reads).
// With `--holders N` the crowd also holds N silent connections, each opened again as soon as the
// daemon closes it, and with `--max-connections M` (sandswimd --http-max-connections) the daemon
// keeps at most M: with N + --connections past M the crowd holds every slot, the reserve's too
// (the reserve attack: with --loopback-apart 0 the crowd and the worker are one client).
// It prints its figures. SANDSWIMD_UNDER_TEST=PATH measures another build's daemon (the
// same benchmark before and after a change).
//
//   bench_hostile [--connections 250] [--seconds 30] [--readers 4] [--read-runs 100000] [--page 10000]
//                 [--loopback-apart 1] [--holders 0] [--max-connections 4096]
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <strings.h>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "platform/clock.h"
#include "server/jobs/submission.h"
#include "server/store/store.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace {

using nlohmann::json;
using Steady = std::chrono::steady_clock;

double SecondsSince(Steady::time_point t) { return std::chrono::duration<double>(Steady::now() - t).count(); }

double Pct(std::vector<double> v, double p) {
  if (v.empty()) return -1;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

void Send(int fd, const std::string& bytes) {
  for (size_t off = 0; off < bytes.size();) {
    const ssize_t n = send(fd, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
    if (n <= 0) return;
    off += static_cast<size_t>(n);
  }
}

// Drops what has arrived; false once the daemon closed the connection.
bool Drain(int fd) {
  char buf[8192];
  for (;;) {
    const ssize_t n = recv(fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n > 0) continue;
    return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR);
  }
}

// GET `path` on a new connection from `from`; the bytes of the answer when it is a 200, else -1.
// `next`: the path of its Link rel="next" header, "" without one.
int64_t ReadFrom(const std::string& listen, const std::string& from, const std::string& path, std::string* next) {
  next->clear();
  const int fd = sandswim::testing::ConnectTo(listen, from);
  if (fd < 0) return -1;
  Send(fd, "GET " + path + " HTTP/1.1\r\nHost: " + listen + "\r\nConnection: close\r\n\r\n");
  std::string head;
  bool head_done = false;
  int64_t bytes = 0;
  char buf[65536];
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    if (poll(&p, 1, 300 * 1000) <= 0) break;
    const ssize_t n = recv(fd, buf, sizeof buf, 0);
    if (n <= 0) break;
    if (!head_done) {
      head.append(buf, static_cast<size_t>(n));
      const size_t end = head.find("\r\n\r\n");
      if (end != std::string::npos) {
        head.resize(end);
        head_done = true;
      }
    }
    bytes += n;
  }
  close(fd);
  // Link: </api/v1/...>; rel="next"
  for (size_t at = head.find("\r\n"); at != std::string::npos; at = head.find("\r\n", at + 2)) {
    const size_t eol = head.find("\r\n", at + 2);
    const std::string line = head.substr(at + 2, eol == std::string::npos ? std::string::npos : eol - at - 2);
    if (strncasecmp(line.c_str(), "Link:", 5) != 0 || line.find("rel=\"next\"") == std::string::npos) continue;
    const size_t open = line.find('<'), close_at = line.find('>');
    if (open != std::string::npos && close_at != std::string::npos) *next = line.substr(open + 1, close_at - open - 1);
  }
  return head.rfind("HTTP/1.1 200", 0) == 0 ? bytes : -1;
}

// The daemon's resident memory, in MB (VmRSS of /proc/PID/status); -1 when unreadable.
double ResidentMb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
  return -1;
}

// Writes a sweep of `runs` points into a new store at `db`, as POST /api/v1/sweeps would.
int SeedBigSweep(const std::string& db, int runs) {
  std::vector<double> omegas;
  for (int i = 0; i < runs; ++i) omegas.push_back(-1.0 - 0.001 * i);
  auto request = sandswim::ParseSubmitRequest(sandswim::testing::OmegaSweep("big", omegas, 0.05, 20));
  if (!request.ok()) return std::fprintf(stderr, "bench_hostile: %s\n", request.status().ToString().c_str()), 1;
  auto store = sandswim::Store::Open(db);
  if (!store.ok()) return std::fprintf(stderr, "bench_hostile: %s\n", store.status().ToString().c_str()), 1;
  sandswim::SystemClock clock;
  auto submitted = sandswim::Submit(**store, *request, "LIGGGHTS (bench_hostile)", clock.Now());
  if (!submitted.ok()) return std::fprintf(stderr, "bench_hostile: %s\n", submitted.status().ToString().c_str()), 1;
  return 0;
}

int Flag(int argc, char** argv, const std::string& name, int fallback) {
  for (int i = 1; i + 1 < argc; ++i)
    if (argv[i] == name) return std::atoi(argv[i + 1]);
  return fallback;
}

}  // namespace

int main(int argc, char** argv) {
  const int connections = Flag(argc, argv, "--connections", 250);
  const int seconds = Flag(argc, argv, "--seconds", 30);
  const int readers = Flag(argc, argv, "--readers", 4);
  const int read_runs = Flag(argc, argv, "--read-runs", 100000);
  const int page = Flag(argc, argv, "--page", 10000);
  const std::string dir = sandswim::testing::CacheDir() + "/bench-hostile";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir + "/daemon");
  const int64_t big = 1;  // the first sweep of the new store
  if (readers > 0) {
    const auto t = Steady::now();
    if (int failed = SeedBigSweep(dir + "/daemon/sandswim.db", read_runs)) return failed;
    std::printf("stored a %d-run sweep in %.1f s\n", read_runs, SecondsSince(t));
  }
  // The readers (127.0.0.2) stand for another host than the crowd's (127.0.0.1); a daemon from
  // before --http-loopback-clients-apart counted each loopback address apart anyway (--loopback-apart 0).
  std::vector<std::string> flags = {"--lease-ttl", "6"};
  if (Flag(argc, argv, "--loopback-apart", 1) != 0) flags.push_back("--http-loopback-clients-apart");
  const int holders = Flag(argc, argv, "--holders", 0);
  if (const int max_connections = Flag(argc, argv, "--max-connections", 0); max_connections > 0) {
    flags.push_back("--http-max-connections");
    flags.push_back(std::to_string(max_connections));
  }
  sandswim::testing::Daemon daemon(dir + "/daemon", flags);
  const std::string listen = daemon.listen();
  // The process started is the engine guard; its one child is sandswimd.
  pid_t daemon_pid = 0;
  {
    const pid_t guard = daemon.process().pid();
    std::ifstream in("/proc/" + std::to_string(guard) + "/task/" + std::to_string(guard) + "/children");
    if (!(in >> daemon_pid)) return std::fprintf(stderr, "bench_hostile: sandswimd's pid is not known\n"), 1;
  }

  // A bed to lease (the worker below holds it).
  int status = 0;
  daemon.Post("/api/v1/sweeps", sandswim::testing::OmegaSweep("leased", {-10}, 0.05, 20), &status);
  if (status != 201) return std::fprintf(stderr, "bench_hostile: cannot submit (%d)\n", status), 1;
  httplib::Client lessor(daemon.url());
  auto leased = lessor.Post("/api/v1/leases", R"({"worker": "bench:1", "host": "bench", "ranks": 1})",
                            "application/json");
  if (!leased || leased->status != 200) return std::fprintf(stderr, "bench_hostile: no lease\n"), 1;
  const std::string token = json::parse(leased->body)["lease"]["token"].get<std::string>();

  std::atomic<bool> stop{false};
  // The crowd.
  std::atomic<int64_t> crowd_reconnects{0}, holder_opens{0};
  std::thread crowd([&] {
    std::vector<int> fds(connections, -1), held(holders, -1);
    std::vector<Steady::time_point> next(connections, Steady::now());
    while (!stop.load()) {
      const auto now = Steady::now();
      for (int& fd : held) {  // silent: the daemon closes them (idle, or a newcomer takes the slot)
        if (fd >= 0 && !Drain(fd)) {
          close(fd);
          fd = -1;
        }
        if (fd < 0 && (fd = sandswim::testing::ConnectTo(listen)) >= 0) holder_opens.fetch_add(1);
      }
      for (int i = 0; i < connections; ++i) {
        if (fds[i] >= 0 && !Drain(fds[i])) {
          close(fds[i]);
          fds[i] = -1;
          crowd_reconnects.fetch_add(1);
        }
        if (now < next[i]) continue;
        if (fds[i] < 0) fds[i] = sandswim::testing::ConnectTo(listen);
        if (fds[i] >= 0) Send(fds[i], std::string("GET /healthz HTTP/1.1\r\nHost: ") + listen + "\r\n\r\n");
        next[i] = now + std::chrono::seconds(3);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    for (int fd : fds)
      if (fd >= 0) close(fd);
    for (int fd : held)
      if (fd >= 0) close(fd);
  });
  std::this_thread::sleep_for(std::chrono::seconds(4));  // every crowd connection open and asking

  std::mutex mu;
  std::vector<double> healthz, beats, read_seconds;
  int healthz_errors = 0, beat_errors = 0, beats_409 = 0;
  std::atomic<int64_t> reads{0}, read_bytes{0}, read_errors{0}, pages{0};
  const double rss_before = ResidentMb(daemon_pid);
  std::atomic<double> rss_peak{rss_before};
  std::vector<std::thread> threads;
  threads.emplace_back([&] {
    while (!stop.load()) {
      const double mb = ResidentMb(daemon_pid);
      if (mb > rss_peak.load()) rss_peak.store(mb);
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
  });
  for (int r = 0; r < readers; ++r) {
    threads.emplace_back([&] {
      while (!stop.load()) {
        // One whole read: the first page and every page after it.
        const auto t = Steady::now();
        std::string path = "/api/v1/sweeps/" + std::to_string(big) + "/results?limit=" + std::to_string(page);
        int64_t bytes = 0;
        std::string next;
        for (;;) {
          const int64_t got = ReadFrom(listen, "127.0.0.2", path, &next);
          if (got < 0) {
            bytes = -1;
            break;
          }
          bytes += got;
          pages.fetch_add(1);
          if (next.empty() || stop.load()) break;
          path = next;
        }
        if (bytes >= 0 && next.empty()) {
          reads.fetch_add(1);
          read_bytes.fetch_add(bytes);
          std::lock_guard<std::mutex> lock(mu);
          read_seconds.push_back(SecondsSince(t));
        } else if (bytes < 0) {
          read_errors.fetch_add(1);
          std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
      }
    });
  }
  threads.emplace_back([&] {
    while (!stop.load()) {
      const auto t = Steady::now();
      httplib::Client c(daemon.url());
      c.set_read_timeout(120, 0);
      auto res = c.Get("/healthz");
      std::lock_guard<std::mutex> lock(mu);
      if (res && res->status == 200) healthz.push_back(SecondsSince(t));
      else ++healthz_errors;
      std::this_thread::sleep_until(t + std::chrono::milliseconds(200));
    }
  });
  threads.emplace_back([&] {
    while (!stop.load()) {
      const auto t = Steady::now();
      httplib::Client c(daemon.url());
      c.set_read_timeout(120, 0);
      auto res = c.Post("/api/v1/leases/" + token + "/heartbeat", R"({"sim_time_s": 0})", "application/json");
      {
        std::lock_guard<std::mutex> lock(mu);
        if (res && res->status == 200) beats.push_back(SecondsSince(t));
        else if (res && res->status == 409) ++beats_409;
        else ++beat_errors;
      }
      std::this_thread::sleep_until(t + std::chrono::seconds(1));
    }
  });
  std::this_thread::sleep_for(std::chrono::seconds(seconds));
  stop.store(true);
  for (std::thread& t : threads) t.join();
  crowd.join();
  std::lock_guard<std::mutex> lock(mu);
  std::printf(
      "bench_hostile: %d keep-alive connections (/healthz every 3 s, %lld reconnects), %d silent holders (%lld "
      "opened), %d readers, %d s\n"
      "  fresh /healthz: %zu answered, %d failed; p50 %.3f s, p99 %.3f s, max %.3f s\n"
      "  heartbeat (new connection, TTL 6 s): %zu answered, %d lost lease (409), %d failed; p50 %.3f s, "
      "p99 %.3f s, max %.3f s\n"
      "  whole %d-run reads: %lld of %.1f MB each (%lld pages in all), %lld failed; p50 %.1f s, max %.1f s\n"
      "  daemon resident memory: %.0f MB at the start of the reads, %.0f MB at its peak\n",
      connections, static_cast<long long>(crowd_reconnects.load()), holders,
      static_cast<long long>(holder_opens.load()), readers, seconds, healthz.size(), healthz_errors,
      Pct(healthz, 0.5), Pct(healthz, 0.99), Pct(healthz, 1.0), beats.size(), beats_409, beat_errors, Pct(beats, 0.5),
      Pct(beats, 0.99), Pct(beats, 1.0), read_runs, static_cast<long long>(reads.load()),
      reads.load() > 0 ? static_cast<double>(read_bytes.load()) / reads.load() / 1e6 : 0.0,
      static_cast<long long>(pages.load()), static_cast<long long>(read_errors.load()), Pct(read_seconds, 0.5),
      Pct(read_seconds, 1.0), rss_before, rss_peak.load());
  return 0;
}
