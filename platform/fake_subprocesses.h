// FakeSubprocesses: a Subprocesses for tests (platform/subprocess.h), on a FakeClock.
//
// Run answers from `outputs` by argv[0] (kUnavailable for a program it does not know) and records
// every call. Spawned children live until a signal kills them: SIGKILL always, SIGTERM unless
// `ignore_term`; Pause advances the clock instead of sleeping.
//
// Thread safety: none; one test thread drives it.
#ifndef SANDSWIM_PLATFORM_FAKE_SUBPROCESSES_H_
#define SANDSWIM_PLATFORM_FAKE_SUBPROCESSES_H_

#include <signal.h>

#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "platform/clock.h"
#include "platform/subprocess.h"

namespace sandswim {

class FakeSubprocesses : public Subprocesses {
 public:
  explicit FakeSubprocesses(FakeClock* clock) : clock_(clock) {}

  Result<CommandOutput> Run(const std::vector<std::string>& argv, const EnvVars& env, double timeout_s) override {
    runs.push_back({argv, env, timeout_s});
    auto it = argv.empty() ? outputs.end() : outputs.find(argv[0]);
    if (it == outputs.end()) return Status::Unavailable("cannot run '" + (argv.empty() ? "" : argv[0]) + "'");
    return it->second;
  }
  Result<pid_t> Spawn(const std::vector<std::string>& argv) override {
    last_argv = argv;
    const pid_t pid = next_pid_++;
    alive.insert(pid);
    ++spawned;
    return pid;
  }
  std::optional<int> Reap(pid_t pid) override {
    if (alive.count(pid)) return std::nullopt;
    return 0;
  }
  void SignalGroup(pid_t pgid, int signal) override {
    signals.emplace_back(pgid, signal);
    if (signal == SIGKILL || (signal == SIGTERM && !ignore_term)) alive.erase(pgid);
  }
  void Pause(double seconds) override { clock_->Advance(seconds); }

  struct RunCall {
    std::vector<std::string> argv;
    EnvVars env;
    double timeout_s = 0;
  };
  std::map<std::string, CommandOutput> outputs;  // by argv[0]
  std::vector<RunCall> runs;
  std::set<pid_t> alive;
  std::vector<std::pair<pid_t, int>> signals;
  std::vector<std::string> last_argv;
  int spawned = 0;
  bool ignore_term = false;

 private:
  FakeClock* clock_;
  pid_t next_pid_ = 100;
};

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_FAKE_SUBPROCESSES_H_
