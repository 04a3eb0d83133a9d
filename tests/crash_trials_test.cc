// Daemon crash trials (issue 15): the promise that nothing is lost and a run is done once, tried by
// killing the daemon. A real sandswimd and two real sandswim-workers (launcher "direct"), whose
// engine is sandswim-stand-in-engine -- a STAND-IN that simulates nothing and lasts a set time, so
// that the orchestration alone is under test -- work through a sweep while the daemon is SIGKILLed
// at random moments and started again on the same database, data directory and port. Each trial
// prints its seed; SANDSWIM_CRASH_SEED=S repeats one, SANDSWIM_CRASH_RUNS / _TRIALS / _KILLS /
// _ENGINE_S make a longer trial on demand (the defaults keep the test near a minute).
//
// Outages are drawn up to 1.5 lease TTLs long, so some outlast a lease. Every trial asserts: every run done, once (one engine start per run, counted by the stand-in),
// one result per run, none left running, `PRAGMA integrity_check` ok, and the bed's file still
// has the checksum its row records.
#include <signal.h>
#include <sys/stat.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "platform/files.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

int EnvInt(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::atoi(v) : fallback;
}
double EnvDouble(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? std::atof(v) : fallback;
}

// Engine starts per run id, from the stand-in's log of working directories ("run-ID-aN").
std::map<int64_t, int> StartsPerRun(const std::string& log) {
  std::map<int64_t, int> starts;
  std::ifstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    const std::string name = fs::path(line).filename().string();
    if (name.rfind("run-", 0) != 0) continue;
    starts[std::stoll(name.substr(4, name.find("-a") - 4))]++;
  }
  return starts;
}

void Trial(int trial, uint64_t seed, int runs, int kills, double engine_s) {
  SCOPED_TRACE("trial " + std::to_string(trial) + ", seed " + std::to_string(seed));
  std::printf("CRASH trial %d: seed %llu, %d runs, %d kills, engine %.2f s\n", trial,
              static_cast<unsigned long long>(seed), runs, kills, engine_s);
  std::mt19937_64 rng(seed);
  const std::string dir = testing::CacheDir() + "/crash-trials/" + std::to_string(trial);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string starts_log = dir + "/engine-starts.log";
  setenv("SANDSWIM_STAND_IN_STARTS", starts_log.c_str(), 1);
  setenv("SANDSWIM_STAND_IN_SECONDS", std::to_string(engine_s).c_str(), 1);
  // Leases short enough that some outages below outlast them: the outage must not count against a
  // worker that kept running (LeaseQueue::ExtendLeasesAfterRestart).
  const double ttl_s = 3;
  const std::vector<std::string> flags = {"--lease-ttl", "3", "--max-attempts", "3"};
  auto daemon = std::make_unique<testing::Daemon>(dir + "/daemon", flags);
  const std::string listen = daemon->listen();

  std::vector<double> omegas;
  for (int i = 0; i < runs; ++i) omegas.push_back(-10.0 - i);
  int status = 0;
  json submitted = daemon->Post("/api/v1/sweeps", testing::OmegaSweep("crash", omegas, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t sweep = submitted["id"].get<int64_t>();

  std::vector<std::unique_ptr<testing::ChildProcess>> workers;
  for (int w = 0; w < 2; ++w) {
    workers.push_back(testing::StartWorker(*daemon, dir + "/worker-" + std::to_string(w), 1,
                                           {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH}));
  }
  std::uniform_real_distribution<double> up(0.3, 2.5 * engine_s + 0.5), down(0.0, 1.5 * ttl_s);
  for (int k = 0; k < kills; ++k) {
    std::this_thread::sleep_for(std::chrono::duration<double>(up(rng)));
    daemon->process().Kill(SIGKILL);
    for (int i = 0; i < 500 && daemon->process().running(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    daemon.reset();
    std::this_thread::sleep_for(std::chrono::duration<double>(down(rng)));
    daemon = std::make_unique<testing::Daemon>(dir + "/daemon", flags, listen);
  }
  const json s = daemon->WaitForSweep(sweep, 60 + runs * engine_s * 2);
  for (auto& w : workers) w->Stop();

  EXPECT_EQ(s["counts"]["done"], runs) << s.dump() << "\nworker 0:\n" << workers[0]->Output();
  EXPECT_EQ(s["counts"]["failed"], 0) << s.dump();
  EXPECT_EQ(daemon->Query("SELECT count(*) FROM runs WHERE state = 'running'"), "0");
  EXPECT_EQ(daemon->Query("SELECT count(*) FROM results"), std::to_string(runs));
  EXPECT_EQ(daemon->Query("SELECT count(DISTINCT run_id) FROM results"), std::to_string(runs));
  EXPECT_EQ(daemon->Query("PRAGMA integrity_check"), "ok");
  // Once each: one engine start per run, and every run's single lease completed.
  const std::map<int64_t, int> starts = StartsPerRun(starts_log);
  EXPECT_EQ(starts.size(), static_cast<size_t>(runs));
  int repeated = 0;
  for (const auto& [run, n] : starts) {
    EXPECT_EQ(n, 1) << "run " << run << " started " << n << " times";
    repeated += n > 1;
  }
  // A lease whose reply died with the daemon is held by no worker: it expires and the run is
  // leased again -- a second lease, not a second execution. Counted, not forbidden.
  const std::string leased_again = daemon->Query("SELECT count(*) FROM runs WHERE attempts > 1");
  // The bed: its file has the checksum its row records.
  const std::string bed_path = daemon->Query("SELECT path FROM beds");
  auto sha = Sha256OfFile(fs::path(bed_path).is_absolute() ? bed_path : dir + "/daemon/" + bed_path);
  ASSERT_TRUE(sha.ok()) << bed_path;
  EXPECT_EQ(*sha, daemon->Query("SELECT sha256 FROM beds"));
  std::printf("CRASH trial %d: %s done, %zu runs started, %d more than once, %s leased again, integrity %s\n",
              trial, s["counts"]["done"].dump().c_str(), starts.size(), repeated, leased_again.c_str(),
              daemon->Query("PRAGMA integrity_check").c_str());
}

TEST(CrashTrialsTest, ASweepSurvivesTheDaemonKilledAtRandomMoments) {
  const int trials = EnvInt("SANDSWIM_CRASH_TRIALS", 2);
  const int runs = EnvInt("SANDSWIM_CRASH_RUNS", 40);
  const int kills = EnvInt("SANDSWIM_CRASH_KILLS", 4);
  const double engine_s = EnvDouble("SANDSWIM_CRASH_ENGINE_S", 0.5);
  const uint64_t first_seed = std::getenv("SANDSWIM_CRASH_SEED") != nullptr
                                  ? std::strtoull(std::getenv("SANDSWIM_CRASH_SEED"), nullptr, 10)
                                  : std::random_device{}();
  for (int t = 0; t < trials; ++t) {
    Trial(t, first_seed + static_cast<uint64_t>(t), runs, kills, engine_s);
    if (::testing::Test::HasFailure()) break;
  }
}

}  // namespace

// A worker that stops heartbeating but keeps running (SIGSTOP: a paused process, a frozen VM) is
// presumed dead once its lease expires: its run goes to another worker, and the paused worker's
// completion, when it wakes, is refused (409) -- one result, from the worker that held the lease.
TEST(CrashTrialsTest, APausedWorkersLateCompletionIsRefused) {
  const std::string dir = testing::CacheDir() + "/crash-trials/paused";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string starts_log = dir + "/engine-starts.log";
  setenv("SANDSWIM_STAND_IN_STARTS", starts_log.c_str(), 1);
  setenv("SANDSWIM_STAND_IN_SECONDS", "1.5", 1);
  testing::Daemon daemon(dir + "/daemon", {"--lease-ttl", "3", "--max-attempts", "3"});
  int status = 0;
  json submitted = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("paused", {-80}, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t sweep = submitted["id"].get<int64_t>();
  const std::vector<std::string> stand_in = {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH};
  auto paused = testing::StartWorker(daemon, dir + "/worker-paused", 1, stand_in);
  // Wait until it runs the run (after the bed), then pause it.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (daemon.Query("SELECT count(*) FROM runs WHERE state = 'running'") != "1") {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << paused->Output();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  paused->SignalProgram(SIGSTOP);
  // Its lease expires (3 s) and is reclaimed; another worker takes the run and completes it.
  auto other = testing::StartWorker(daemon, dir + "/worker-other", 1, stand_in);
  const json s = daemon.WaitForSweep(sweep, 60);
  EXPECT_EQ(s["counts"]["done"], 1) << s.dump() << "\n" << other->Output();
  // The paused worker wakes: its engine has long finished; its completion must change nothing.
  paused->SignalProgram(SIGCONT);
  const auto settle = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (paused->Output().find("lease was lost") == std::string::npos && std::chrono::steady_clock::now() < settle)
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_THAT(paused->Output(), ::testing::HasSubstr("lease was lost")) << paused->Output();
  EXPECT_EQ(daemon.Query("SELECT count(*) FROM results"), "1");
  EXPECT_EQ(daemon.Query("SELECT attempts FROM runs"), "2");
  EXPECT_EQ(daemon.Query("SELECT state FROM runs"), "done");
  // Two engine starts -- the paused worker's and the second worker's -- but one result: the
  // price of presuming a silent worker dead, and the reason a lease TTL is generous.
  const std::map<int64_t, int> starts = StartsPerRun(starts_log);
  ASSERT_EQ(starts.size(), 1u);
  EXPECT_EQ(starts.begin()->second, 2);
  EXPECT_EQ(daemon.Query("PRAGMA integrity_check"), "ok");
  paused->Stop();
  other->Stop();
}


// A submission is all or nothing: the daemon SIGKILLed while it plans and writes a large sweep
// (50,000 runs, one transaction) leaves either the whole sweep or none of it.
TEST(CrashTrialsTest, ASubmissionKilledMidwayLeavesAllOrNothing) {
  std::mt19937_64 rng(std::random_device{}());
  std::vector<double> omegas;
  for (int i = 0; i < 500; ++i) omegas.push_back(-10.0 - i);
  json sweep = testing::OmegaSweep("big", omegas, 0.05, 20);
  sweep["axes"].push_back({{"param", "A"}, {"range", {{"from", 0.001}, {"to", 0.1}, {"step", 0.001}}}});
  constexpr int64_t kRuns = 500 * 100;
  int whole = 0, none = 0;
  for (int trial = 0; trial < 4; ++trial) {
    const std::string dir = testing::CacheDir() + "/crash-trials/submission-" + std::to_string(trial);
    fs::remove_all(dir);
    auto daemon = std::make_unique<testing::Daemon>(dir + "/daemon");
    const std::string listen = daemon->listen();
    std::thread post([&] {
      try {
        int status = 0;
        daemon->Post("/api/v1/sweeps", sweep, &status);
      } catch (const std::exception&) {  // the daemon died under it: expected
      }
    });
    std::this_thread::sleep_for(std::chrono::duration<double>(std::uniform_real_distribution<double>(0.2, 3.0)(rng)));
    daemon->process().Kill(SIGKILL);
    post.join();
    daemon.reset();
    testing::Daemon again(dir + "/daemon", {}, listen);
    const std::string runs = again.Query("SELECT count(*) FROM runs");
    const std::string members = again.Query("SELECT count(*) FROM sweep_runs");
    const int64_t sweeps = std::stoll(again.Query("SELECT count(*) FROM sweeps"));
    // The sweep stored has all its runs, or there is neither sweep nor run.
    EXPECT_LE(sweeps, 1);
    EXPECT_EQ(std::stoll(runs), sweeps * kRuns) << "trial " << trial;
    EXPECT_EQ(std::stoll(members), sweeps * kRuns) << "trial " << trial;
    EXPECT_EQ(again.Query("PRAGMA integrity_check"), "ok");
    (sweeps > 0 ? whole : none)++;
    std::printf("CRASH submission trial %d: %lld sweep(s), %s runs after the kill\n", trial,
                static_cast<long long>(sweeps), runs.c_str());
  }
  std::printf("CRASH submissions: %d kills left nothing new, %d left whole sweeps, none a part\n", none, whole);
}

}  // namespace sandswim
