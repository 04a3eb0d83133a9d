#include "workers/worker.h"

#include <signal.h>
#include <stdlib.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <fstream>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/dump_reader.h"
#include "core/keys.h"
#include "core/trajectory.h"
#include "platform/clock.h"
#include "tests/fixture_file.h"

namespace sandswim::worker {
namespace {

using testing::Fixture;  // tests/fixture_file.h

void WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
}

constexpr char kBedBytes[] = "pretend restart bytes";

// The clock of tests that run several slots on threads of their own (their fakes then take real
// time); the others give the worker, client and launcher one FakeClock, which the fake engine's
// waits move.
Clock* RealClock() {
  static SystemClock clock;
  return &clock;
}

// The daemon, scripted.
class FakeClient : public ServerClient {
 public:
  std::mutex mu;
  std::deque<api::LeaseGrant> grants;
  std::vector<api::Heartbeat> beats;
  std::vector<api::Completion> completions;
  std::vector<std::string> uploads;  // sha256 of each upload
  bool cancel_on_beat = false;
  size_t cancel_from_beat = 0;  // > 0: answer cancel from this beat on (1: the first)
  std::condition_variable beat_cv;  // notified on every heartbeat
  bool conflict_on_beat = false;
  std::string bed_bytes = kBedBytes;
  std::atomic<int> downloads{0};
  bool piggyback = false;             // answer a completion's `next` with the next grant, as the daemon does
  int granted_by_lease = 0;           // grants handed out by Lease() (not with a completion)
  std::vector<std::string> released;  // tokens handed back
  std::function<void()> on_complete;  // runs inside Complete (e.g. a stop request arriving then)
  Clock* clock = RealClock();
  std::vector<double> completed_at;  // the clock's monotonic time of each completion
  std::vector<api::LeaseGrant> granted;  // by Lease()
  bool requeue_released = false;         // a released grant is leasable again
  // Runs at the start of the n-th Lease() call (from 0), before it looks at `grants`: holds a
  // lease on its way while the test arranges what happens meanwhile.
  std::function<void(int n)> before_lease;
  std::atomic<int> lease_calls{0};

  Result<std::optional<api::LeaseGrant>> Lease(const api::LeaseRequest&) override {
    const int n = lease_calls++;
    if (before_lease) before_lease(n);
    std::lock_guard<std::mutex> l(mu);
    if (grants.empty()) return std::optional<api::LeaseGrant>();
    ++granted_by_lease;
    api::LeaseGrant g = grants.front();
    grants.pop_front();
    granted.push_back(g);
    return std::optional<api::LeaseGrant>(g);
  }
  Result<api::HeartbeatReply> Heartbeat(const std::string&, const api::Heartbeat& beat) override {
    std::lock_guard<std::mutex> l(mu);
    beats.push_back(beat);
    beat_cv.notify_all();
    if (conflict_on_beat) return Status::Conflict("lease lost");
    api::HeartbeatReply r;
    r.cancel = cancel_on_beat || (cancel_from_beat > 0 && beats.size() >= cancel_from_beat);
    return r;
  }
  Status DownloadBed(const api::BedRef&, const std::string& dest) override {
    ++downloads;
    WriteFile(dest, bed_bytes);
    return Status::Ok();
  }
  Status UploadBed(int64_t, const std::string&, const std::string&, const std::string& sha256) override {
    std::lock_guard<std::mutex> l(mu);
    uploads.push_back(sha256);
    return Status::Ok();
  }
  Result<api::CompletionReply> Complete(const std::string&, const api::Completion& c) override {
    std::lock_guard<std::mutex> l(mu);
    completions.push_back(c);
    completed_at.push_back(clock->Monotonic());
    if (on_complete) on_complete();
    api::CompletionReply reply{c.ok ? "done" : "failed"};
    if (piggyback && c.next && !grants.empty()) {
      reply.next = grants.front();
      grants.pop_front();
    }
    return reply;
  }
  // False when `n` heartbeats have not come within 10 s of real time.
  bool WaitForBeats(size_t n) {
    std::unique_lock<std::mutex> l(mu);
    return beat_cv.wait_for(l, std::chrono::seconds(10), [&] { return beats.size() >= n; });
  }
  Result<api::CompletionReply> Release(const std::string& token, const std::string&) override {
    std::lock_guard<std::mutex> l(mu);
    released.push_back(token);
    if (requeue_released) {  // as the daemon does: queued again, leasable at once
      for (const api::LeaseGrant& g : granted)
        if (g.token == token) grants.push_front(g);
    }
    return api::CompletionReply{"queued"};
  }
};

// The engine, scripted: writes its output files into the run directory when started, then
// either exits at once or runs until stopped.
class FakeProcess : public EngineProcess {
 public:
  // `stops` outlives the process (the worker destroys it when the job ends): tests read it.
  FakeProcess(Clock* clock, bool runs_until_stopped, std::atomic<int>* stops, double runs_for_s = 0, int exit_code = 0)
      : clock_(clock), running_(runs_until_stopped), stops_(stops), until_(clock->Monotonic() + runs_for_s) {
    status_.exit_code = exit_code;
  }
  pid_t pid() const override { return 0; }
  // Waits on the clock: a FakeClock moves by the time waited.
  bool WaitFor(double seconds) override {
    if (!running_) {
      clock_->SleepFor(std::min(seconds, until_ - clock_->Monotonic()));
      return clock_->Monotonic() >= until_;
    }
    clock_->SleepFor(std::min(seconds, 0.005));
    return !running_;
  }
  void Stop(double) override {
    ++*stops_;
    if (running_) status_.signal = SIGTERM;
    running_ = false;
  }
  ExitStatus exit_status() const override { return status_; }

 private:
  Clock* clock_;
  std::atomic<bool> running_;
  std::atomic<int>* stops_;
  double until_;  // the clock's monotonic time it exits by itself at (runs_for_s)
  ExitStatus status_;
};

class FakeLauncher : public Launcher {
 public:
  std::map<std::string, std::string> files;  // written into the run directory at start
  bool runs_until_stopped = false;
  Clock* clock = RealClock();
  double runs_for_s = 0;  // wall time a process takes before it exits by itself
  bool missing = false;
  // mpirun with more ranks than this (0: any) exits at once with Open MPI's refusal, as it does
  // when the host has fewer slots and --oversubscribe is missing or not understood.
  int refuses_above_ranks = 0;
  std::mutex mu;
  std::vector<LaunchSpec> started;
  std::vector<double> started_at;  // the clock's monotonic time of each start
  std::atomic<int> stops{0};  // Stop() calls on any process this launcher started
  size_t Started() {
    std::lock_guard<std::mutex> l(mu);
    return started.size();
  }

  Result<std::unique_ptr<EngineProcess>> Start(const LaunchSpec& spec) override {
    if (missing) return Status::Unavailable("'liggghts' not found on PATH or not executable");
    std::lock_guard<std::mutex> l(mu);
    started.push_back(spec);
    started_at.push_back(clock->Monotonic());
    int np = 1;
    for (size_t i = 0; i + 1 < spec.argv.size(); ++i)
      if (spec.argv[i] == "-np") np = std::stoi(spec.argv[i + 1]);
    if (refuses_above_ranks > 0 && np > refuses_above_ranks) {
      WriteFile(spec.cwd + "/" + spec.output_file,
                "There are not enough slots available in the system to satisfy the " + std::to_string(np) +
                    "\nslots that were requested by the application:\n");
      return std::unique_ptr<EngineProcess>(std::make_unique<FakeProcess>(clock, false, &stops, 0, 1));
    }
    for (const auto& [name, text] : files) WriteFile(spec.cwd + "/" + name, text);
    return std::unique_ptr<EngineProcess>(std::make_unique<FakeProcess>(clock, runs_until_stopped, &stops, runs_for_s));
  }
};

// What the daemon's lease carries besides the deck (core/deck.h DriveFacts), here read from the
// fixture deck, which states the very numbers it was rendered from.
api::LeaseGrant WithDriveFacts(api::LeaseGrant g) {
  Result<DriveInfo> drive = ReadDriveInfo(g.deck);
  EXPECT_TRUE(drive.ok()) << drive.status().ToString();
  if (!drive.ok()) return g;
  g.dt_s = drive->dt;
  g.f_hz = drive->f;
  g.A_m = drive->A;
  g.z_floor_m = drive->z_floor;
  g.so_radius_m = drive->so_radius;
  return g;
}

api::LeaseGrant RunGrant() {
  api::LeaseGrant g;
  g.token = "tok-1";
  g.kind = api::JobKind::kRun;
  g.id = 42;
  g.attempt = 2;
  g.deck = Fixture("drive_omega_minus80.in");
  g.steps = 30000;
  g.duration_s = 0.3;
  g.ttl_s = 60;
  g.bed = api::BedRef{7, Sha256Hex(kBedBytes), "/api/v1/beds/7/restart"};
  return WithDriveFacts(g);
}

WorkerOptions WorkerOptionsFor(const std::string& workdir) {
  WorkerOptions o;
  o.name = "test:1";
  o.host = "testhost";
  o.workdir = workdir;
  o.heartbeat_every_s = 0.01;
  o.stop_grace_s = 0.1;
  o.stop_settle_s = 0;
  o.idle_poll_s = 0.01;
  o.launcher = LauncherKind::kDirect;
  o.keep_run_dirs = true;
  return o;
}

// Puts the worker, its daemon and its engine on one FakeClock: a job's heartbeats, budgets and
// stalls then happen in the time the fake engine's waits move, with no real wait.
WorkerOptions OnClock(FakeClock* clock, FakeClient& client, FakeLauncher& launcher, WorkerOptions o) {
  client.clock = clock;
  launcher.clock = clock;
  o.clock = clock;
  return o;
}

TEST(WorkerTest, CompletedRunCarriesItsResultAndTrajectory) {
  const std::string work = testing::TempDir("worker");
  FakeClient client;
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("drive_omega_minus80.log")},
                    {"so.dump", Fixture("so_omega_minus80.dump")}};
  Worker worker(WorkerOptionsFor(work), client, launcher);
  worker.RunJob(RunGrant());

  ASSERT_EQ(client.completions.size(), 1u);
  const api::Completion& c = client.completions[0];
  ASSERT_TRUE(c.ok) << (c.failure ? c.failure->kind + ": " + c.failure->message : "");
  ASSERT_TRUE(c.result.has_value());
  // 0.3 s at 3 Hz: the window after the one-period transient holds no whole period.
  EXPECT_FALSE(c.result->uz.has_value());
  EXPECT_FALSE(c.result->conclusive);
  EXPECT_EQ(c.result->analysis, api::kAnalysisVersion);
  EXPECT_GT(c.result->dz_rate, 0.0);  // Omega = -80 rose in this run
  EXPECT_EQ(c.result->steps, 30000);
  EXPECT_EQ(c.result->grains, 5024);
  EXPECT_EQ(c.result->stop_reason, "duration");
  EXPECT_NEAR(c.result->dz, 0.0266815 - -0.0112944, 1e-12);
  ASSERT_TRUE(c.trajectory.has_value());
  EXPECT_EQ(c.trajectory->t.size(), 301u);
  EXPECT_DOUBLE_EQ(c.trajectory->t.back(), 0.3);
  EXPECT_NE(c.execution.engine_version.find("LIGGGHTS-PUBLIC 3.8.0"), std::string::npos);
  EXPECT_EQ(c.execution.host, "testhost");
  EXPECT_EQ(c.execution.launcher, "direct");
  EXPECT_FALSE(c.log_tail.empty());
  // The run directory has the deck and the verified bed.
  ASSERT_EQ(launcher.started.size(), 1u);
  EXPECT_EQ(launcher.started[0].cwd, work + "/run-42-a2");
  std::ifstream bed(work + "/run-42-a2/bed.restart");
  std::string bed_text((std::istreambuf_iterator<char>(bed)), std::istreambuf_iterator<char>());
  EXPECT_EQ(bed_text, kBedBytes);
  // A second run from the same bed does not download it again.
  worker.RunJob(RunGrant());
  EXPECT_EQ(client.downloads.load(), 1);
}

// `sandswim analyze` on the run directory the worker leaves gives the numbers the worker reported:
// a real 3 s vibration run (tests/fixtures/runs/vibration-3s), analysed by the worker, then by the
// real CLI binary from the files alone.
TEST(WorkerTest, OfflineAnalysisOfTheRunDirectoryGivesTheWorkersNumbers) {
  const std::string work = testing::TempDir("worker");
  FakeClient client;
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("runs/vibration-3s/log.liggghts")},
                    {"so.dump", Fixture("runs/vibration-3s/so.dump")}};
  Worker worker(WorkerOptionsFor(work), client, launcher);
  api::LeaseGrant grant = RunGrant();
  grant.deck = Fixture("runs/vibration-3s/drive.in");
  grant.steps = 300000;
  grant.duration_s = 3;
  grant = WithDriveFacts(grant);
  worker.RunJob(grant);
  ASSERT_EQ(client.completions.size(), 1u);
  ASSERT_TRUE(client.completions[0].ok);
  const api::RunResult& mine = *client.completions[0].result;
  ASSERT_TRUE(mine.conclusive && mine.uz && mine.uz_stderr);

  const std::string out = work + "/analyze.json";
  const std::string cmd = std::string(SANDSWIM_CLI_PATH) + " analyze " + work + "/run-42-a2/so.dump --json > " + out;
  ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
  nlohmann::json j = nlohmann::json::parse(std::ifstream(out));
  ASSERT_EQ(j.size(), 1u);
  api::RunResult theirs = j[0]["result"].get<api::RunResult>();
  EXPECT_EQ(j[0]["inputs"]["surface_from"], "log " + work + "/run-42-a2/log.liggghts");
  // The same numbers, to the last bit: one analysis, the same inputs.
  EXPECT_EQ(theirs.uz, mine.uz);
  EXPECT_EQ(theirs.uz_stderr, mine.uz_stderr);
  EXPECT_EQ(theirs.uz_ci95, mine.uz_ci95);
  EXPECT_EQ(theirs.uz_blocks, mine.uz_blocks);
  EXPECT_EQ(theirs.window_t0, mine.window_t0);
  EXPECT_EQ(theirs.window_t1, mine.window_t1);
  EXPECT_EQ(theirs.window_end, mine.window_end);
  EXPECT_EQ(theirs.conclusive, mine.conclusive);
  EXPECT_EQ(theirs.dz, mine.dz);
  EXPECT_EQ(theirs.dz_rate, mine.dz_rate);
  EXPECT_EQ(theirs.z_osc_amplitude, mine.z_osc_amplitude);
  EXPECT_EQ(theirs.grains, mine.grains);
  EXPECT_EQ(theirs.stop_reason, mine.stop_reason);
}

TEST(WorkerTest, DeckErrorIsReportedWithItsLine) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("deck_error.log")}};
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(RunGrant());
  ASSERT_EQ(client.completions.size(), 1u);
  ASSERT_TRUE(client.completions[0].failure.has_value());
  EXPECT_EQ(client.completions[0].failure->kind, "deck_error");
  EXPECT_EQ(client.completions[0].failure->message, "ERROR: Unknown command: foo_command 1 2 (./src/input.cpp:259)");
}

TEST(WorkerTest, CancelStopsTheEngineAndCompletesAsCancelled) {
  FakeClient client;
  client.cancel_on_beat = true;
  FakeLauncher launcher;
  launcher.runs_until_stopped = true;
  FakeClock clock;
  Worker worker(OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker"))), client, launcher);
  worker.RunJob(RunGrant());
  EXPECT_EQ(client.beats.size(), 1u);  // the first beat's reply stops it
  EXPECT_NEAR(clock.Monotonic(), 0.01, 0.006);  // at the first beat (heartbeat_every_s)
  ASSERT_EQ(launcher.started.size(), 1u);
  EXPECT_GT(launcher.stops.load(), 0);
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_EQ(client.completions[0].failure->kind, "cancelled");
}

TEST(WorkerTest, LeaseLossStopsTheEngineWithoutCompleting) {
  FakeClient client;
  client.conflict_on_beat = true;
  FakeLauncher launcher;
  launcher.runs_until_stopped = true;
  FakeClock clock;
  Worker worker(OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker"))), client, launcher);
  worker.RunJob(RunGrant());
  EXPECT_GT(launcher.stops.load(), 0);
  EXPECT_TRUE(client.completions.empty());
  EXPECT_EQ(worker.stats().abandoned, 1);
}

TEST(WorkerTest, HeartbeatsCarryTheSoZFromTheGrowingDump) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.runs_until_stopped = true;
  const std::string dump = Fixture("so_omega_minus80.dump");
  // 51 whole frames (steps 0..5000) and a torn 52nd, as while the engine writes.
  size_t cut = 0;
  for (int i = 0; i < 51; ++i) cut = dump.find("ITEM: TIMESTEP", cut + 1);
  launcher.files = {{"so.dump", dump.substr(0, cut + 40)}};
  client.cancel_from_beat = 3;
  FakeClock clock;
  Worker worker(OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker"))), client, launcher);
  worker.RunJob(RunGrant());
  ASSERT_EQ(client.beats.size(), 3u);
  EXPECT_EQ(client.beats[2].step, client.beats[0].step);  // the dump did not grow
  const api::Heartbeat& b = client.beats.front();
  EXPECT_EQ(b.step, 5000);
  EXPECT_DOUBLE_EQ(b.sim_time_s, 5000 * 1e-5);
  auto frames = ReadDump(dump.substr(0, cut));
  ASSERT_TRUE(frames.ok());
  EXPECT_DOUBLE_EQ(b.so_z, frames->back().At(0, 3));
}

TEST(WorkerTest, WallBudgetStopsTheEngineAsTimeout) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.runs_until_stopped = true;
  api::LeaseGrant g = RunGrant();
  g.wall_budget_s = 0.05;
  FakeClock clock;
  Worker worker(OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker"))), client, launcher);
  worker.RunJob(g);
  // Stopped once the budget had passed, at the first look after it (the fake engine waits 5 ms at a time).
  EXPECT_GT(clock.Monotonic(), 0.05);
  EXPECT_LT(clock.Monotonic(), 0.05 + 0.006);
  EXPECT_GT(launcher.stops.load(), 0);
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_EQ(client.completions[0].failure->kind, "timeout");
}

// An engine that runs on without its simulated time moving (no dump is ever written here) is
// stopped and reported as stalled, with the step it stood at.
TEST(WorkerTest, AHungEngineIsStoppedAsStalled) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.runs_until_stopped = true;
  FakeClock clock;
  WorkerOptions o = OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker")));
  o.stall_after_s = 0.05;
  Worker worker(o, client, launcher);
  worker.RunJob(RunGrant());
  // The first heartbeat (at 0.01 s) sees step 0; standing still from then, the engine is stopped
  // at the first heartbeat (every 0.01 s) after stall_after_s.
  EXPECT_GT(clock.Monotonic(), 0.01 + 0.05);
  EXPECT_LT(clock.Monotonic(), 0.01 + 0.05 + 0.015);
  EXPECT_GT(launcher.stops.load(), 0);
  ASSERT_EQ(client.completions.size(), 1u);
  ASSERT_TRUE(client.completions[0].failure.has_value());
  EXPECT_EQ(client.completions[0].failure->kind, "stalled");
  EXPECT_NE(client.completions[0].failure->message.find("step 0"), std::string::npos)
      << client.completions[0].failure->message;
}

// The same stand, told apart by the engine's CPU (here a fake /proc): runnable but given a tenth
// of a core, it is starved by other work and left to run; sleeping, or spinning at a whole core
// without moving, it is hung.
TEST(WorkerTest, AStarvedEngineIsNotStoppedAsStalled) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.runs_for_s = 2;  // forty stall times; then exits by itself (without output: it fails, but not as stalled)
  FakeClock clock;
  WorkerOptions o = OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker")));
  o.stall_after_s = 0.05;
  o.heartbeat_every_s = 0.01;
  o.engine_cpu = [&clock](pid_t) -> std::optional<TreeCpu> {
    return TreeCpu{0.1 * clock.Monotonic(), /*runnable=*/true, 1};
  };
  Worker worker(o, client, launcher);
  worker.RunJob(RunGrant());
  EXPECT_GE(clock.Monotonic(), 2.0);  // it ran until it exited
  EXPECT_EQ(launcher.stops.load(), 0);
  ASSERT_EQ(client.completions.size(), 1u);
  if (client.completions[0].failure) {
    EXPECT_NE(client.completions[0].failure->kind, "stalled");
  }
}

TEST(WorkerTest, ASleepingOrSpinningEngineIsStoppedAsStalled) {
  FakeClock clock;
  auto wall = [&clock] { return clock.Monotonic(); };
  const std::function<std::optional<TreeCpu>(pid_t)> sleeping = [](pid_t) {
    return std::optional<TreeCpu>(TreeCpu{0.01, /*runnable=*/false, 1});
  };
  const std::function<std::optional<TreeCpu>(pid_t)> spinning = [wall](pid_t) {
    return std::optional<TreeCpu>(TreeCpu{wall(), /*runnable=*/true, 1});
  };
  for (const auto& probe : {sleeping, spinning}) {
    FakeClient client;
    FakeLauncher launcher;
    launcher.runs_until_stopped = true;
    WorkerOptions o = OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker")));
    o.stall_after_s = 0.05;
    o.heartbeat_every_s = 0.01;
    o.engine_cpu = probe;
    const double started = clock.Monotonic();
    Worker worker(o, client, launcher);
    worker.RunJob(RunGrant());
    EXPECT_LT(clock.Monotonic() - started, 0.01 + 0.05 + 0.015);  // as AHungEngineIsStoppedAsStalled
    ASSERT_EQ(client.completions.size(), 1u);
    ASSERT_TRUE(client.completions[0].failure.has_value());
    EXPECT_EQ(client.completions[0].failure->kind, "stalled");
  }
}

TEST(WorkerTest, BedChecksumMismatchNeverStartsTheEngine) {
  FakeClient client;
  client.bed_bytes = "tampered bytes";
  FakeLauncher launcher;
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(RunGrant());
  EXPECT_TRUE(launcher.started.empty());
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_EQ(client.completions[0].failure->kind, "bed_mismatch");
}

TEST(WorkerTest, MissingEngineIsReported) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.missing = true;
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(RunGrant());
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_EQ(client.completions[0].failure->kind, "engine_missing");
}

TEST(WorkerTest, EngineExitingZeroWithoutFinishingIsIncomplete) {
  FakeClient client;
  FakeLauncher launcher;
  std::string log = Fixture("drive_omega_minus80.log");
  log = log.substr(0, log.find("SANDSWIM drive stop"));  // as after SIGTERM: exit 0, no stop marker
  launcher.files = {{"log.liggghts", log}, {"so.dump", Fixture("so_omega_minus80.dump")}};
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(RunGrant());
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_EQ(client.completions[0].failure->kind, "incomplete");
}

TEST(WorkerTest, CorruptDumpIsBadOutput) {
  FakeClient client;
  FakeLauncher launcher;
  std::string dump = Fixture("so_omega_minus80.dump");
  dump.replace(dump.find("0.0266815"), 9, "0.02x6815");
  launcher.files = {{"log.liggghts", Fixture("drive_omega_minus80.log")}, {"so.dump", dump}};
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(RunGrant());
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_EQ(client.completions[0].failure->kind, "bad_output");
  EXPECT_NE(client.completions[0].failure->message.find("dump line 3010"), std::string::npos)
      << client.completions[0].failure->message;
}

// The worker never guesses what the deck states: a lease without its typed timestep (a daemon
// older than the worker) fails the job, saying so, without starting the engine.
TEST(WorkerTest, ALeaseWithoutItsTimestepFailsWithoutStartingTheEngine) {
  FakeClient client;
  FakeLauncher launcher;
  api::LeaseGrant g = RunGrant();
  g.dt_s = 0;
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(g);
  ASSERT_EQ(client.completions.size(), 1u);
  ASSERT_FALSE(client.completions[0].ok);
  EXPECT_EQ(client.completions[0].failure->kind, "bad_lease");
  EXPECT_NE(client.completions[0].failure->message.find("dt_s"), std::string::npos);
  EXPECT_TRUE(launcher.started.empty());
}

TEST(WorkerTest, BedJobUploadsTheRestartAndReportsTheBed) {
  FakeClient client;
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("bed.log")}, {"bed.restart", "new bed bytes"}};
  api::LeaseGrant g;
  g.token = "tok-bed";
  g.kind = api::JobKind::kBed;
  g.id = 7;
  g.deck = "timestep 1e-05\n";
  g.dt_s = 1e-5;
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  worker.RunJob(g);
  ASSERT_EQ(client.completions.size(), 1u);
  const api::Completion& c = client.completions[0];
  ASSERT_TRUE(c.ok) << c.failure->message;
  ASSERT_TRUE(c.bed_result.has_value());
  EXPECT_EQ(c.bed_result->grains, 5024);
  EXPECT_TRUE(c.bed_result->equilibrated);
  EXPECT_NEAR(c.bed_result->ke_ratio, 0.00300510734387237 / 37.677812517013, 1e-15);
  EXPECT_EQ(c.bed_result->sha256, Sha256Hex("new bed bytes"));
  EXPECT_EQ(c.bed_result->bytes, 13);
  ASSERT_EQ(client.uploads.size(), 1u);
  EXPECT_EQ(client.uploads[0], Sha256Hex("new bed bytes"));
  EXPECT_EQ(launcher.started[0].argv[2], "bed.in");
}

TEST(WorkerTest, StopRequestStopsRunningJobsWithoutCompleting) {
  FakeClient client;
  client.grants.push_back(RunGrant());
  FakeLauncher launcher;
  launcher.runs_until_stopped = true;
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.slots = 2;
  Worker worker(o, client, launcher);
  std::thread run([&] { worker.Run(); });
  EXPECT_TRUE(client.WaitForBeats(1));
  worker.RequestStop();
  run.join();
  ASSERT_EQ(launcher.started.size(), 1u);
  EXPECT_GT(launcher.stops.load(), 0);
  EXPECT_TRUE(client.completions.empty());
  EXPECT_EQ(worker.stats().leased, 1);
}

// A once-worker runs one job and never asks for a next one with its completion.
TEST(WorkerTest, OnceTakesOneJobAndReturns) {
  FakeClient client;
  client.piggyback = true;
  client.grants = {RunGrant(), RunGrant()};
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("drive_omega_minus80.log")},
                    {"so.dump", Fixture("so_omega_minus80.dump")}};
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.once = true;
  o.slots = 4;
  Worker worker(o, client, launcher);
  worker.Run();
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_FALSE(client.completions[0].next.has_value());
  EXPECT_EQ(client.grants.size(), 1u);
}

// Each completion asks for the next job, and a job that came with the reply runs without a
// lease call of its own: one round trip per job.
TEST(WorkerTest, JobsLeasedWithTheCompletionRunWithoutAnotherLease) {
  FakeClient client;
  client.piggyback = true;
  client.grants = {RunGrant(), RunGrant(), RunGrant()};
  client.grants[1].token = "tok-2";
  client.grants[2].token = "tok-3";
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("drive_omega_minus80.log")},
                    {"so.dump", Fixture("so_omega_minus80.dump")}};
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.idle_poll_s = 0.01;
  o.exit_when_idle_s = 0.05;
  o.slurm_job = "77";  // inside an allocation, every request says which job it is
  Worker worker(o, client, launcher);
  worker.Run();
  ASSERT_EQ(client.completions.size(), 3u);
  for (const api::Completion& c : client.completions) {
    ASSERT_TRUE(c.next.has_value());
    EXPECT_EQ(c.next->worker, o.name);
    EXPECT_EQ(c.next->slurm_job, "77");
  }
  EXPECT_EQ(worker.stats().leased, 3);
  EXPECT_EQ(launcher.started.size(), 3u);
  // Only the first job came from a lease call.
  std::lock_guard<std::mutex> l(client.mu);
  EXPECT_EQ(client.granted_by_lease, 1);
  EXPECT_TRUE(client.grants.empty());
  EXPECT_TRUE(client.released.empty());
}

// Whether the next job fits the allocation is judged with the run just done counted: a first
// run longer than the time left asks for no next job (before any run, the margin is the guess).
TEST(WorkerTest, NextJobIsAskedForOnlyWhenItFitsTheAllocation) {
  FakeClient client;
  client.piggyback = true;
  client.grants = {RunGrant(), RunGrant()};
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("drive_omega_minus80.log")},
                    {"so.dump", Fixture("so_omega_minus80.dump")}};
  launcher.runs_for_s = 0.3;
  FakeClock clock;
  WorkerOptions o = OnClock(&clock, client, launcher, WorkerOptionsFor(testing::TempDir("worker")));
  o.end_margin_s = 0.01;
  o.allocation_seconds_left = []() -> Result<std::optional<double>> { return std::optional<double>(0.2); };
  Worker worker(o, client, launcher);
  worker.Run();  // one run, then nothing fits
  ASSERT_EQ(client.completions.size(), 1u);
  EXPECT_FALSE(client.completions[0].next.has_value());
  EXPECT_TRUE(worker.stats().allocation_ending);
  EXPECT_EQ(client.grants.size(), 1u);
}

// A job that came with the last completion as the worker was stopping is handed back unstarted.
TEST(WorkerTest, NextJobArrivingAsTheWorkerStopsIsHandedBack) {
  FakeClient client;
  client.piggyback = true;
  client.grants = {RunGrant(), RunGrant()};
  client.grants[1].token = "tok-next";
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("drive_omega_minus80.log")},
                    {"so.dump", Fixture("so_omega_minus80.dump")}};
  Worker worker(WorkerOptionsFor(testing::TempDir("worker")), client, launcher);
  client.on_complete = [&] { worker.RequestStop(); };
  worker.Run();
  EXPECT_EQ(launcher.started.size(), 1u);
  ASSERT_EQ(client.released.size(), 1u);
  EXPECT_EQ(client.released[0], "tok-next");
}

TEST(WorkerTest, ExitWhenIdleReturnsWithNoWork) {
  FakeClient client;  // no grants: every lease answers "nothing queued"
  FakeLauncher launcher;
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.once = true;
  o.idle_poll_s = 0.01;
  o.exit_when_idle_s = 0.05;
  Worker worker(o, client, launcher);
  worker.Run();  // would wait forever without exit_when_idle_s
  EXPECT_EQ(worker.stats().leased, 0);
  EXPECT_TRUE(launcher.started.empty());
}


// A bed job as the daemon grants it (queue_dry: nothing else was leasable then).
api::LeaseGrant BedGrant(int64_t id, bool queue_dry) {
  api::LeaseGrant g;
  g.token = "tok-bed-" + std::to_string(id);
  g.kind = api::JobKind::kBed;
  g.id = id;
  g.deck = "timestep 1e-05\n";
  g.dt_s = 1e-5;
  g.queue_dry = queue_dry;
  return g;
}

// The ranks an engine was started with: mpirun's -np, or 1 for the direct launcher.
int RanksOf(const LaunchSpec& spec) {
  for (size_t i = 0; i + 1 < spec.argv.size(); ++i)
    if (spec.argv[i] == "-np") return std::stoi(spec.argv[i + 1]);
  return 1;
}

bool WaitUntil(const std::function<bool()>& done, double seconds = 10) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                                              std::chrono::duration<double>(seconds));
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return true;
}

// No idle cores: a bed granted with the queue dry runs on the ranks of the worker's idle slot
// too, and that slot leases nothing until the bed is done (a job queued meanwhile starts after
// it, on one rank); the completion says how many ranks it ran on.
TEST(WorkerTest, AJobGrantedWithTheQueueDryTakesTheIdleSlotsAsRanks) {
  FakeClient client;
  client.requeue_released = true;
  client.grants = {BedGrant(1, /*queue_dry=*/true)};
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("bed.log")}, {"bed.restart", "new bed bytes"}};
  launcher.runs_for_s = 0.3;
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.launcher = LauncherKind::kMpirun;  // the fake launcher starts nothing: only the command is read
  o.slots = 2;
  o.max_ranks = 2;
  Worker worker(o, client, launcher);
  std::thread run([&] { worker.Run(); });
  ASSERT_TRUE(WaitUntil([&] { return launcher.Started() == 1; }));
  {
    std::lock_guard<std::mutex> l(client.mu);
    client.grants.push_back(BedGrant(2, /*queue_dry=*/false));
  }
  const bool both = WaitUntil([&] {
    std::lock_guard<std::mutex> l(client.mu);
    return client.completions.size() == 2;
  });
  worker.RequestStop();
  run.join();
  ASSERT_TRUE(both);
  ASSERT_EQ(launcher.started.size(), 2u);
  EXPECT_EQ(RanksOf(launcher.started[0]), 2);
  EXPECT_EQ(RanksOf(launcher.started[1]), 1);
  // Open MPI's slots are physical cores; the slots' count may be logical CPUs.
  auto has = [](const LaunchSpec& spec, const std::string& arg) {
    return std::find(spec.argv.begin(), spec.argv.end(), arg) != spec.argv.end();
  };
  EXPECT_TRUE(has(launcher.started[0], "--oversubscribe"));
  EXPECT_FALSE(has(launcher.started[1], "--oversubscribe"));
  EXPECT_EQ(client.completions[0].execution.ranks, 2);
  EXPECT_EQ(client.completions[1].execution.ranks, 1);
  EXPECT_GE(launcher.started_at[1], client.completed_at[0]);  // the lent slot waited for the bed
  EXPECT_EQ(worker.stats().widened, 1);
}

// Without the queue dry, without --max-ranks, or with the direct launcher (one rank by nature), a
// job runs on the worker's ranks even while the other slot idles.
TEST(WorkerTest, AJobRunsOnItsOwnRanksUnlessTheQueueIsDryAndMoreAreAllowed) {
  struct Case {
    bool queue_dry;
    int max_ranks;
    LauncherKind launcher;
  };
  for (const Case& c : {Case{false, 2, LauncherKind::kMpirun}, Case{true, 0, LauncherKind::kMpirun},
                        Case{true, 1, LauncherKind::kMpirun}, Case{true, 2, LauncherKind::kDirect}}) {
    FakeClient client;
    client.grants = {BedGrant(1, c.queue_dry)};
    FakeLauncher launcher;
    launcher.files = {{"log.liggghts", Fixture("bed.log")}, {"bed.restart", "new bed bytes"}};
    WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
    o.launcher = c.launcher;
    o.slots = 2;
    o.max_ranks = c.max_ranks;
    o.exit_when_idle_s = 0.05;
    Worker worker(o, client, launcher);
    worker.Run();
    ASSERT_EQ(launcher.started.size(), 1u);
    EXPECT_EQ(RanksOf(launcher.started[0]), 1) << c.queue_dry << " " << c.max_ranks;
    ASSERT_EQ(client.completions.size(), 1u);
    EXPECT_EQ(client.completions[0].execution.ranks, 1);
    EXPECT_EQ(worker.stats().widened, 0);
  }
}

// Every slot busy: a job granted with the queue dry has no idle slot to take.
TEST(WorkerTest, NoSlotIsTakenFromAJobThatRuns) {
  FakeClient client;
  client.grants = {BedGrant(1, /*queue_dry=*/false), BedGrant(2, /*queue_dry=*/true)};
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("bed.log")}, {"bed.restart", "new bed bytes"}};
  launcher.runs_for_s = 1;  // long enough that both slots have leased before either job ends
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.launcher = LauncherKind::kMpirun;
  o.slots = 2;
  o.max_ranks = 2;
  o.exit_when_idle_s = 0.05;
  Worker worker(o, client, launcher);
  worker.Run();
  ASSERT_EQ(launcher.started.size(), 2u);
  EXPECT_EQ(RanksOf(launcher.started[0]), 1);
  EXPECT_EQ(RanksOf(launcher.started[1]), 1);
  EXPECT_EQ(worker.stats().widened, 0);
}

// A slot's lease on its way holds its core: slot A's lease is slow to come back and slot B gets
// a bed with the queue dry meanwhile; B runs it on its own core only, and A's job, when its
// lease arrives, runs at once on A's core (it was handed back, to wait for all of B's bed, when
// the core was taken only once the lease had come: B started its bed on both cores at once).
TEST(WorkerTest, ALeaseOnItsWayKeepsItsSlotsCore) {
  FakeClient client;
  FakeLauncher launcher;
  client.grants = {BedGrant(2, /*queue_dry=*/true), BedGrant(1, /*queue_dry=*/false)};
  client.before_lease = [&](int n) {
    // A's lease comes back once B's bed started, or after 0.5 s (B now waits for A's lease).
    if (n == 0) WaitUntil([&] { return launcher.Started() >= 1; }, 0.5);
  };
  launcher.files = {{"log.liggghts", Fixture("bed.log")}, {"bed.restart", "new bed bytes"}};
  launcher.runs_for_s = 0.5;
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.launcher = LauncherKind::kMpirun;
  o.slots = 2;
  o.max_ranks = 2;
  o.exit_when_idle_s = 0.05;
  Worker worker(o, client, launcher);
  worker.Run();
  EXPECT_TRUE(client.released.empty());
  ASSERT_EQ(launcher.started.size(), 2u);
  EXPECT_EQ(RanksOf(launcher.started[0]), 1);
  EXPECT_EQ(RanksOf(launcher.started[1]), 1);
  EXPECT_EQ(worker.stats().widened, 0);
  ASSERT_EQ(client.completed_at.size(), 2u);
  EXPECT_LT(launcher.started_at[1], client.completed_at[0]);  // side by side, not one after the other
}

// mpirun refuses the widened job's ranks: the job runs on the worker's own ranks within its
// lease (no failed completion, so no attempt counted; before, it failed, and each retry was
// widened and refused again), the lent slot is free at once, and no later job is widened.
TEST(WorkerTest, AWidenedEngineThatWillNotStartRunsOnTheWorkersOwnRanks) {
  FakeClient client;
  client.grants = {BedGrant(1, /*queue_dry=*/true)};
  FakeLauncher launcher;
  launcher.files = {{"log.liggghts", Fixture("bed.log")}, {"bed.restart", "new bed bytes"}};
  launcher.refuses_above_ranks = 1;
  launcher.runs_for_s = 0.3;
  WorkerOptions o = WorkerOptionsFor(testing::TempDir("worker"));
  o.launcher = LauncherKind::kMpirun;
  o.slots = 2;
  o.max_ranks = 2;
  Worker worker(o, client, launcher);
  std::thread run([&] { worker.Run(); });
  ASSERT_TRUE(WaitUntil([&] { return launcher.Started() == 2; }));
  {
    std::lock_guard<std::mutex> l(client.mu);
    client.grants.push_back(BedGrant(2, /*queue_dry=*/false));  // the other slot's core is free again
  }
  ASSERT_TRUE(WaitUntil([&] {
    std::lock_guard<std::mutex> l(client.mu);
    return client.completions.size() == 2;
  }));
  {
    std::lock_guard<std::mutex> l(client.mu);
    client.grants.push_back(BedGrant(3, /*queue_dry=*/true));  // both slots idle: widened, but for the refusal
  }
  const bool all = WaitUntil([&] {
    std::lock_guard<std::mutex> l(client.mu);
    return client.completions.size() == 3;
  });
  worker.RequestStop();
  run.join();
  ASSERT_TRUE(all);
  ASSERT_EQ(launcher.started.size(), 4u);
  EXPECT_EQ(RanksOf(launcher.started[0]), 2);
  EXPECT_EQ(RanksOf(launcher.started[1]), 1);
  EXPECT_LT(launcher.started_at[2], client.completed_at[0]);  // bed 2 beside bed 1, not after it
  EXPECT_EQ(RanksOf(launcher.started[3]), 1);
  for (const api::Completion& c : client.completions) {
    EXPECT_TRUE(c.ok) << (c.failure ? c.failure->message : "");
    EXPECT_EQ(c.execution.ranks, 1);
  }
  EXPECT_TRUE(client.released.empty());
}

}  // namespace
}  // namespace sandswim::worker
