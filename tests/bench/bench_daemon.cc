// bench_daemon: the daemon's figures, printed one per line.
//
//   submit   ParseSubmitRequest + Submit of a N-point sweep (default 100,000) into a fresh SQLite
//            file, in-process; then the same body POSTed to /api/v1/sweeps of a real in-process
//            ApiServer on a second fresh file (what a user waits for).            goal <= 2 s
//   status   GET /api/v1/sweeps/{id} (with counts) and Store::GetSweep on that sweep: median and
//            p95 of 50 queries each.                                              goal <= 50 ms
//   cycles   lease -> complete cycles per second through REST: C client threads (default 32),
//            each with its own keep-alive connection, looping POST /api/v1/leases then
//            POST /api/v1/leases/{token}/complete (a small ok completion), on a queue pre-filled
//            with runs whose bed was made done through the same API.              goal >= 5,000/s
//   piggyback  the same cycles as the worker makes them: each completion also asks for the next
//            job (Completion.next), so a cycle is one request (one lease call to start).
//   inproc   the two-request cycles calling LeaseQueue directly, no HTTP (what REST adds).
//
// Usage: bench_daemon [--runs N] [--clients C] [--cycles M] [--dir DIR]
//                     [--only submit|cycles|piggyback|inproc]
// Everything binds 127.0.0.1 on an ephemeral port; DIR (default: a fresh temp dir) is removed.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>
#include <sys/resource.h>
#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/keys.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "platform/clock.h"
#include "server/jobs/lease_queue.h"
#include "server/http/routes.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"
#include "tests/bench/in_process_daemon.h"

namespace {

using json = nlohmann::json;
using sandswim::Status;
namespace fs = std::filesystem;

// CPU seconds (user + system) of this process so far: wall time on a shared, loaded machine
// overstates what the work costs.
double CpuSeconds() {
  struct rusage u {};
  getrusage(RUSAGE_SELF, &u);
  return u.ru_utime.tv_sec + u.ru_stime.tv_sec + (u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

// Write system calls and bytes written by this process so far (/proc/self/io): how many WAL
// frames (two pwrites each) a state change costs.
std::pair<long long, long long> WritesSoFar() {
  std::ifstream in("/proc/self/io");
  std::string key;
  long long value = 0, calls = 0, bytes = 0;
  while (in >> key >> value) {
    if (key == "syscw:") calls = value;
    if (key == "wchar:") bytes = value;
  }
  return {calls, bytes};
}

double Seconds() {
  using namespace std::chrono;
  return duration<double>(steady_clock::now().time_since_epoch()).count();
}

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "bench_daemon: %s\n", what.c_str());
  std::exit(1);
}

// An oscillatory sweep at smoke scale with about `n` points: A x f x Omega.
json SweepJson(const std::string& name, int n) {
  // 40 Omega values x 50 f values x (n / 2000) A values; small n shrinks the A axis first.
  int a_count = std::max(1, n / 2000);
  int f_count = n >= 2000 ? 50 : std::max(1, n / 40);
  json omegas = json::array();
  for (int i = 0; i < 40; ++i) omegas.push_back(-200 + 10 * i);
  return json{{"name", name},
              {"scale", "smoke"},
              {"base", {{"mode", "oscillatory"}, {"A", 0.003}, {"f", 3}, {"Omega", -80}, {"duration_s", 0.3}}},
              {"axes",
               {{{"param", "A"}, {"range", {{"from", 0.0005}, {"to", 0.0005 * a_count}, {"step", 0.0005}}}},
                {{"param", "f"}, {"range", {{"from", 0.5}, {"to", 0.5 * f_count}, {"step", 0.5}}}},
                {{"param", "Omega"}, {"values", omegas}}}},
              {"combine", "product"}};
}

struct Stats {
  double median = 0, p95 = 0, max = 0;
};
Stats Summarise(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  Stats s;
  if (v.empty()) return s;
  s.median = v[v.size() / 2];
  s.p95 = v[std::min(v.size() - 1, v.size() * 95 / 100)];
  s.max = v.back();
  return s;
}

// A daemon in this process: store + lease queue + ApiServer on 127.0.0.1:ephemeral.
using Daemon = sandswim::bench::InProcessDaemon;

constexpr const char* kEngine = "LIGGGHTS-PUBLIC 3.8.0 (bench)";

// ---- submit + status ---------------------------------------------------------------------------

void BenchSubmitAndStatus(const fs::path& root, int runs) {
  const json body = SweepJson("bench", runs);
  const std::string text = body.dump();
  // Planning alone (expand, render and hash every deck), as Submit plans.
  {
    auto req = sandswim::ParseSubmitRequest(json::parse(text));
    if (!req.ok()) Die("parse: " + req.status().ToString());
    sandswim::PlanOptions options;
    options.keep_decks = false;
    options.threads = 2;
    double t0 = Seconds(), c0 = CpuSeconds();
    auto plan = sandswim::PlanSweeps(req->sweeps, *sandswim::FindScale("smoke"), kEngine, options);
    if (!plan.ok()) Die("plan: " + plan.status().ToString());
    std::printf("plan_s %.3f cpu_s %.3f (%zu runs, keep_decks=false, threads=2)\n", Seconds() - t0, CpuSeconds() - c0,
                plan->runs.size());
  }
  // In-process: ParseSweep (via ParseSubmitRequest) + Submit.
  {
    fs::create_directories(root / "inproc");
    auto store = sandswim::Store::Open((root / "inproc" / "sandswim.db").string());
    if (!store.ok()) Die(store.status().ToString());
    double t0 = Seconds(), c0 = CpuSeconds();
    auto req = sandswim::ParseSubmitRequest(json::parse(text));
    if (!req.ok()) Die("parse: " + req.status().ToString());
    double t1 = Seconds();
    auto result = sandswim::Submit(**store, *req, kEngine, 1.7e9);
    if (!result.ok()) Die("submit: " + result.status().ToString());
    double t2 = Seconds();
    std::printf("submit_inproc_runs %lld\n", static_cast<long long>(result->runs));
    std::printf("submit_inproc_parse_s %.3f\n", t1 - t0);
    std::printf("submit_inproc_total_s %.3f cpu_s %.3f   (goal <= 2 s)\n", t2 - t0, CpuSeconds() - c0);
    std::printf("db_bytes_after_submit %lld\n",
                static_cast<long long>(fs::file_size(root / "inproc" / "sandswim.db") +
                                       (fs::exists(root / "inproc" / "sandswim.db-wal")
                                            ? fs::file_size(root / "inproc" / "sandswim.db-wal")
                                            : 0)));
    std::fflush(stdout);
  }
  // Through REST.
  fs::create_directories(root / "rest");
  Daemon d(root / "rest", kEngine);
  httplib::Client client("127.0.0.1", d.port);
  client.set_read_timeout(120, 0);
  double t0 = Seconds();
  auto res = client.Post("/api/v1/sweeps", text, "application/json");
  double t1 = Seconds();
  if (!res || res->status != 201) Die("POST /api/v1/sweeps: " + (res ? res->body : std::string("no answer")));
  int64_t id = json::parse(res->body).at("id").get<int64_t>();
  std::printf("submit_rest_s %.3f   (goal <= 2 s)\n", t1 - t0);
  std::fflush(stdout);

  const std::string path = "/api/v1/sweeps/" + std::to_string(id);
  std::vector<double> rest_ms, store_ms;
  json last;
  for (int i = 0; i < 50; ++i) {
    double a = Seconds();
    auto r = client.Get(path.c_str());
    double b = Seconds();
    if (!r || r->status != 200) Die("GET " + path);
    if (i == 0) last = json::parse(r->body);
    rest_ms.push_back((b - a) * 1e3);
  }
  for (int i = 0; i < 50; ++i) {
    double a = Seconds();
    auto s = d.store->GetSweep(id);
    double b = Seconds();
    if (!s.ok()) Die("GetSweep: " + s.status().ToString());
    store_ms.push_back((b - a) * 1e3);
  }
  Stats r = Summarise(rest_ms), s = Summarise(store_ms);
  std::printf("status_counts %s\n", last.at("counts").dump().c_str());
  std::printf("status_rest_ms median %.2f p95 %.2f max %.2f   (goal <= 50 ms)\n", r.median, r.p95, r.max);
  std::printf("status_store_ms median %.2f p95 %.2f max %.2f\n", s.median, s.p95, s.max);
  // A run's detail renders its deck (check it is there and time it).
  std::vector<double> run_ms;
  for (int i = 0; i < 20; ++i) {
    double a = Seconds();
    auto g = client.Get(("/api/v1/runs/" + std::to_string(1 + i * 997)).c_str());
    double b = Seconds();
    if (!g || g->status != 200) Die("GET /api/v1/runs/N");
    if (json::parse(g->body).at("deck").get<std::string>().empty()) Die("run detail has no deck");
    run_ms.push_back((b - a) * 1e3);
  }
  Stats g = Summarise(run_ms);
  std::printf("run_detail_rest_ms median %.2f p95 %.2f\n", g.median, g.p95);
  std::fflush(stdout);
}

// ---- lease -> complete cycles ------------------------------------------------------------------

std::string SmallCompletion() {
  sandswim::api::Completion c;
  c.ok = true;
  sandswim::api::RunResult r;
  r.uz = -0.001;
  r.uz_stderr = 1e-5;
  r.window_t0 = 0.1;
  r.window_t1 = 0.3;
  r.dz = -0.0003;
  r.stop_reason = "duration";
  r.sim_time_s = 0.3;
  r.steps = 3000;
  r.grains = 3700;
  r.z0 = 0.1;
  c.result = r;
  c.execution.engine_version = kEngine;
  c.execution.host = "bench";
  c.execution.launcher = "direct";
  c.execution.wall_s = 0.01;
  return json(c).dump();
}

enum class CycleMode { kRest, kRestPiggyback, kInProcess };

// kInProcess: the same cycles calling LeaseQueue directly (what the REST layer adds is the
// difference). kRestPiggyback: one request per cycle, as the worker does it.
void BenchCycles(const fs::path& root, int clients, int cycles, CycleMode mode) {
  const bool rest = mode != CycleMode::kInProcess;
  const bool piggyback = mode == CycleMode::kRestPiggyback;
  const fs::path dir = root / (!rest ? "cycles-inproc" : piggyback ? "cycles-piggyback" : "cycles");
  fs::create_directories(dir);
  Daemon d(dir, kEngine);
  httplib::Client client("127.0.0.1", d.port);
  client.set_read_timeout(120, 0);
  // Enough queued runs for every cycle.
  auto res = client.Post("/api/v1/sweeps", SweepJson("cycles", cycles).dump(), "application/json");
  if (!res || res->status != 201) Die("POST sweep: " + (res ? res->body : std::string("no answer")));
  const int64_t sweep_id = json::parse(res->body).at("id").get<int64_t>();
  const int64_t queued = json::parse(res->body).at("runs").get<int64_t>();
  // The bed, done through the queue API.
  const json lease_req = {{"worker", "bench-bed"}, {"host", "bench"}, {"ranks", 1}};
  res = client.Post("/api/v1/leases", lease_req.dump(), "application/json");
  if (!res || res->status != 200) Die("lease bed");
  sandswim::api::LeaseGrant bed = json::parse(res->body).at("lease").get<sandswim::api::LeaseGrant>();
  if (bed.kind != sandswim::api::JobKind::kBed) Die("first lease is not the bed");
  const std::string restart = "bench restart bytes";
  const std::string sha = sandswim::Sha256Hex(restart);
  res = client.Put(("/api/v1/beds/" + std::to_string(bed.id) + "/restart?token=" + bed.token).c_str(),
                   {{"X-Sha256", sha}}, restart, "application/octet-stream");
  if (!res || res->status != 200) Die("upload restart");
  sandswim::api::Completion bed_done;
  bed_done.ok = true;
  bed_done.bed_result = sandswim::api::BedResult{
      3700,         0.1,          0.2,          true,        1e-4, sha, static_cast<int64_t>(restart.size()),
      std::nullopt, std::nullopt, std::nullopt, std::nullopt};
  res = client.Post(("/api/v1/leases/" + bed.token + "/complete").c_str(), json(bed_done).dump(), "application/json");
  if (!res || res->status != 200) Die("complete bed");

  const std::string completion = SmallCompletion();
  const sandswim::api::Completion completion_value = json::parse(completion).get<sandswim::api::Completion>();
  const int per_client = static_cast<int>(std::min<int64_t>(cycles, queued)) / clients;
  std::atomic<int> failures{0};
  std::vector<std::vector<double>> lease_ms(clients), complete_ms(clients);
  std::vector<std::thread> threads;
  double t0 = Seconds(), c0 = CpuSeconds();
  const auto w0 = WritesSoFar();
  for (int i = 0; i < clients; ++i) {
    threads.emplace_back([&, i] {
      if (!rest) {
        sandswim::api::LeaseRequest req{"bench-" + std::to_string(i), "bench", 1};
        for (int k = 0; k < per_client; ++k) {
          double a = Seconds();
          auto g = d.leases->Lease(req);
          double b = Seconds();
          if (!g.ok() || !*g) {
            ++failures;
            continue;
          }
          auto done = d.leases->Complete((*g)->token, completion_value);
          double e = Seconds();
          if (!done.ok() || done->state != "done") {
            ++failures;
            continue;
          }
          lease_ms[i].push_back((b - a) * 1e3);
          complete_ms[i].push_back((e - b) * 1e3);
        }
        return;
      }
      httplib::Client c("127.0.0.1", d.port);
      c.set_keep_alive(true);
      c.set_tcp_nodelay(std::getenv("BENCH_NO_NODELAY") == nullptr);
      c.set_read_timeout(60, 0);
      const json lease_request = {{"worker", "bench-" + std::to_string(i)}, {"host", "bench"}, {"ranks", 1}};
      const std::string req = lease_request.dump();
      if (piggyback) {
        json with_next = json::parse(completion);
        with_next["next"] = lease_request;
        const std::string body = with_next.dump();
        std::string token;
        for (int k = 0; k < per_client; ++k) {
          double a = Seconds();
          if (token.empty()) {  // the first job, or after a completion that found none
            auto r = c.Post("/api/v1/leases", req, "application/json");
            if (!r || r->status != 200) {
              ++failures;
              continue;
            }
            token = json::parse(r->body).at("lease").at("token").get<std::string>();
          }
          double b = Seconds();
          // The last completion asks for nothing more: every job leased is completed.
          auto done = c.Post(("/api/v1/leases/" + token + "/complete").c_str(), k + 1 < per_client ? body : completion,
                             "application/json");
          double e = Seconds();
          token.clear();
          if (!done || done->status != 200) {
            ++failures;
            continue;
          }
          const json reply = json::parse(done->body);
          if (k + 1 < per_client && reply.contains("next")) {
            token = reply["next"].at("token").get<std::string>();
          }
          lease_ms[i].push_back((b - a) * 1e3);
          complete_ms[i].push_back((e - b) * 1e3);
        }
        if (!token.empty()) ++failures;  // a leased job left uncompleted
        return;
      }
      for (int k = 0; k < per_client; ++k) {
        double a = Seconds();
        auto r = c.Post("/api/v1/leases", req, "application/json");
        double b = Seconds();
        if (!r || r->status != 200) {
          ++failures;
          continue;
        }
        // The token is a fixed-width field of the grant; parse the grant as a worker would.
        std::string token = json::parse(r->body).at("lease").at("token").get<std::string>();
        auto done = c.Post(("/api/v1/leases/" + token + "/complete").c_str(), completion, "application/json");
        double e = Seconds();
        if (!done || done->status != 200) {
          ++failures;
          continue;
        }
        lease_ms[i].push_back((b - a) * 1e3);
        complete_ms[i].push_back((e - b) * 1e3);
      }
    });
  }
  for (auto& t : threads) t.join();
  double elapsed = Seconds() - t0, cpu = CpuSeconds() - c0;
  const auto w1 = WritesSoFar();
  std::vector<double> all_lease, all_complete;
  for (int i = 0; i < clients; ++i) {
    all_lease.insert(all_lease.end(), lease_ms[i].begin(), lease_ms[i].end());
    all_complete.insert(all_complete.end(), complete_ms[i].begin(), complete_ms[i].end());
  }
  auto sweep = d.store->GetSweep(sweep_id);
  if (!sweep.ok()) Die("GetSweep: " + sweep.status().ToString());
  const long long ok_cycles = static_cast<long long>(all_complete.size());
  if (sweep->counts.done != ok_cycles) {
    Die("done runs " + std::to_string(sweep->counts.done) + " != completed cycles " + std::to_string(ok_cycles));
  }
  Stats l = Summarise(all_lease), c = Summarise(all_complete);
  const char* how = !rest ? "inproc" : piggyback ? "rest_piggyback" : "rest";
  std::printf("cycles_%s_clients %d\n", how, clients);
  std::printf("cycles_%s_done %lld failures %d in %.3f s\n", how, ok_cycles, failures.load(), elapsed);
  std::printf("cycles_%s_per_s %.0f%s\n", how, ok_cycles / elapsed, rest ? "   (goal >= 5000)" : "");
  // CPU of this whole process (server and clients) per cycle: what the figure would be on two
  // idle cores is about 2 / cpu_per_cycle, whatever else the machine was doing.
  std::printf("cycles_%s_cpu_us_per_cycle %.0f (cpu_s %.3f; on 2 idle cores at most ~%.0f/s)\n", how,
              cpu / ok_cycles * 1e6, cpu, 2 * ok_cycles / cpu);
  std::printf("cycles_%s_write_calls_per_cycle %.1f  bytes_written_per_cycle %.0f (incl. HTTP sends)\n", how,
              double(w1.first - w0.first) / ok_cycles, double(w1.second - w0.second) / ok_cycles);
  std::printf("%s lease_ms median %.2f p95 %.2f   complete_ms median %.2f p95 %.2f\n", how, l.median, l.p95, c.median,
              c.p95);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 100000, clients = 32, cycles = 20000;
  std::string dir, only;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) Die("missing value after " + a);
      return argv[++i];
    };
    if (a == "--runs")
      runs = std::atoi(next().c_str());
    else if (a == "--clients")
      clients = std::atoi(next().c_str());
    else if (a == "--cycles")
      cycles = std::atoi(next().c_str());
    else if (a == "--dir")
      dir = next();
    else if (a == "--only")
      only = next();
    else
      Die("unknown argument " + a +
          " (--runs N --clients C --cycles M --dir DIR --only submit|cycles|piggyback|inproc)");
  }
  if (runs < 1 || clients < 1 || cycles < clients) Die("need runs >= 1 and cycles >= clients >= 1");
  fs::path root =
      dir.empty() ? fs::temp_directory_path() / ("bench_daemon." + std::to_string(::getpid())) : fs::path(dir);
  fs::remove_all(root);
  fs::create_directories(root);
  if (only.empty() || only == "submit") BenchSubmitAndStatus(root, runs);
  if (only.empty() || only == "cycles") BenchCycles(root, clients, cycles, CycleMode::kRest);
  if (only.empty() || only == "piggyback") BenchCycles(root, clients, cycles, CycleMode::kRestPiggyback);
  if (only.empty() || only == "inproc") BenchCycles(root, clients, cycles, CycleMode::kInProcess);
  fs::remove_all(root);
  return 0;
}
