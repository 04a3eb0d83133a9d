// bench_load: load figures on the real sandswimd. A campaign runs (a sweep whose runs a
// worker runs with the STAND-IN engine, tests/bench/stand_in_engine.cc, 1 s each, 2 slots) while
// a second process sends status queries at a fixed rate (default 1,000 requests/s for 60 s: a
// sweep's status, the running runs, the dashboard's live snapshot, in turn) over 16 keep-alive
// connections. It prints the achieved rate, errors, latency percentiles (from the time each
// request was due, so a stalled server is not hidden by requests not sent), and the campaign's
// throughput (runs finished per minute) with and without the load.
//
//   bench_load [--rate 1000] [--seconds 60]
//   bench_load --load URL RATE SECONDS   (the load process; prints one JSON line)
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

extern char** environ;

namespace {

using nlohmann::json;
using Steady = std::chrono::steady_clock;

[[noreturn]] void Die(const std::string& why) {
  std::fprintf(stderr, "bench_load: %s\n", why.c_str());
  std::exit(1);
}

double Pct(std::vector<double>& v, double p) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[std::min(v.size() - 1, static_cast<size_t>(p * static_cast<double>(v.size())))];
}

// The load process: open loop, `rate` requests/s in all over kConnections threads.
int Load(const std::string& url, double rate, double seconds) {
  constexpr int kConnections = 16;
  const std::string paths[] = {"/api/v1/sweeps/1", "/api/v1/runs?state=running&limit=100", "/api/v1/live"};
  std::mutex mu;
  std::vector<double> from_due, service;
  std::atomic<int64_t> ok{0}, errors{0};
  const Steady::time_point t0 = Steady::now() + std::chrono::milliseconds(200);
  std::vector<std::thread> threads;
  for (int c = 0; c < kConnections; ++c) {
    threads.emplace_back([&, c] {
      httplib::Client client(url);
      client.set_keep_alive(true);
      client.set_read_timeout(30, 0);
      std::vector<double> due_ms, service_ms;
      const double every = kConnections / rate;
      for (int64_t i = 0;; ++i) {
        const Steady::time_point due =
            t0 + std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(every * i + c / rate));
        if (std::chrono::duration<double>(due - t0).count() >= seconds) break;
        std::this_thread::sleep_until(due);
        const Steady::time_point sent = Steady::now();
        auto r = client.Get(paths[(i + c) % 3]);
        const Steady::time_point got = Steady::now();
        if (r && r->status == 200) {
          ++ok;
        } else {
          ++errors;
        }
        due_ms.push_back(std::chrono::duration<double, std::milli>(got - due).count());
        service_ms.push_back(std::chrono::duration<double, std::milli>(got - sent).count());
      }
      std::lock_guard<std::mutex> lock(mu);
      from_due.insert(from_due.end(), due_ms.begin(), due_ms.end());
      service.insert(service.end(), service_ms.begin(), service_ms.end());
    });
  }
  for (std::thread& t : threads) t.join();
  const double wall = std::chrono::duration<double>(Steady::now() - t0).count();
  json out = {{"requests", ok + errors},     {"ok", ok.load()},
              {"errors", errors.load()},     {"rate", (ok + errors) / wall},
              {"p50_ms", Pct(from_due, 0.5)}, {"p99_ms", Pct(from_due, 0.99)},
              {"max_ms", Pct(from_due, 1.0)}, {"service_p50_ms", Pct(service, 0.5)},
              {"service_p99_ms", Pct(service, 0.99)}};
  std::printf("%s\n", out.dump().c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 5 && std::string(argv[1]) == "--load") return Load(argv[2], std::atof(argv[3]), std::atof(argv[4]));
  double rate = 1000, seconds = 60;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--rate")
      rate = std::atof(argv[i + 1]);
    else if (flag == "--seconds")
      seconds = std::atof(argv[i + 1]);
    else
      Die("usage: bench_load [--rate R] [--seconds S]");
  }
  const std::filesystem::path dir = std::filesystem::path(sandswim::testing::CacheDir()) / "bench-load";
  std::filesystem::remove_all(dir);
  setenv("SANDSWIM_STAND_IN_SECONDS", "1", 1);
  sandswim::testing::Daemon daemon((dir / "daemon").string());
  std::vector<double> omegas;
  for (int i = 0; i < 2000; ++i) omegas.push_back(-10.0 - i);
  int status = 0;
  daemon.Post("/api/v1/sweeps", sandswim::testing::OmegaSweep("load", omegas, 1.0), &status);
  if (status != 201) Die("submit");
  auto worker = sandswim::testing::StartWorker(daemon, (dir / "worker").string(), 2,
                                               {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  std::this_thread::sleep_for(std::chrono::seconds(5));  // the bed, the first runs

  auto done = [&] { return daemon.Get("/api/v1/sweeps/1")["counts"]["done"].get<int64_t>(); };
  auto window = [&](const char* what, bool load) {
    const int64_t d0 = done();
    const Steady::time_point t0 = Steady::now();
    json stats;
    if (load) {
      int pipe_fds[2];
      if (pipe(pipe_fds) != 0) Die("pipe");
      posix_spawn_file_actions_t actions;
      posix_spawn_file_actions_init(&actions);
      posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], 1);
      posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
      const std::string rate_s = std::to_string(rate), seconds_s = std::to_string(seconds);
      std::vector<char*> args = {const_cast<char*>("/proc/self/exe"), const_cast<char*>("--load"),
                                 const_cast<char*>(daemon.url().c_str()), const_cast<char*>(rate_s.c_str()),
                                 const_cast<char*>(seconds_s.c_str()), nullptr};
      pid_t pid = 0;
      if (posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, args.data(), environ) != 0) Die("spawn");
      close(pipe_fds[1]);
      std::string out;
      char buf[4096];
      for (ssize_t n; (n = read(pipe_fds[0], buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
      close(pipe_fds[0]);
      int wstatus = 0;
      waitpid(pid, &wstatus, 0);
      stats = json::parse(out);
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    }
    const double wall = std::chrono::duration<double>(Steady::now() - t0).count();
    const int64_t finished = done() - d0;
    std::printf("%-22s campaign: %lld runs finished in %.0f s = %.1f runs/min", what, static_cast<long long>(finished),
                wall, 60.0 * finished / wall);
    if (load) {
      std::printf("; load: %lld requests at %.0f/s, %lld errors, latency from due p50 %.2f ms, p99 %.2f ms, max %.1f ms "
                  "(service p50 %.2f ms, p99 %.2f ms)",
                  static_cast<long long>(stats["requests"].get<int64_t>()), stats["rate"].get<double>(),
                  static_cast<long long>(stats["errors"].get<int64_t>()), stats["p50_ms"].get<double>(),
                  stats["p99_ms"].get<double>(), stats["max_ms"].get<double>(), stats["service_p50_ms"].get<double>(),
                  stats["service_p99_ms"].get<double>());
    }
    std::printf("\n");
  };
  window("without load", false);
  window("with status load", true);
  window("without load (again)", false);
  worker->Stop();
  return 0;
}
