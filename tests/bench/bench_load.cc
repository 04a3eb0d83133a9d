// bench_load: load figures on the real sandswimd. A campaign runs (a sweep whose runs a
// worker runs with the STAND-IN engine, tests/bench/stand_in_engine.cc, 1 s each, 2 slots, every
// run heartbeating each second) while a second process sends status queries at a fixed rate
// (default 1,000 requests/s for 60 s: a sweep's status, the running runs, the dashboard's live
// snapshot, in turn) over 16 keep-alive connections. It prints the achieved rate, errors, latency
// percentiles (from the time each request was due, so a stalled server is not hidden by requests
// not sent), and the campaign's throughput (runs finished per minute) with and without the load.
//
// --matrix runs the same load on campaigns of 58, 1,000 and 10,000 runs with 2 and 64 slots (one
// worker process, every slot's run heartbeating each second), one window without the load and
// one with it each, so the cost of a status answer can be read against the runs in the campaign
// and in flight; runs last long enough that the campaign outlives both windows (at least 1 s, 6 s
// with 64 slots). --claims times GET /api/v1/campaign-runs/{id}/claims on a finished 10,000-run
// campaign run (tests/bench/synthetic_campaign.h, with its one claim): the first answer,
// then the same asked again.
//
//   bench_load [--rate 1000] [--seconds 60] [--runs 2000] [--slots 2] [--run-seconds 1]
//   bench_load --matrix [--rate 1000] [--seconds 30]
//   bench_load --claims
//   bench_load --load URL RATE SECONDS   (the load process; prints one JSON line)
// SANDSWIMD_UNDER_TEST=PATH runs it on another build's daemon (tests/service_fixture.cc).
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>

#include "tests/bench/synthetic_campaign.h"
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


std::string Spawn(const std::vector<std::string>& argv) {
  int pipe_fds[2];
  if (pipe(pipe_fds) != 0) Die("pipe");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], 1);
  posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, args.data(), environ) != 0) Die("spawn");
  posix_spawn_file_actions_destroy(&actions);
  close(pipe_fds[1]);
  std::string out;
  char buf[4096];
  for (ssize_t n; (n = read(pipe_fds[0], buf, sizeof buf)) > 0;) out.append(buf, static_cast<size_t>(n));
  close(pipe_fds[0]);
  int wstatus = 0;
  waitpid(pid, &wstatus, 0);
  return out;
}

struct Window {
  double runs_per_min = 0;
  json load;  // the load process's line; null without load
};

// One campaign of `runs` runs of `run_s` each on `slots` slots in `dir`, measured over the windows
// `loads` (true: with the status load) of `seconds` each; prints a line per window.
std::vector<Window> Campaign(const std::filesystem::path& dir, int runs, int slots, double run_s, double rate,
                             double seconds, const std::vector<bool>& loads, const std::string& label) {
  std::filesystem::remove_all(dir);
  setenv("SANDSWIM_STAND_IN_SECONDS", std::to_string(run_s).c_str(), 1);
  sandswim::testing::Daemon daemon((dir / "daemon").string());
  std::vector<double> omegas;
  for (int i = 0; i < runs; ++i) omegas.push_back(-10.0 - i);
  int status = 0;
  daemon.Post("/api/v1/sweeps", sandswim::testing::OmegaSweep("load", omegas, 1.0), &status);
  if (status != 201) Die("submit");
  auto worker = sandswim::testing::StartWorker(daemon, (dir / "worker").string(), slots,
                                               {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  auto sweep = [&] { return daemon.Get("/api/v1/sweeps/1"); };
  // The bed, then the first runs: wait until every slot has a run (or a bed and a minute).
  const Steady::time_point ready_by = Steady::now() + std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(run_s + 60));
  std::this_thread::sleep_for(std::chrono::seconds(2));
  while (Steady::now() < ready_by) {
    const json s = sweep();
    if (s["counts"]["running"].get<int64_t>() >= std::min(slots, runs)) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
  }
  std::this_thread::sleep_for(std::chrono::duration<double>(std::min(run_s, 3.0)));  // past the first completions
  std::vector<Window> out;
  for (bool load : loads) {
    const int64_t d0 = sweep()["counts"]["done"].get<int64_t>();
    const Steady::time_point t0 = Steady::now();
    Window w;
    if (load) {
      w.load = json::parse(Spawn({"/proc/self/exe", "--load", daemon.url(), std::to_string(rate), std::to_string(seconds)}));
    } else {
      std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
    }
    const double wall = std::chrono::duration<double>(Steady::now() - t0).count();
    const json s = sweep();
    const int64_t finished = s["counts"]["done"].get<int64_t>() - d0;
    w.runs_per_min = 60.0 * static_cast<double>(finished) / wall;
    const std::string what = label + (label.empty() ? "" : ", ") + (load ? "with status load" : "without load");
    std::printf("%-44s campaign: %lld runs finished in %.0f s = %.1f runs/min (%lld running at the end)", what.c_str(),
                static_cast<long long>(finished), wall, w.runs_per_min,
                static_cast<long long>(s["counts"]["running"].get<int64_t>()));
    if (load) {
      const json& st = w.load;
      std::printf("; load: %lld requests at %.0f/s, %lld errors, latency from due p50 %.2f ms, p99 %.2f ms, max %.1f ms "
                  "(service p50 %.2f ms, p99 %.2f ms)",
                  static_cast<long long>(st["requests"].get<int64_t>()), st["rate"].get<double>(),
                  static_cast<long long>(st["errors"].get<int64_t>()), st["p50_ms"].get<double>(),
                  st["p99_ms"].get<double>(), st["max_ms"].get<double>(), st["service_p50_ms"].get<double>(),
                  st["service_p99_ms"].get<double>());
    }
    std::printf("\n");
    std::fflush(stdout);
    out.push_back(std::move(w));
  }
  worker->Stop();
  return out;
}

// The claims of a finished 10,000-run campaign run, asked for twice.
int Claims(const std::filesystem::path& dir) {
  std::filesystem::remove_all(dir);
  auto seeded = sandswim::bench::SeedTenThousandRunCampaign((dir / "daemon" / "sandswim.db").string(),
                                                           (dir / "daemon").string(), 10000, "SYNTHETIC bench_load",
                                                           /*with_claim=*/true);
  if (!seeded.ok()) Die("seed: " + seeded.status().ToString());
  sandswim::testing::Daemon daemon((dir / "daemon").string());
  int status = 0;
  const json runs = daemon.Get("/api/v1/campaign-runs");
  const int64_t id = runs["campaign_runs"].at(0)["id"].get<int64_t>();
  const std::string path = "/api/v1/campaign-runs/" + std::to_string(id) + "/claims";
  for (const char* what : {"first", "again", "again"}) {
    const Steady::time_point t0 = Steady::now();
    const std::string body = daemon.GetText(path, &status);
    const double ms = std::chrono::duration<double, std::milli>(Steady::now() - t0).count();
    std::printf("GET %s (%d runs, %s): %d, %zu bytes in %.1f ms\n", path.c_str(), seeded->runs, what, status,
                body.size(), ms);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 5 && std::string(argv[1]) == "--load") return Load(argv[2], std::atof(argv[3]), std::atof(argv[4]));
  double rate = 1000, seconds = 60, run_s = 1;
  int runs = 2000, slots = 2;
  bool matrix = false, claims = false;
  for (int i = 1; i < argc; ++i) {
    const std::string flag = argv[i];
    if (flag == "--matrix") {
      matrix = true;
      seconds = 30;
      continue;
    }
    if (flag == "--claims") {
      claims = true;
      continue;
    }
    if (i + 1 >= argc) Die("usage: bench_load [--rate R] [--seconds S] [--runs N] [--slots N] [--run-seconds S] | --matrix | --claims");
    const double value = std::atof(argv[++i]);
    if (flag == "--rate")
      rate = value;
    else if (flag == "--seconds")
      seconds = value;
    else if (flag == "--runs")
      runs = static_cast<int>(value);
    else if (flag == "--slots")
      slots = static_cast<int>(value);
    else if (flag == "--run-seconds")
      run_s = value;
    else
      Die("unknown flag " + flag);
  }
  const std::filesystem::path dir = std::filesystem::path(sandswim::testing::CacheDir()) / "bench-load";
  if (claims) return Claims(dir);
  if (!matrix) {
    Campaign(dir, runs, slots, run_s, rate, seconds, {false, true, false}, "");
    return 0;
  }
  std::printf("%-8s %-6s %-6s %-10s %-10s %-10s %-12s %-14s %-14s\n", "runs", "slots", "run_s", "req/s", "p50_ms",
              "p99_ms", "service_p99", "runs/min idle", "runs/min load");
  std::vector<std::string> table;
  for (int n : {58, 1000, 10000}) {
    for (int s : {2, 64}) {
      // Long enough that the campaign outlives the settling and both windows.
      const double r = std::max(s > 2 ? 6.0 : 1.0, std::ceil((2 * seconds + 15) * s / n));
      const std::string label = std::to_string(n) + " runs, " + std::to_string(s) + " slots";
      auto w = Campaign(dir, n, s, r, rate, seconds, {false, true}, label);
      const json& l = w[1].load;
      char line[256];
      std::snprintf(line, sizeof line, "%-8d %-6d %-6.0f %-10.0f %-10.2f %-10.2f %-12.2f %-14.1f %-14.1f", n, s, r,
                    l["rate"].get<double>(), l["p50_ms"].get<double>(), l["p99_ms"].get<double>(),
                    l["service_p99_ms"].get<double>(), w[0].runs_per_min, w[1].runs_per_min);
      table.push_back(line);
    }
  }
  std::printf("\n%-8s %-6s %-6s %-10s %-10s %-10s %-12s %-14s %-14s\n", "runs", "slots", "run_s", "req/s", "p50_ms",
              "p99_ms", "service_p99", "runs/min idle", "runs/min load");
  for (const std::string& line : table) std::printf("%s\n", line.c_str());
  return 0;
}
