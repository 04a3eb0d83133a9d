#include "platform/subprocess.h"

#include <pthread.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

TEST(SubprocessesTest, RunCapturesBothStreamsTheExitCodeAndTheAddedEnvironment) {
  PosixSubprocesses processes;
  auto r = processes.Run({"sh", "-c", "echo out; echo err >&2; echo $SANDSWIM_X; exit 3"}, {{"SANDSWIM_X", "y"}}, 10);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->exit_code, 3);
  EXPECT_EQ(r->out, "out\ny\n");
  EXPECT_EQ(r->err, "err\n");
  EXPECT_FALSE(r->timed_out);
}

// More than a pipe holds on both streams at once: drained together, nothing blocks.
TEST(SubprocessesTest, RunDrainsLargeOutputOnBothStreams) {
  PosixSubprocesses processes;
  auto r = processes.Run({"sh", "-c", "head -c 300000 /dev/zero; head -c 200000 /dev/zero >&2"}, {}, 30);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->exit_code, 0);
  EXPECT_EQ(r->out.size(), 300000u);
  EXPECT_EQ(r->err.size(), 200000u);
}

TEST(SubprocessesTest, RunKillsACommandAtItsDeadlineAndKeepsWhatItPrinted) {
  PosixSubprocesses processes;
  auto r = processes.Run({"sh", "-c", "echo started; exec sleep 30"}, {}, 0.3);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->timed_out);
  EXPECT_EQ(r->out, "started\n");
  EXPECT_EQ(r->exit_code, 128 + SIGKILL);
}

TEST(SubprocessesTest, AMissingProgramIsUnavailableAndNamed) {
  PosixSubprocesses processes;
  auto r = processes.Run({"sandswim-no-such-program"}, {}, 5);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kUnavailable);
  EXPECT_NE(r.status().reason().find("sandswim-no-such-program"), std::string::npos);
  EXPECT_EQ(processes.Spawn({"/nonexistent/sandswim-worker"}).status().code(), StatusCode::kUnavailable);
}

TEST(SubprocessesTest, ASpawnedChildLeadsItsGroupAndDiesWithIt) {
  PosixSubprocesses processes;
  // The daemon blocks SIGTERM in its threads (to sigwait for it): the child must not inherit that.
  sigset_t term, old;
  sigemptyset(&term);
  sigaddset(&term, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &term, &old);
  auto pid = processes.Spawn({"/bin/sleep", "30"});
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  ASSERT_TRUE(pid.ok()) << pid.status().ToString();
  EXPECT_EQ(getpgid(*pid), *pid);
  EXPECT_FALSE(processes.Reap(*pid).has_value());
  processes.SignalGroup(*pid, SIGTERM);
  std::optional<int> status;
  while (!(status = processes.Reap(*pid))) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  ASSERT_TRUE(WIFSIGNALED(*status));
  EXPECT_EQ(WTERMSIG(*status), SIGTERM);
}

}  // namespace
}  // namespace sandswim
