// The worker inside a Slurm allocation: it stops leasing before the allocation ends, and a stop
// (Slurm's USR1, scancel's TERM) hands running jobs back to the daemon instead of abandoning them.
#include <signal.h>
#include <stdlib.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include <gtest/gtest.h>

#include "core/keys.h"
#include "core/trajectory.h"
#include "tests/fixture_file.h"
#include "workers/worker.h"

namespace sandswim::worker {
namespace {

using testing::Fixture;  // tests/fixture_file.h

constexpr char kBed[] = "bed bytes";

// A daemon with an endless queue of runs.
class QueueClient : public ServerClient {
 public:
  std::mutex mu;
  int leases = 0;
  std::vector<std::string> released;  // tokens
  std::vector<std::string> completed;
  std::atomic<bool> leased{false};
  std::condition_variable leased_cv;  // notified on every lease

  Result<std::optional<api::LeaseGrant>> Lease(const api::LeaseRequest&) override {
    std::lock_guard<std::mutex> l(mu);
    api::LeaseGrant g;
    g.token = "tok-" + std::to_string(++leases);
    g.kind = api::JobKind::kRun;
    g.id = leases;
    g.deck = Fixture("drive_omega_minus80.in");
    g.steps = 30000;
    g.duration_s = 0.3;
    g.bed = api::BedRef{1, Sha256Hex(kBed), "/api/v1/beds/1/restart"};
    // What the daemon's lease carries besides the deck: the numbers the deck states.
    auto drive = ReadDriveInfo(g.deck);
    g.dt_s = drive.ok() ? drive->dt : 0;
    g.f_hz = drive.ok() ? drive->f : 0;
    g.A_m = drive.ok() ? drive->A : 0;
    g.z_floor_m = drive.ok() ? drive->z_floor : std::nullopt;
    leased = true;
    leased_cv.notify_all();
    return std::optional<api::LeaseGrant>(g);
  }
  Result<api::HeartbeatReply> Heartbeat(const std::string&, const api::Heartbeat&) override {
    return api::HeartbeatReply{};
  }
  Status DownloadBed(const api::BedRef&, const std::string& dest) override {
    std::ofstream(dest, std::ios::binary) << kBed;
    return Status::Ok();
  }
  Status UploadBed(int64_t, const std::string&, const std::string&, const std::string&) override {
    return Status::Ok();
  }
  Result<api::CompletionReply> Complete(const std::string& token, const api::Completion&) override {
    std::lock_guard<std::mutex> l(mu);
    completed.push_back(token);
    return api::CompletionReply{"done"};
  }
  Result<api::CompletionReply> Release(const std::string& token, const std::string&) override {
    std::lock_guard<std::mutex> l(mu);
    released.push_back(token);
    return api::CompletionReply{"queued"};
  }
};

// An engine that runs until stopped, then reports death by SIGTERM.
class EndlessProcess : public EngineProcess {
 public:
  pid_t pid() const override { return 0; }
  bool WaitFor(double seconds) override {
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(seconds, 0.005)));
    return !running_;
  }
  void Stop(double) override { running_ = false; }
  ExitStatus exit_status() const override {
    ExitStatus s;
    s.signal = SIGTERM;
    return s;
  }

 private:
  std::atomic<bool> running_{true};
};

class EndlessLauncher : public Launcher {
 public:
  Result<std::unique_ptr<EngineProcess>> Start(const LaunchSpec&) override {
    return std::unique_ptr<EngineProcess>(std::make_unique<EndlessProcess>());
  }
};

WorkerOptions Options() {
  WorkerOptions o;
  o.name = "slurm-1";
  o.host = "node1";
  o.workdir = testing::TempDir("alloc");
  o.heartbeat_every_s = 0.01;
  o.stop_grace_s = 0.01;
  o.idle_poll_s = 0.01;
  o.launcher = LauncherKind::kSrun;
  o.end_margin_s = 300;
  return o;
}

TEST(WorkerAllocationTest, NoLeaseWhenTheAllocationEndsBeforeARunWouldFinish) {
  QueueClient client;
  EndlessLauncher launcher;
  WorkerOptions o = Options();
  int asked = 0;
  o.allocation_seconds_left = [&asked]() -> Result<std::optional<double>> {
    ++asked;
    return std::optional<double>(120);  // under the 300 s margin
  };
  Worker worker(o, client, launcher);
  worker.Run();  // returns: every slot stopped leasing
  EXPECT_EQ(client.leases, 0);
  EXPECT_GE(asked, 1);
  EXPECT_TRUE(worker.stats().allocation_ending);
}

// Waits for the worker's first lease, at most `limit`: a worker that never leases fails the test
// (and is stopped by it) instead of hanging it.
bool LeasedWithin(QueueClient& client, std::chrono::milliseconds limit) {
  std::unique_lock<std::mutex> l(client.mu);
  return client.leased_cv.wait_for(l, limit, [&] { return client.leased.load(); });
}

TEST(WorkerAllocationTest, LeasesWhileTheAllocationHasRoom) {
  QueueClient client;
  EndlessLauncher launcher;
  WorkerOptions o = Options();
  o.allocation_seconds_left = []() -> Result<std::optional<double>> { return std::optional<double>(3600); };
  Worker worker(o, client, launcher);
  std::thread run([&] { worker.Run(); });
  EXPECT_TRUE(LeasedWithin(client, std::chrono::seconds(10)));
  worker.RequestStop();
  run.join();
  EXPECT_EQ(client.leases, 1);
  EXPECT_FALSE(worker.stats().allocation_ending);
}

TEST(WorkerAllocationTest, SlurmNotAnsweringDoesNotIdleTheAllocation) {
  QueueClient client;
  EndlessLauncher launcher;
  WorkerOptions o = Options();
  o.allocation_seconds_left = []() -> Result<std::optional<double>> { return Status::Unavailable("slurmctld down"); };
  Worker worker(o, client, launcher);
  std::thread run([&] { worker.Run(); });
  EXPECT_TRUE(LeasedWithin(client, std::chrono::seconds(10)));
  worker.RequestStop();
  run.join();
  EXPECT_EQ(client.leases, 1);
}

TEST(WorkerAllocationTest, StopHandsTheRunningJobBack) {
  QueueClient client;
  EndlessLauncher launcher;
  Worker worker(Options(), client, launcher);
  std::thread run([&] { worker.Run(); });
  EXPECT_TRUE(LeasedWithin(client, std::chrono::seconds(10)));
  worker.RequestStop();
  run.join();
  ASSERT_EQ(client.released.size(), 1u);
  EXPECT_EQ(client.released[0], "tok-1");
  EXPECT_TRUE(client.completed.empty());
  EXPECT_EQ(worker.stats().released, 1);
  EXPECT_EQ(worker.stats().abandoned, 0);
}

}  // namespace
}  // namespace sandswim::worker
