// Daemon crash trials: the promise that nothing is lost and a run is done once, tried by
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
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
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


namespace {

// Files directly in `dir` (none when it does not exist).
std::vector<fs::path> FilesIn(const std::string& dir) {
  std::vector<fs::path> files;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) files.push_back(e.path());
  return files;
}

// A PUT of a bed restart that stops halfway: the headers promise `promised` bytes and `sent` of
// them follow. The connection is left open, as a client's would be while the daemon dies.
int StartHalfUpload(const std::string& listen, int64_t bed_id, const std::string& token, size_t promised,
                    size_t sent) {
  const int fd = testing::ConnectTo(listen);
  if (fd < 0) return -1;
  std::string head = "PUT /api/v1/beds/" + std::to_string(bed_id) + "/restart?token=" + token +
                     " HTTP/1.1\r\nHost: " + listen +
                     "\r\nContent-Type: application/octet-stream\r\n"
                     "X-Sha256: " +
                     std::string(64, '0') + "\r\nContent-Length: " + std::to_string(promised) + "\r\n\r\n";
  head += std::string(sent, 'x');
  for (size_t off = 0; off < head.size();) {
    const ssize_t n = send(fd, head.data() + off, head.size() - off, MSG_NOSIGNAL);
    if (n <= 0) break;
    off += static_cast<size_t>(n);
  }
  return fd;
}

}  // namespace

// The daemon SIGKILLed while a bed's restart is being uploaded: the half-received body left in
// DATA/uploads/ is removed at the next start, no part of it is recorded as the bed, the bed's
// lease expires, a worker makes the bed again and the sweep finishes on a bed whose file has the
// checksum its row records.
TEST(CrashTrialsTest, ADaemonKilledDuringABedUploadRecordsNoPartOfIt) {
  const std::string dir = testing::CacheDir() + "/crash-trials/bed-upload";
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string starts_log = dir + "/engine-starts.log";
  setenv("SANDSWIM_STAND_IN_STARTS", starts_log.c_str(), 1);
  setenv("SANDSWIM_STAND_IN_SECONDS", "0.3", 1);
  const std::vector<std::string> flags = {"--lease-ttl", "3", "--max-attempts", "3"};
  auto daemon = std::make_unique<testing::Daemon>(dir + "/daemon", flags);
  const std::string listen = daemon->listen();
  int status = 0;
  json submitted = daemon->Post("/api/v1/sweeps", testing::OmegaSweep("upload", {-80}, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const std::string uploads = dir + "/daemon/data/uploads";
  {
    testing::BedHandIn held(*daemon);
    const int fd = StartHalfUpload(listen, held.grant().id, held.grant().token, 8 << 20, 4 << 20);
    ASSERT_GE(fd, 0);
    // The daemon is writing the body when it dies.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
    auto received = [&] {
      std::error_code ec;
      for (const auto& f : FilesIn(uploads))
        if (fs::file_size(f, ec) > 0) return true;
      return false;
    };
    while (!received()) {
      ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "no upload file appeared in " << uploads;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    daemon->process().Kill(SIGKILL);
    for (int i = 0; i < 500 && daemon->process().running(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    close(fd);
    EXPECT_EQ(FilesIn(uploads).size(), 1u) << "the killed daemon left its half upload";
  }  // the hand-in stops heartbeating: its lease expires after the restart
  daemon.reset();
  daemon = std::make_unique<testing::Daemon>(dir + "/daemon", flags, listen);
  EXPECT_TRUE(FilesIn(uploads).empty()) << "the restarted daemon kept a half upload";
  EXPECT_THAT(daemon->process().Output(), ::testing::HasSubstr("removed 1 unfinished backup or upload file(s)"));
  EXPECT_EQ(daemon->Query("SELECT count(*) FROM beds WHERE sha256 IS NOT NULL"), "0");
  EXPECT_TRUE(FilesIn(dir + "/daemon/data/beds").empty());

  auto worker = testing::StartWorker(*daemon, dir + "/worker", 1,
                                     {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  const json s = daemon->WaitForSweep(submitted["id"].get<int64_t>(), 60);
  worker->Stop();
  EXPECT_EQ(s["counts"]["done"], 1) << s.dump() << "\n" << worker->Output();
  EXPECT_EQ(daemon->Query("SELECT count(*) FROM results"), "1");
  EXPECT_EQ(daemon->Query("PRAGMA integrity_check"), "ok");
  const std::string bed_path = daemon->Query("SELECT path FROM beds");
  auto sha = Sha256OfFile(fs::path(bed_path).is_absolute() ? bed_path : dir + "/daemon/" + bed_path);
  ASSERT_TRUE(sha.ok()) << bed_path;
  EXPECT_EQ(*sha, daemon->Query("SELECT sha256 FROM beds"));
  EXPECT_TRUE(FilesIn(uploads).empty());
}

namespace {

// The engine alone, or mpirun alone, SIGKILLed under a live worker in the middle of a run: the
// worker reports the attempt failed on that signal, the run is queued again and run once more
// (the stand-in counts two starts), and there is one result. `launcher`: "direct" or "mpirun";
// `victim`: the command name of the process killed.
void KillAloneAndRunAgain(const std::string& launcher, const std::string& victim) {
  SCOPED_TRACE(launcher + ", " + victim + " killed");
  const std::string dir = testing::CacheDir() + "/crash-trials/alone-" + launcher;
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string starts_log = dir + "/engine-starts.log";
  setenv("SANDSWIM_STAND_IN_STARTS", starts_log.c_str(), 1);
  setenv("SANDSWIM_STAND_IN_SECONDS", "3", 1);
  // The requeue comes from the signal, not a lease's expiry: a long TTL keeps a busy machine's
  // late heartbeat from adding an attempt.
  testing::Daemon daemon(dir + "/daemon", {"--lease-ttl", "30", "--max-attempts", "3"});
  int status = 0;
  json submitted = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("alone", {-80}, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const std::string worker_dir = dir + "/worker";
  auto worker = testing::StartWorker(daemon, worker_dir, 1,
                                     {"--launcher", launcher, "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  pid_t target = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (target == 0) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << "no " << victim << " of a run seen\n" << worker->Output();
    if (daemon.Query("SELECT count(*) FROM runs WHERE state = 'running'") == "1") {
      for (const auto& p : testing::ProcessesUnder(worker_dir + "/"))
        if (p.comm == victim) target = p.pid;
    }
    if (target == 0) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(500));  // well into the run
  ASSERT_EQ(kill(target, SIGKILL), 0);
  const json s = daemon.WaitForSweep(submitted["id"].get<int64_t>(), 60);
  EXPECT_TRUE(worker->running()) << "the worker died with its engine\n" << worker->Output();
  // Nothing of either attempt outlives it: no rank orphaned by its mpirun.
  std::string left;
  for (const auto& p : testing::ProcessesUnder(worker_dir + "/")) left += " " + p.comm;
  EXPECT_EQ(left, "") << "processes left in the runs' directories";
  worker->Stop();
  EXPECT_EQ(s["counts"]["done"], 1) << s.dump() << "\n" << worker->Output();
  EXPECT_EQ(daemon.Query("SELECT attempts FROM runs"), "2");
  EXPECT_EQ(daemon.Query("SELECT count(*) FROM results"), "1");
  const std::string requeued = daemon.Query("SELECT detail FROM events WHERE kind = 'run.requeued'");
  EXPECT_THAT(requeued, ::testing::HasSubstr("\"signal\"")) << requeued;
  const std::map<int64_t, int> starts = StartsPerRun(starts_log);
  ASSERT_EQ(starts.size(), 1u);
  EXPECT_EQ(starts.begin()->second, 2);
  EXPECT_EQ(daemon.Query("PRAGMA integrity_check"), "ok");
  std::printf("CRASH %s killed alone under a %s worker: run requeued (%s), done once more, 1 result\n",
              victim.c_str(), launcher.c_str(), requeued.c_str());
}

}  // namespace

TEST(CrashTrialsTest, AnEngineKilledAloneIsRunAgain) { KillAloneAndRunAgain("direct", "sandswim-stand-"); }

TEST(CrashTrialsTest, MpirunKilledAloneIsRunAgain) { KillAloneAndRunAgain("mpirun", "mpirun"); }

// Disk faults: the daemon's database and data directory on a small filesystem the test mounts
// (a 64 MiB tmpfs: root only; the test is skipped, saying why, where it cannot mount), filled to
// its last byte while a sweep runs, and later made read-only. The daemon's own output stays on the
// ordinary disk beside them (symbolic links), so what it says can be read.
class DiskFaultsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::CacheDir() + "/crash-trials/disk";
    mnt_ = dir_ + "/fs";
    umount2(mnt_.c_str(), MNT_DETACH);  // left by an earlier run that died
    fs::remove_all(dir_);
    fs::create_directories(mnt_);
    if (mount("tmpfs", mnt_.c_str(), "tmpfs", 0, "size=64m") != 0) {
      GTEST_SKIP() << "cannot mount a tmpfs at " << mnt_ << " (" << std::strerror(errno)
                   << "): the disk-fault tests need root";
    }
    mounted_ = true;
    fs::create_directories(dir_ + "/daemon");
    fs::create_directories(mnt_ + "/data");
    fs::create_symlink(mnt_ + "/data", dir_ + "/daemon/data");
    fs::create_symlink(mnt_ + "/sandswim.db", dir_ + "/daemon/sandswim.db");
  }
  void TearDown() override {
    if (mounted_) umount2(mnt_.c_str(), MNT_DETACH);
  }
  // Fills the filesystem to its last byte with one file; returns its path.
  std::string Fill() {
    const std::string path = mnt_ + "/filler";
    FILE* f = std::fopen(path.c_str(), "wb");
    EXPECT_NE(f, nullptr);
    std::setvbuf(f, nullptr, _IONBF, 0);
    std::vector<char> block(1 << 16, 'f');
    for (size_t size = block.size(); size > 0; size /= 2) {
      while (std::fwrite(block.data(), 1, size, f) == size) {
      }
      std::clearerr(f);
    }
    std::fclose(f);
    return path;
  }
  bool mounted_ = false;
  std::string dir_, mnt_;
};

// Full to the last byte while a worker completes runs: a new sweep is refused with a problem that
// says the disk is full and what to do, and nothing of it is stored; reads still answer; the
// worker's completions wait (retried), and once space returns the sweep finishes with every run
// done once, one result each, the database intact, and new sweeps accepted again.
TEST_F(DiskFaultsTest, AFullDiskRefusesWritesClearlyAndServiceResumesWhenSpaceReturns) {
  const std::string starts_log = dir_ + "/engine-starts.log";
  setenv("SANDSWIM_STAND_IN_STARTS", starts_log.c_str(), 1);
  setenv("SANDSWIM_STAND_IN_SECONDS", "0.3", 1);
  testing::Daemon daemon(dir_ + "/daemon", {"--lease-ttl", "10", "--max-attempts", "3"});
  const int runs = 12;
  std::vector<double> omegas;
  for (int i = 0; i < runs; ++i) omegas.push_back(-10.0 - i);
  int status = 0;
  json submitted = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("disk", omegas, 0.05, 20), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t sweep = submitted["id"].get<int64_t>();
  auto worker = testing::StartWorker(daemon, dir_ + "/worker", 1,
                                     {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH});
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (std::stoll(daemon.Query("SELECT count(*) FROM results")) < 2) {
    ASSERT_LT(std::chrono::steady_clock::now(), deadline) << worker->Output();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const std::string filler = Fill();
  const std::string done_when_full = daemon.Query("SELECT count(*) FROM results");

  json refused = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("while-full", {-5}, 0.05, 20), &status);
  EXPECT_EQ(status, 503) << refused.dump();
  EXPECT_THAT(refused.value("detail", ""), ::testing::HasSubstr("disk that holds the database is full")) << refused.dump();
  EXPECT_EQ(daemon.Query("SELECT count(*) FROM sweeps"), "1");
  daemon.Get("/api/v1/sweeps/" + std::to_string(sweep), &status);
  EXPECT_EQ(status, 200) << "reads stop when the disk is full";
  std::this_thread::sleep_for(std::chrono::seconds(3));  // the worker's completions meet the full disk
  const std::string done_while_full = daemon.Query("SELECT count(*) FROM results");
  EXPECT_LT(std::stoll(done_while_full), runs) << "the sweep finished before the full disk was met";

  fs::remove(filler);
  const json s = daemon.WaitForSweep(sweep, 60);
  EXPECT_EQ(s["counts"]["done"], runs) << s.dump() << "\n" << worker->Output();
  EXPECT_EQ(daemon.Query("SELECT count(*) FROM results"), std::to_string(runs));
  const std::map<int64_t, int> starts = StartsPerRun(starts_log);
  EXPECT_EQ(starts.size(), static_cast<size_t>(runs));
  for (const auto& [run, n] : starts) EXPECT_EQ(n, 1) << "run " << run << " started " << n << " times";
  EXPECT_EQ(daemon.Query("PRAGMA integrity_check"), "ok");
  json accepted = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("after", {-5}, 0.05, 20), &status);
  EXPECT_EQ(status, 201) << accepted.dump();
  worker->Stop();
  EXPECT_TRUE(daemon.process().running());
  std::printf("DISK full: %s results when filled, %s after 3 s full, %d after space returned; refused: %s\n",
              done_when_full.c_str(), done_while_full.c_str(), runs, refused.value("detail", "").c_str());
}

// A database on a filesystem that became read-only: the daemon does not start, and says why and
// what to do; made writable again, it starts on the same files with everything it had.
TEST_F(DiskFaultsTest, ADaemonOnAReadOnlyDatabaseSaysSoAndStartsWhenWritable) {
  std::string listen;
  {
    testing::Daemon daemon(dir_ + "/daemon");
    listen = daemon.listen();
    int status = 0;
    json submitted = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("ro", {-5, -6}, 0.05, 20), &status);
    ASSERT_EQ(status, 201) << submitted.dump();
    daemon.process().Stop();
  }
  ASSERT_EQ(mount("tmpfs", mnt_.c_str(), "tmpfs", MS_REMOUNT | MS_RDONLY, "size=64m"), 0) << std::strerror(errno);
  std::string said;
  try {
    testing::Daemon daemon(dir_ + "/daemon", {}, listen);
    ADD_FAILURE() << "the daemon started on a read-only database";
  } catch (const std::runtime_error& e) {
    said = e.what();
  }
  EXPECT_THAT(said, ::testing::HasSubstr("is on a read-only filesystem")) << said;
  ASSERT_EQ(mount("tmpfs", mnt_.c_str(), "tmpfs", MS_REMOUNT, "size=64m"), 0) << std::strerror(errno);
  testing::Daemon daemon(dir_ + "/daemon", {}, listen);
  EXPECT_EQ(daemon.Query("SELECT count(*) FROM runs"), "2");
  EXPECT_EQ(daemon.Query("PRAGMA integrity_check"), "ok");
  std::printf("DISK read-only: the daemon said: %s\n", said.substr(said.rfind("\n", said.size() - 2) + 1).c_str());
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
