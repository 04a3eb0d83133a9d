// bench_dashboard: two figures, on the real sandswimd.
//
//  1. Time to first render of a campaign run's page with 10,000 runs, in headless Chromium: a
//     campaign of one 100 x 100 sweep at smoke, 9,000 runs completed with SYNTHETIC results (the
//     rest queued), served by sandswimd; the page marks `runs-table` once its table is drawn.
//  2. The daemon's CPU with 50 open pages during a campaign: a sweep run by a worker whose engine
//     is the STAND-IN (tests/bench/stand_in_engine.cc), and 0 pages, 50 event streams (what an
//     open page holds: GET /api/v1/live/events), or 50 pages polling GET /api/v1/live every 2 s.
//     sandswimd's CPU time is read from /proc over each window.
//
//   bench_dashboard [--runs-done 9000] [--window 30]
#include <dirent.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <httplib.h>

#include "tests/bench/synthetic_campaign.h"
#include "tests/browser/webdriver.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace {

using nlohmann::json;
using Steady = std::chrono::steady_clock;
namespace fs = std::filesystem;

[[noreturn]] void Die(const std::string& why) {
  std::fprintf(stderr, "bench_dashboard: %s\n", why.c_str());
  std::exit(1);
}

double Seconds(Steady::time_point since) { return std::chrono::duration<double>(Steady::now() - since).count(); }

// The pid of the sandswimd whose parent is `guard` (the fixture runs it under the engine guard).
pid_t DaemonPid(pid_t guard) {
  for (int attempt = 0; attempt < 100; ++attempt) {
    DIR* proc = opendir("/proc");
    for (dirent* e = readdir(proc); e != nullptr; e = readdir(proc)) {
      const pid_t pid = std::atoi(e->d_name);
      if (pid <= 0) continue;
      std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
      std::string line;
      std::getline(stat, line);
      const size_t close = line.rfind(')');
      if (close == std::string::npos || line.find("(sandswimd)") == std::string::npos) continue;
      std::istringstream rest(line.substr(close + 2));
      char state;
      pid_t ppid = 0;
      rest >> state >> ppid;
      if (ppid == guard || pid == guard) {
        closedir(proc);
        return pid;
      }
    }
    closedir(proc);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  Die("cannot find sandswimd under pid " + std::to_string(guard));
}

// utime + stime of a process, in seconds.
double CpuSeconds(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  std::getline(stat, line);
  std::istringstream rest(line.substr(line.rfind(')') + 2));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  return (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

// ---- 1. A campaign run of 10,000 runs -----------------------------------------------------------

void TenThousandRuns(const fs::path& dir, int runs_done) {
  auto seeded = sandswim::bench::SeedTenThousandRunCampaign((dir / "daemon" / "sandswim.db").string(),
                                                            (dir / "daemon" / "data").string(), runs_done,
                                                            "LIGGGHTS (SYNTHETIC, bench_dashboard)");
  if (!seeded.ok()) Die(seeded.status().ToString());
  std::printf("10,000-run campaign: %d runs completed with SYNTHETIC results in %.1f s, %d queued\n",
              seeded->runs_done, seeded->seconds, seeded->runs - seeded->runs_done);
  // The real daemon on that file.
  sandswim::testing::Daemon daemon((dir / "daemon").string());
  const json runs = daemon.Get("/api/v1/campaign-runs");
  const int64_t id = runs["campaign_runs"][0]["id"].get<int64_t>();
  {
    const Steady::time_point t0 = Steady::now();
    int status = 0;
    const std::string body =
        daemon.GetText("/api/v1/campaign-runs/" + std::to_string(id) + "/results?limit=10000", &status);  // one page
    std::printf("GET /api/v1/campaign-runs/%lld/results: %d, %.1f MB in %.3f s\n", static_cast<long long>(id), status,
                body.size() / 1e6, Seconds(t0));
  }
  sandswim::testing::Browser browser((dir / "browser").string());
  for (int round = 0; round < 3; ++round) {
    browser.Navigate(daemon.url() + "/beds");
    const Steady::time_point t0 = Steady::now();
    browser.Navigate(daemon.url() + "/campaign-runs/" + std::to_string(id));
    if (!browser.WaitUntil("performance.getEntriesByName('runs-table').length > 0", 120)) Die("the page never drew its table");
    const double wall = Seconds(t0);
    const json t = browser.Script(
        "const m = performance.getEntriesByName('runs-table')[0];"
        "const r = performance.getEntriesByType('resource').find(e => /campaign-runs\\/\\d+\\/results(\\?|$)/.test(e.name));"
        "return {mark: m.startTime, fetch: r ? r.duration : -1, bytes: r ? r.encodedBodySize : -1,"
        " rows: document.querySelectorAll('#runs tbody tr').length, count: document.querySelector('#runs .table-count').textContent};");
    std::printf("round %d: table drawn %.0f ms after navigation start (results fetched in %.0f ms, %.1f MB); %s rows shown "
                "(%s); WebDriver wall %.2f s\n",
                round + 1, t["mark"].get<double>(), t["fetch"].get<double>(), t["bytes"].get<double>() / 1e6,
                std::to_string(t["rows"].get<int>()).c_str(), t["count"].get<std::string>().c_str(), wall);
  }
  browser.Screenshot((dir / "campaign-10k.png").string());
  // Sorting and filtering the 10,000 in the page.
  const json sort = browser.Script(
      "const t0 = performance.now(); document.querySelector(\"#runs th[data-key='Uz']\").click();"
      "const t1 = performance.now(); const f = document.querySelector('#runs .table-filter'); f.value = 'Omega -500';"
      "f.dispatchEvent(new Event('input')); return {sort: t1 - t0, filter: performance.now() - t1,"
      " count: document.querySelector('#runs .table-count').textContent};");
  std::printf("sort 10,000 rows by U_z: %.0f ms; filter them: %.0f ms (%s)\n", sort["sort"].get<double>(),
              sort["filter"].get<double>(), sort["count"].get<std::string>().c_str());
}

// ---- 2. 50 open pages during a campaign ---------------------------------------------------------

void FiftyPages(const fs::path& dir, double window_s) {
  setenv("SANDSWIM_STAND_IN_SECONDS", "2", 1);
  sandswim::testing::Daemon daemon((dir / "daemon").string());
  std::vector<double> omegas;
  for (int i = 0; i < 400; ++i) omegas.push_back(-10.0 - i);
  int status = 0;
  daemon.Post("/api/v1/sweeps", sandswim::testing::OmegaSweep("pages", omegas, 1.0), &status);
  if (status != 201) Die("submit");
  auto worker = sandswim::testing::StartWorker(daemon, (dir / "worker").string(), 2,
                                               {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  const pid_t pid = DaemonPid(daemon.process().pid());
  std::this_thread::sleep_for(std::chrono::seconds(5));  // the bed, and the first runs

  auto measure = [&](const char* what, int pages, bool stream) {
    std::atomic<bool> stop{false};
    std::atomic<int64_t> events{0}, bytes{0}, polls{0}, errors{0};
    std::vector<std::thread> clients;
    const int port = std::stoi(daemon.listen().substr(daemon.listen().rfind(':') + 1));
    for (int i = 0; i < pages; ++i) {
      clients.emplace_back([&, port] {
        httplib::Client c("127.0.0.1", port);
        c.set_read_timeout(60, 0);
        if (stream) {
          c.Get("/api/v1/live/events", [&](const char* data, size_t n) {
            bytes += static_cast<int64_t>(n);
            for (size_t k = 0; k + 12 <= n; ++k) events += std::string_view(data + k, 12) == "event: board";
            return !stop.load();
          });
        } else {
          std::string etag;
          while (!stop.load()) {
            auto r = c.Get("/api/v1/live", etag.empty() ? httplib::Headers{} : httplib::Headers{{"If-None-Match", etag}});
            ++polls;
            if (!r || (r->status != 200 && r->status != 304)) ++errors;
            if (r && r->status == 200) {
              etag = r->get_header_value("ETag");
              bytes += static_cast<int64_t>(r->body.size());
            }
            for (int k = 0; k < 20 && !stop.load(); ++k) std::this_thread::sleep_for(std::chrono::milliseconds(100));
          }
        }
      });
    }
    std::this_thread::sleep_for(std::chrono::seconds(2));  // connected
    const json before = daemon.Get("/api/v1/sweeps/1");
    const double cpu0 = CpuSeconds(pid);
    const Steady::time_point t0 = Steady::now();
    const int64_t events0 = events.load();
    std::this_thread::sleep_for(std::chrono::duration<double>(window_s));
    const double cpu = CpuSeconds(pid) - cpu0, wall = Seconds(t0);
    const json after = daemon.Get("/api/v1/sweeps/1");
    stop = true;
    if (stream) daemon.Post("/api/v1/sweeps", sandswim::testing::OmegaSweep("wake", {-9}, 1.0), &status);  // an event ends each stream
    for (std::thread& t : clients) t.join();
    std::printf("%-28s sandswimd CPU %.2f s in %.0f s = %.1f %% of a core; runs done %lld; events %lld (%.2f/s a page), "
                "polls %lld, %.1f MB sent, errors %lld\n",
                what, cpu, wall, 100 * cpu / wall,
                static_cast<long long>(after["counts"]["done"].get<int64_t>() - before["counts"]["done"].get<int64_t>()),
                static_cast<long long>(events.load() - events0),
                pages ? (events.load() - events0) / wall / pages : 0.0, static_cast<long long>(polls.load()),
                bytes.load() / 1e6, static_cast<long long>(errors.load()));
  };
  measure("no page open", 0, true);
  measure("50 pages, event streams", 50, true);
  measure("50 pages, polling every 2 s", 50, false);
  measure("no page open (again)", 0, true);
  worker->Stop();
}

}  // namespace

int main(int argc, char** argv) {
  int runs_done = 9000;
  double window_s = 30;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--runs-done")
      runs_done = std::atoi(argv[i + 1]);
    else if (flag == "--window")
      window_s = std::atof(argv[i + 1]);
    else
      Die("usage: bench_dashboard [--runs-done N] [--window SECONDS]");
  }
  std::string why;
  if (!sandswim::testing::BrowserAvailable(&why)) Die(why);
  const fs::path dir = fs::path(sandswim::testing::CacheDir()) / "bench-dashboard";
  fs::remove_all(dir);
  TenThousandRuns(dir / "10k", runs_done);
  FiftyPages(dir / "pages", window_s);
  return 0;
}
