#include "workers/launcher.h"
#include "tests/fixture_file.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <thread>

#include <gtest/gtest.h>

namespace sandswim::worker {
namespace {

using SteadyClock = std::chrono::steady_clock;

LaunchSpec Sh(const std::string& script, const std::string& cwd = "") {
  LaunchSpec spec;
  spec.argv = {"/bin/sh", "-c", script};
  spec.cwd = cwd;
  return spec;
}

// The tests that hold for both ways of starting an engine: through the guard (mpirun, srun) and
// straight from the worker (single_process: a direct engine).
class LauncherModes : public ::testing::TestWithParam<bool> {
 protected:
  LaunchSpec Mode(LaunchSpec spec) const {
    spec.single_process = GetParam();
    return spec;
  }
};
INSTANTIATE_TEST_SUITE_P(GuardedAndSingle, LauncherModes, ::testing::Bool(),
                         [](const auto& info) { return info.param ? "SingleProcess" : "Guarded"; });

TEST_P(LauncherModes, ExitStatusAndOutputFile) {
  const std::string dir = testing::TempDir("launcher");
  LaunchSpec spec = Sh("echo hello from $SANDSWIM_TEST_VAR; pwd; exit 3", dir);
  spec.env = {{"SANDSWIM_TEST_VAR", "the child"}};
  spec.output_file = "out.txt";
  GuardedLauncher launcher;
  auto proc = launcher.Start(Mode(spec));
  ASSERT_TRUE(proc.ok()) << proc.status().ToString();
  ASSERT_TRUE((*proc)->WaitFor(10));
  EXPECT_EQ((*proc)->exit_status().exit_code, 3);
  EXPECT_EQ((*proc)->exit_status().signal, 0);
  std::ifstream in(dir + "/out.txt");
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), "hello from the child\n" + dir + "\n");
}

TEST_P(LauncherModes, WaitForZeroDoesNotBlock) {
  GuardedLauncher launcher;
  auto proc = launcher.Start(Mode(Sh("sleep 30")));
  ASSERT_TRUE(proc.ok());
  EXPECT_FALSE((*proc)->WaitFor(0));
  EXPECT_FALSE((*proc)->WaitFor(0.05));
  (*proc)->Stop(5);
}

TEST(LauncherTest, StopEndsTheWholeGroupWithinTheGrace) {
  const std::string dir = testing::TempDir("launcher");
  GuardedLauncher launcher;
  // The shell's child `sleep` writes its pid; Stop() must end it too (it is in the group).
  auto proc = launcher.Start(Sh("sleep 30 & echo $! > sleep.pid; wait", dir));
  ASSERT_TRUE(proc.ok());
  pid_t sleeper = 0;
  for (int i = 0; i < 200 && sleeper == 0; ++i) {
    std::ifstream in(dir + "/sleep.pid");
    in >> sleeper;
    if (sleeper == 0) usleep(10000);
  }
  ASSERT_GT(sleeper, 0);
  const auto t0 = SteadyClock::now();
  (*proc)->Stop(5);
  EXPECT_LT(std::chrono::duration<double>(SteadyClock::now() - t0).count(), 4.0);
  EXPECT_EQ((*proc)->exit_status().signal, SIGTERM);
  // The grandchild got SIGTERM too (it may linger a moment as a zombie of init).
  bool gone = false;
  for (int i = 0; i < 200 && !gone; ++i) {
    std::ifstream stat("/proc/" + std::to_string(sleeper) + "/stat");
    std::string s;
    std::getline(stat, s);
    gone = s.empty() || s.find(") Z") != std::string::npos;
    if (!gone) usleep(10000);
  }
  EXPECT_TRUE(gone);
}

TEST_P(LauncherModes, ProcessIgnoringSigtermGetsSigkill) {
  const std::string dir = testing::TempDir("launcher");
  GuardedLauncher launcher;
  auto proc = launcher.Start(Mode(Sh("trap '' TERM; touch ready; while :; do sleep 0.05; done", dir)));
  ASSERT_TRUE(proc.ok());
  for (int i = 0; i < 200 && access((dir + "/ready").c_str(), F_OK) != 0; ++i) usleep(10000);
  const auto t0 = SteadyClock::now();
  (*proc)->Stop(0.3);
  const double took = std::chrono::duration<double>(SteadyClock::now() - t0).count();
  EXPECT_EQ((*proc)->exit_status().signal, SIGKILL);
  EXPECT_GE(took, 0.29);
  EXPECT_LT(took, 3.0);
}

TEST_P(LauncherModes, MissingCommandIsUnavailable) {
  GuardedLauncher launcher;
  LaunchSpec spec;
  spec.argv = {"sandswim-no-such-engine-here"};
  auto proc = launcher.Start(Mode(spec));
  ASSERT_FALSE(proc.ok());
  EXPECT_EQ(proc.status().code(), StatusCode::kUnavailable);
  EXPECT_NE(proc.status().reason().find("sandswim-no-such-engine-here"), std::string::npos);
}

TEST_P(LauncherModes, BadWorkingDirectoryIsUnavailable) {
  GuardedLauncher launcher;
  auto proc = launcher.Start(Mode(Sh("true", "/nonexistent/sandswim/dir")));
  ASSERT_FALSE(proc.ok());
  EXPECT_NE(proc.status().reason().find("/nonexistent/sandswim/dir"), std::string::npos) << proc.status().reason();
}

TEST_P(LauncherModes, CpuTimeIsCounted) {
  GuardedLauncher launcher;
  auto proc = launcher.Start(Mode(Sh("i=0; while [ $i -lt 200000 ]; do i=$((i+1)); done")));
  ASSERT_TRUE(proc.ok());
  ASSERT_TRUE((*proc)->WaitFor(30));
  EXPECT_GT((*proc)->exit_status().cpu_s, 0.01);
  EXPECT_GT((*proc)->exit_status().wall_s, 0.01);
}

TEST(LauncherTest, EngineCommands) {
  LaunchSpec m = EngineCommand(LauncherKind::kMpirun, 2, "liggghts", "drive.in", "log.liggghts", "/d", true);
  EXPECT_EQ(m.argv, (std::vector<std::string>{"mpirun", "-np", "2", "--bind-to", "none", "liggghts", "-in", "drive.in",
                                              "-log", "log.liggghts", "-screen", "/dev/null"}));
  EXPECT_FALSE(m.single_process);  // mpirun starts ranks: it needs its guard
  EXPECT_EQ(m.env.size(), 2u);
  EXPECT_EQ(m.cwd, "/d");
  EXPECT_TRUE(EngineCommand(LauncherKind::kMpirun, 1, "liggghts", "a", "b", "/d", false).env.empty());
  // A job widened onto idle slots' cores may ask for more ranks than Open MPI's slots (physical cores).
  const std::vector<std::string> widened =
      EngineCommand(LauncherKind::kMpirun, 4, "liggghts", "a", "b", "/d", false, /*widened=*/true).argv;
  EXPECT_EQ(std::vector<std::string>(widened.begin(), widened.begin() + 6),
            (std::vector<std::string>{"mpirun", "-np", "4", "--bind-to", "none", "--oversubscribe"}));
  EXPECT_EQ(std::count(m.argv.begin(), m.argv.end(), "--oversubscribe"), 0);
  LaunchSpec s = EngineCommand(LauncherKind::kSrun, 4, "liggghts", "bed.in", "log.liggghts", "/d", false);
  EXPECT_EQ(s.argv, (std::vector<std::string>{"srun", "--mpi=pmix", "-n", "4", "--exclusive", "liggghts", "-in",
                                              "bed.in", "-log", "log.liggghts", "-screen", "/dev/null"}));
  LaunchSpec d = EngineCommand(LauncherKind::kDirect, 1, "/opt/liggghts", "x.in", "log", "/d", true);
  EXPECT_TRUE(d.single_process);
  EXPECT_EQ(d.argv, (std::vector<std::string>{"/opt/liggghts", "-in", "x.in", "-log", "log", "-screen", "/dev/null"}));
}

// True while `pid` runs (a zombie waiting for its reaper counts as dead).
bool Alive(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return false;
  size_t close_paren = line.rfind(')');
  return close_paren != std::string::npos && close_paren + 2 < line.size() && line[close_paren + 2] != 'Z';
}

pid_t ReadPid(const std::string& path) {
  std::ifstream in(path);
  pid_t pid = 0;
  in >> pid;
  return pid;
}

// The engine inherits none of the worker's descriptors (sockets, other engines' pipes), nor a
// signal the worker ignores or blocks: a worker that ignores SIGTERM still stops its engine with
// SIGTERM, not only after the grace with SIGKILL.
TEST_P(LauncherModes, EngineInheritsNoDescriptorsAndNoIgnoredOrBlockedSignals) {
  const std::string dir = testing::TempDir("launcher");
  int leak[2];
  ASSERT_EQ(pipe(leak), 0);  // not close-on-exec
  struct sigaction ignore {
  }, old_term{};
  ignore.sa_handler = SIG_IGN;
  ASSERT_EQ(sigaction(SIGTERM, &ignore, &old_term), 0);
  sigset_t block, old_mask;
  sigemptyset(&block);
  sigaddset(&block, SIGINT);
  pthread_sigmask(SIG_BLOCK, &block, &old_mask);
  GuardedLauncher launcher;
  LaunchSpec fds = Sh("exec ls /proc/self/fd", dir);
  fds.output_file = "fds.txt";
  auto listed = launcher.Start(Mode(fds));
  auto sleeper = launcher.Start(Mode(Sh("touch ready; exec sleep 30", dir)));
  sigaction(SIGTERM, &old_term, nullptr);
  pthread_sigmask(SIG_SETMASK, &old_mask, nullptr);
  close(leak[0]);
  close(leak[1]);
  ASSERT_TRUE(listed.ok() && sleeper.ok());
  ASSERT_TRUE((*listed)->WaitFor(10));
  std::ifstream in(dir + "/fds.txt");
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), "0\n1\n2\n3\n");  // ls's own: stdio and the directory it reads
  for (int i = 0; i < 500 && access((dir + "/ready").c_str(), F_OK) != 0; ++i) usleep(10000);
  (*sleeper)->Stop(5);
  EXPECT_EQ((*sleeper)->exit_status().signal, SIGTERM);
  // sh -c 'exec sleep' with SIGINT blocked would not die of it; unblocked, it does.
  auto interrupted = launcher.Start(Mode(Sh("touch ready2; exec sleep 30", dir)));
  ASSERT_TRUE(interrupted.ok());
  for (int i = 0; i < 500 && access((dir + "/ready2").c_str(), F_OK) != 0; ++i) usleep(10000);
  kill(-(*interrupted)->pid(), SIGINT);
  ASSERT_TRUE((*interrupted)->WaitFor(5));
  EXPECT_EQ((*interrupted)->exit_status().signal, SIGINT);
}

// A single-process engine has no guard: it dies with a worker killed by SIGKILL all by itself.
TEST(LauncherTest, SingleProcessEngineDiesWithAWorkerKilledBySigkill) {
  const std::string dir = testing::TempDir("launcher");
  pid_t worker = fork();
  ASSERT_GE(worker, 0);
  if (worker == 0) {
    GuardedLauncher launcher;
    LaunchSpec spec = Sh("echo $$ > engine.tmp && mv engine.tmp engine.pid && exec sleep 300", dir);
    spec.single_process = true;
    auto proc = launcher.Start(spec);
    if (!proc.ok()) _exit(1);
    while (true) pause();
  }
  pid_t engine = 0;
  const auto deadline = SteadyClock::now() + std::chrono::seconds(20);
  while ((engine = ReadPid(dir + "/engine.pid")) == 0 && SteadyClock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (engine <= 0) {
    kill(worker, SIGKILL);
    waitpid(worker, nullptr, 0);
    FAIL() << "the engine did not start";
  }
  EXPECT_TRUE(Alive(engine));
  EXPECT_EQ(getpgid(engine), engine);  // the leader of its own group
  kill(worker, SIGKILL);
  ASSERT_EQ(waitpid(worker, nullptr, 0), worker);
  const auto gone_by = SteadyClock::now() + std::chrono::seconds(10);
  while (Alive(engine) && SteadyClock::now() < gone_by) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  EXPECT_FALSE(Alive(engine)) << "the engine outlived its worker";
  if (Alive(engine)) kill(engine, SIGKILL);
}

// A worker killed with SIGKILL takes its engine with it: the engine (here a shell) and the
// "rank" it started in the background, as mpirun's ranks, are gone soon after.
TEST(LauncherTest, EngineDiesWithAWorkerKilledBySigkill) {
  const std::string dir = testing::TempDir("launcher");
  pid_t worker = fork();
  ASSERT_GE(worker, 0);
  if (worker == 0) {
    // The worker-like parent: starts the engine, then waits to be killed.
    GuardedLauncher launcher;
    // engine.pid is complete before rank.pid appears (renamed into place).
    auto proc =
        launcher.Start(Sh("echo $$ > engine.pid; sleep 300 & echo $! > rank.tmp && "
                          "mv rank.tmp rank.pid; wait",
                          dir));
    if (!proc.ok()) _exit(1);
    while (true) pause();
  }
  // Whatever happens below, nothing this test started outlives it (the paused parent would
  // also hold the test's stdout open).
  pid_t rank = 0, engine = 0;
  bool reaped = false;
  struct Cleanup {
    std::function<void()> f;
    ~Cleanup() { f(); }
  } cleanup{[&] {
    if (!reaped) {
      kill(worker, SIGKILL);
      waitpid(worker, nullptr, 0);
    }
    if (rank > 0 && Alive(rank)) kill(rank, SIGKILL);
    if (engine > 0 && Alive(engine)) kill(engine, SIGKILL);
  }};
  // Wait (bounded) for the engine to have started its rank.
  const auto deadline = SteadyClock::now() + std::chrono::seconds(20);
  while (ReadPid(dir + "/rank.pid") == 0 && SteadyClock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  rank = ReadPid(dir + "/rank.pid");
  engine = ReadPid(dir + "/engine.pid");
  ASSERT_GT(rank, 0) << "the engine did not start";
  ASSERT_GT(engine, 0);
  EXPECT_TRUE(Alive(rank));
  EXPECT_TRUE(Alive(engine));

  kill(worker, SIGKILL);
  int st = 0;
  ASSERT_EQ(waitpid(worker, &st, 0), worker);
  reaped = true;
  ASSERT_TRUE(WIFSIGNALED(st) && WTERMSIG(st) == SIGKILL);
  const auto gone_by = SteadyClock::now() + std::chrono::seconds(10);
  while ((Alive(rank) || Alive(engine)) && SteadyClock::now() < gone_by) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  EXPECT_FALSE(Alive(engine)) << "the engine outlived its worker";
  EXPECT_FALSE(Alive(rank)) << "the engine's rank outlived its worker";
}

// The guard passes the engine's way of ending on: a signal reads as that signal.
TEST_P(LauncherModes, EngineKilledBySignalReadsAsThatSignal) {
  GuardedLauncher launcher;
  auto proc = launcher.Start(Mode(Sh("kill -SEGV $$")));
  ASSERT_TRUE(proc.ok());
  ASSERT_TRUE((*proc)->WaitFor(10));
  EXPECT_EQ((*proc)->exit_status().signal, SIGSEGV);
}

}  // namespace
}  // namespace sandswim::worker
