// bench_orchestration: orchestration figures, with a STAND-IN engine
// (sandswim-stand-in-engine, which simulates nothing and exits at once; for this measurement only).
//
//   throughput   end-to-end runs per second: an in-process daemon (store + lease queue + REST on
//                127.0.0.1:ephemeral) and an in-process Worker with S slots (default 8), direct
//                launcher, the real GuardedLauncher, HTTP client, run directories, dump parsing
//                and completion; N runs (default 2000) of one sweep, timed from the first run
//                lease to the last result stored.                                goal >= 500/s
//   overhead     the same with 1 slot on a short sweep, per run, from what the store kept:
//                lease -> engine start (the worker's lease_to_start_s), engine wall time, and
//                engine exit -> result stored = (lease completed_at - granted_at) - lease_to_start_s
//                - wall_s (all but the lease reply's way back to the worker).
//
// Usage: bench_orchestration [--runs N] [--slots S] [--engine PATH] [--dir DIR]
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "platform/clock.h"
#include "server/jobs/lease_queue.h"
#include "server/http/routes.h"
#include "server/store/store.h"
#include "tests/bench/in_process_daemon.h"
#include "workers/client.h"
#include "workers/launcher.h"
#include "workers/worker.h"

namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

double Seconds() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }
double CpuSeconds() {
  struct rusage self {
  }, kids{};
  getrusage(RUSAGE_SELF, &self);
  getrusage(RUSAGE_CHILDREN, &kids);
  auto s = [](const struct rusage& u) {
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
  };
  return s(self) + s(kids);
}

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "bench_orchestration: %s\n", what.c_str());
  std::exit(1);
}

// An oscillatory smoke sweep of n points (distinct Omega values).
json SweepJson(const std::string& name, int n) {
  json omegas = json::array();
  for (int i = 0; i < n; ++i) omegas.push_back(-100 + 0.01 * i);
  return json{{"name", name},
              {"scale", "smoke"},
              {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -80}, {"duration_s", 0.3}}},
              {"axes", {{{"param", "Omega"}, {"values", omegas}}}},
              {"combine", "product"}};
}

using Daemon = sandswim::bench::InProcessDaemon;

struct Figures {
  int64_t done = 0, failed = 0;
  double runs_per_s = 0, cpu_ms_per_run = 0;
  double lease_to_start_ms = 0, wall_ms = 0, exit_to_stored_ms = 0, cycle_ms = 0;
};

Figures Measure(const fs::path& dir, const std::string& engine, int runs, int slots) {
  fs::create_directories(dir);
  Daemon d(dir, "sandswim-stand-in-engine 0");
  httplib::Client client("127.0.0.1", d.port);
  client.set_read_timeout(120, 0);
  auto res = client.Post("/api/v1/sweeps", SweepJson("orchestration", runs).dump(), "application/json");
  if (!res || res->status != 201) Die("POST sweep: " + (res ? res->body : std::string("no answer")));
  const int64_t sweep = json::parse(res->body).at("id").get<int64_t>();

  sandswim::ClientOptions co;
  co.server = "http://127.0.0.1:" + std::to_string(d.port);
  sandswim::worker::HttpServerClient http(co);
  sandswim::worker::GuardedLauncher launcher;
  sandswim::worker::WorkerOptions wo;
  wo.name = "bench";
  wo.host = "bench";
  wo.slots = slots;
  wo.ranks = 1;
  wo.launcher = sandswim::worker::LauncherKind::kDirect;
  wo.engine = engine;
  wo.workdir = (dir / "worker").string();
  wo.idle_poll_s = 0.02;
  sandswim::worker::Worker worker(wo, http, launcher);
  std::thread runner([&] { worker.Run(); });

  // From the bed's completion (the first run lease) to the last run stored.
  double t0 = 0, c0 = 0, t1 = 0, c1 = 0;
  Figures f;
  while (true) {
    auto s = d.store->GetSweep(sweep);
    if (!s.ok()) Die(s.status().ToString());
    if (t0 == 0 && s->counts.queued < runs) {
      t0 = Seconds();
      c0 = CpuSeconds();
    }
    f.done = s->counts.done;
    f.failed = s->counts.failed;
    if (f.done + f.failed >= runs) break;
    // Coarse polling: a sweep-counts query costs CPU the runs being measured would miss.
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  t1 = Seconds();
  c1 = CpuSeconds();
  worker.RequestStop();
  runner.join();
  f.runs_per_s = runs / (t1 - t0);
  f.cpu_ms_per_run = (c1 - c0) / runs * 1e3;

  auto t = d.store->db().BeginRead();
  if (!t.ok()) Die(t.status().ToString());
  sandswim::Statement st = t->Prepare(
      "SELECT AVG(r.lease_to_start_s), AVG(r.wall_s), AVG(l.completed_at - l.granted_at) "
      "FROM leases l JOIN results r ON r.run_id = l.job_id WHERE l.kind = 'run' AND l.outcome = 'done'");
  auto row = st.Step();
  if (!row.ok() || !*row) Die("no results");
  f.lease_to_start_ms = st.Double(0) * 1e3;
  f.wall_ms = st.Double(1) * 1e3;
  f.cycle_ms = st.Double(2) * 1e3;
  f.exit_to_stored_ms = f.cycle_ms - f.lease_to_start_ms - f.wall_ms;
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 2000, slots = 8;
  std::string dir, engine;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) Die("missing value after " + a);
      return argv[++i];
    };
    if (a == "--runs")
      runs = std::atoi(next().c_str());
    else if (a == "--slots")
      slots = std::atoi(next().c_str());
    else if (a == "--engine")
      engine = next();
    else if (a == "--dir")
      dir = next();
    else
      Die("unknown argument " + a + " (--runs N --slots S --engine PATH --dir DIR)");
  }
  if (engine.empty()) {
    engine = (fs::canonical("/proc/self/exe").parent_path() / "sandswim-stand-in-engine").string();
  }
  if (access(engine.c_str(), X_OK) != 0) Die("no stand-in engine at " + engine + " (build sandswim-stand-in-engine)");
  spdlog::set_level(spdlog::level::warn);
  fs::path root =
      dir.empty() ? fs::temp_directory_path() / ("bench_orchestration." + std::to_string(::getpid())) : fs::path(dir);
  fs::remove_all(root);
  std::printf("engine %s (a STAND-IN that exits at once: for this measurement only)\n", engine.c_str());
  Figures f = Measure(root / "throughput", engine, runs, slots);
  std::printf("throughput_slots %d runs %d done %lld failed %lld\n", slots, runs, static_cast<long long>(f.done),
              static_cast<long long>(f.failed));
  std::printf("throughput_runs_per_s %.0f   (goal >= 500)\n", f.runs_per_s);
  std::printf("throughput_cpu_ms_per_run %.2f (this process + engines; on 2 idle cores at most ~%.0f/s)\n",
              f.cpu_ms_per_run, 2e3 / f.cpu_ms_per_run);
  Figures o = Measure(root / "overhead", engine, std::min(runs, 200), 1);
  std::printf("serial_runs_per_s %.0f (1 slot)\n", o.runs_per_s);
  std::printf("per_run_ms lease_to_start %.2f  engine_wall %.2f  exit_to_stored %.2f  lease_to_stored %.2f\n",
              o.lease_to_start_ms, o.wall_ms, o.exit_to_stored_ms, o.cycle_ms);
  fs::remove_all(root);
  return 0;
}
