#include "platform/process_cpu.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <thread>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

// A child in a process group of its own running `script` under /bin/sh.
pid_t StartGroup(const char* script) {
  pid_t pid = fork();
  if (pid == 0) {
    setpgid(0, 0);
    execl("/bin/sh", "sh", "-c", script, static_cast<char*>(nullptr));
    _exit(127);
  }
  setpgid(pid, pid);  // either side may win the race; both set the same group
  return pid;
}

void EndGroup(pid_t pgid) {
  kill(-pgid, SIGKILL);
  waitpid(pgid, nullptr, 0);
}

// The spinning process is a grandchild in a session (and group) of its own, as mpirun's ranks
// are: the tree still counts it. (It spins at most 3 s, as the test ends only its parent.)
TEST(ProcessCpuTest, ASpinningDescendantIsRunnableAndUsesCpu) {
  pid_t pgid = StartGroup("setsid timeout 3 sh -c 'while :; do :; done' & wait");
  bool runnable = false;
  std::optional<TreeCpu> cpu;
  for (int i = 0; i < 300 && !(runnable && cpu && cpu->cpu_s > 0.05); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    cpu = ReadProcessTreeCpu(pgid);
    if (cpu && cpu->runnable) runnable = true;
  }
  EndGroup(pgid);
  ASSERT_TRUE(cpu.has_value());
  EXPECT_GE(cpu->processes, 3);  // sh, timeout, the spinning sh
  EXPECT_TRUE(runnable);
  EXPECT_GT(cpu->cpu_s, 0.05);
}

TEST(ProcessCpuTest, ASleepingGroupIsNotRunnable) {
  pid_t pgid = StartGroup("sleep 30");
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // past exec
  std::optional<TreeCpu> cpu = ReadProcessTreeCpu(pgid);
  EndGroup(pgid);
  ASSERT_TRUE(cpu.has_value());
  EXPECT_FALSE(cpu->runnable);
  EXPECT_LT(cpu->cpu_s, 0.5);
}

TEST(ProcessCpuTest, NoGroupHereIsNothing) {
  EXPECT_FALSE(ReadProcessTreeCpu(0).has_value());
  pid_t pgid = StartGroup("exit 0");
  waitpid(pgid, nullptr, 0);
  EXPECT_FALSE(ReadProcessTreeCpu(pgid).has_value());
}

}  // namespace
}  // namespace sandswim
