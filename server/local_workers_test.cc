#include "server/local_workers.h"

#include <signal.h>
#include <sys/wait.h>

#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <utility>

#include <gtest/gtest.h>

#include "platform/fake_subprocesses.h"

namespace sandswim {
namespace {

LocalWorkersOptions Options(int count) {
  LocalWorkersOptions o;
  o.count = count;
  o.argv = {"/bin/sh", "--server", "http://127.0.0.1:1"};
  o.min_backoff_s = 1;
  o.max_backoff_s = 8;
  o.healthy_after_s = 30;
  o.grace_s = 5;
  return o;
}

TEST(LocalWorkersTest, StartsEveryWorkerWithItsCommandLine) {
  FakeClock clock;
  FakeSubprocesses processes(&clock);
  LocalWorkers workers(Options(3), &processes, &clock);
  ASSERT_TRUE(workers.Start().ok());
  EXPECT_EQ(processes.spawned, 3);
  EXPECT_EQ(processes.alive.size(), 3u);
  EXPECT_EQ(processes.last_argv, Options(3).argv);
}

// The daemon's local worker is named "<host>:local-<daemon pid>"; only such a name on this host reads
// as a local worker's (a worker elsewhere, or one named by hand, is not handed back for free).
TEST(LocalWorkersTest, LocalWorkerNames) {
  EXPECT_EQ(LocalWorkerName("vm", 2519), "vm:local-2519");
  EXPECT_TRUE(IsLocalWorkerName(LocalWorkerName("vm", 2519), "vm"));
  EXPECT_FALSE(IsLocalWorkerName("vm:local-2519", "vm2"));
  EXPECT_FALSE(IsLocalWorkerName("node:local-2519", "vm"));
  EXPECT_FALSE(IsLocalWorkerName("vm:2519", "vm"));
  EXPECT_FALSE(IsLocalWorkerName("vm:local-", "vm"));
  EXPECT_FALSE(IsLocalWorkerName("vm:local-25x", "vm"));
  EXPECT_FALSE(HostName().empty());
}

TEST(LocalWorkersTest, RefusesAMissingWorkerBinary) {
  FakeClock clock;
  FakeSubprocesses processes(&clock);
  LocalWorkersOptions o = Options(2);
  o.argv[0] = "/nonexistent/sandswim-worker";
  LocalWorkers workers(o, &processes, &clock);
  Status s = workers.Start();
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(s.field(), "--local-workers");
  EXPECT_EQ(processes.spawned, 0);
}

TEST(LocalWorkersTest, RestartsADeadWorkerAfterADoublingBackoff) {
  FakeClock clock;
  FakeSubprocesses processes(&clock);
  LocalWorkers workers(Options(1), &processes, &clock);
  ASSERT_TRUE(workers.Start().ok());
  pid_t first = workers.pids()[0];

  processes.alive.erase(first);  // dies young
  workers.Tick();
  EXPECT_EQ(workers.pids()[0], 0);
  clock.Advance(0.5);
  workers.Tick();
  EXPECT_EQ(processes.spawned, 1);  // still backing off (1 s)
  clock.Advance(0.6);
  workers.Tick();
  EXPECT_EQ(processes.spawned, 2);
  pid_t second = workers.pids()[0];
  EXPECT_NE(second, first);

  processes.alive.erase(second);  // dies young again: 2 s now
  workers.Tick();
  clock.Advance(1.5);
  workers.Tick();
  EXPECT_EQ(processes.spawned, 2);
  clock.Advance(0.6);
  workers.Tick();
  EXPECT_EQ(processes.spawned, 3);
  EXPECT_EQ(workers.restarts(), 2);

  // One that lived long resets the backoff to 1 s.
  clock.Advance(60);
  processes.alive.erase(workers.pids()[0]);
  workers.Tick();
  clock.Advance(1.1);
  workers.Tick();
  EXPECT_EQ(processes.spawned, 4);
}

TEST(LocalWorkersTest, StopTermsThenKillsAfterTheGrace) {
  FakeClock clock;
  FakeSubprocesses processes(&clock);
  processes.ignore_term = true;
  LocalWorkers workers(Options(2), &processes, &clock);
  ASSERT_TRUE(workers.Start().ok());
  double t0 = clock.Now();
  workers.Stop();
  EXPECT_TRUE(processes.alive.empty());
  EXPECT_GE(clock.Now() - t0, 5.0);
  int terms = 0, kills = 0;
  for (const auto& [pgid, sig] : processes.signals) {
    terms += sig == SIGTERM;
    kills += sig == SIGKILL;
  }
  EXPECT_EQ(terms, 2);
  EXPECT_EQ(kills, 2);
  workers.Tick();  // stopped: never restarts
  EXPECT_EQ(processes.spawned, 2);
}

TEST(LocalWorkersTest, StopIsQuickWhenWorkersObeySigterm) {
  FakeClock clock;
  FakeSubprocesses processes(&clock);
  LocalWorkers workers(Options(2), &processes, &clock);
  ASSERT_TRUE(workers.Start().ok());
  double t0 = clock.Now();
  workers.Stop();
  EXPECT_TRUE(processes.alive.empty());
  EXPECT_LT(clock.Now() - t0, 0.1);
}

// Processes of group `pgid` that are not zombies (a killed grandchild may await its reaper).
int LiveGroupMembers(pid_t pgid) {
  int live = 0;
  for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
    std::ifstream in(entry.path() / "stat");
    std::string stat;
    if (!std::getline(in, stat)) continue;
    size_t paren = stat.rfind(')');
    if (paren == std::string::npos) continue;
    std::istringstream fields(stat.substr(paren + 2));
    char state = 0;
    long ppid = 0, pgrp = 0;
    fields >> state >> ppid >> pgrp;
    if (pgrp == pgid && state != 'Z') ++live;
  }
  return live;
}

// Real processes: each in its own group; one that ignores SIGTERM is killed with its children.
TEST(LocalWorkersPosixTest, StopsRealChildrenIncludingOnesIgnoringSigterm) {
  SystemClock clock;
  PosixSubprocesses processes;
  LocalWorkersOptions o;
  o.count = 2;
  char dir[] = "/tmp/sandswim-workers-XXXXXX";
  ASSERT_NE(mkdtemp(dir), nullptr);
  // Each child says when its trap is set, so the SIGTERM surely meets it.
  o.argv = {"/bin/sh", "-c", std::string("trap '' TERM; sleep 30 & touch ") + dir + "/$$; wait"};
  o.grace_s = 0.3;
  LocalWorkers workers(o, &processes, &clock);
  ASSERT_TRUE(workers.Start().ok());
  std::vector<pid_t> pids = workers.pids();
  for (pid_t pid : pids) {
    std::string ready = std::string(dir) + "/" + std::to_string(pid);
    for (int i = 0; i < 500 && !std::filesystem::exists(ready); ++i) usleep(2000);
    ASSERT_TRUE(std::filesystem::exists(ready));
  }
  auto t0 = std::chrono::steady_clock::now();
  for (pid_t pid : pids) {
    ASSERT_GT(pid, 0);
    EXPECT_EQ(getpgid(pid), pid);
  }
  workers.Stop();
  EXPECT_GE(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(250));  // waited the grace
  std::filesystem::remove_all(dir);
  for (pid_t pid : pids) {
    EXPECT_EQ(kill(pid, 0), -1);  // reaped and gone
    // SIGKILL is delivered at once but a grandchild takes a moment to exit: allow it 2 s.
    int live = LiveGroupMembers(pid);
    for (int i = 0; i < 200 && live > 0; ++i) {
      usleep(10000);
      live = LiveGroupMembers(pid);
    }
    EXPECT_EQ(live, 0);  // and nothing left alive in its group
  }
}

}  // namespace
}  // namespace sandswim
