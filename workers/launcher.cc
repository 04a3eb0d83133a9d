#include "workers/launcher.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <cstring>
#include <thread>

extern char** environ;

namespace sandswim::worker {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

// argv[0] resolved on PATH in the parent, so the child only calls async-signal-safe functions.
std::string FindOnPath(const std::string& name) {
  if (name.find('/') != std::string::npos) return access(name.c_str(), X_OK) == 0 ? name : "";
  const char* path = getenv("PATH");
  std::string p = path ? path : "/usr/local/bin:/usr/bin:/bin";
  size_t start = 0;
  while (start <= p.size()) {
    size_t end = p.find(':', start);
    if (end == std::string::npos) end = p.size();
    std::string dir = p.substr(start, end - start);
    if (dir.empty()) dir = ".";
    std::string candidate = dir + "/" + name;
    struct stat st;
    if (stat(candidate.c_str(), &st) == 0 && S_ISREG(st.st_mode) && access(candidate.c_str(), X_OK) == 0) {
      return candidate;
    }
    start = end + 1;
  }
  return "";
}

class ChildProcess : public EngineProcess {
 public:
  ChildProcess(pid_t pid, int pidfd) : pid_(pid), pidfd_(pidfd), start_(Clock::now()) {}
  pid_t pid() const override { return pid_; }
  ~ChildProcess() override {
    if (!reaped_) Stop(0.0);
    if (pidfd_ >= 0) close(pidfd_);
  }

  bool WaitFor(double seconds) override {
    if (reaped_) return true;
    if (TryReap()) return true;
    if (seconds <= 0) return false;
    const auto deadline = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
    if (pidfd_ >= 0) {
      // The pidfd becomes readable when the child exits: no polling delay, no busy loop.
      while (true) {
        double left = Seconds(deadline - Clock::now());
        if (left <= 0) return TryReap();
        struct pollfd p{pidfd_, POLLIN, 0};
        int rc = poll(&p, 1, static_cast<int>(std::ceil(left * 1000)));
        if (rc < 0 && errno == EINTR) continue;
        return TryReap();
      }
    }
    // Without pidfd (old kernels): poll with growing sleeps.
    auto nap = std::chrono::microseconds(500);
    while (!TryReap()) {
      if (Clock::now() >= deadline) return false;
      std::this_thread::sleep_for(std::min<Clock::duration>(nap, deadline - Clock::now()));
      nap = std::min(nap * 2, std::chrono::microseconds(50000));
    }
    return true;
  }

  void Stop(double grace_s) override {
    if (reaped_) return;
    kill(-pid_, SIGTERM);
    if (WaitFor(grace_s)) return;
    kill(-pid_, SIGKILL);
    while (!WaitFor(1.0)) {
    }
  }

  ExitStatus exit_status() const override { return status_; }

 private:
  bool TryReap() {
    if (reaped_) return true;
    int st = 0;
    struct rusage ru;
    std::memset(&ru, 0, sizeof(ru));
    pid_t r;
    do {
      r = wait4(pid_, &st, WNOHANG, &ru);
    } while (r < 0 && errno == EINTR);
    if (r == 0) return false;
    reaped_ = true;
    status_.wall_s = Seconds(Clock::now() - start_);
    if (r < 0) {  // somebody else reaped it (should not happen): report what we know
      status_.exit_code = -1;
      return true;
    }
    if (WIFEXITED(st)) status_.exit_code = WEXITSTATUS(st);
    if (WIFSIGNALED(st)) status_.signal = WTERMSIG(st);
    status_.cpu_s = ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
    return true;
  }

  pid_t pid_;
  int pidfd_;
  Clock::time_point start_;
  bool reaped_ = false;
  ExitStatus status_;
};

}  // namespace

const char* LauncherName(LauncherKind kind) {
  switch (kind) {
    case LauncherKind::kMpirun: return "mpirun";
    case LauncherKind::kSrun: return "srun";
    case LauncherKind::kDirect: return "direct";
  }
  return "?";
}

LaunchSpec EngineCommand(LauncherKind kind, int ranks, const std::string& engine, const std::string& deck_file,
                         const std::string& log_file, const std::string& cwd, bool as_root) {
  LaunchSpec spec;
  spec.cwd = cwd;
  spec.output_file = "engine.out";
  const std::string r = std::to_string(ranks);
  switch (kind) {
    case LauncherKind::kMpirun:
      spec.argv = {"mpirun", "-np", r, "--bind-to", "none"};
      if (as_root) {
        spec.env = {{"OMPI_ALLOW_RUN_AS_ROOT", "1"}, {"OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1"}};
      }
      break;
    case LauncherKind::kSrun:
      spec.argv = {"srun", "--mpi=pmix", "-n", r};
      break;
    case LauncherKind::kDirect:
      break;
  }
  spec.argv.push_back(engine);
  for (const std::string& a : {std::string("-in"), deck_file, std::string("-log"), log_file,
                               std::string("-screen"), std::string("/dev/null")}) {
    spec.argv.push_back(a);
  }
  return spec;
}

Result<std::unique_ptr<EngineProcess>> ProcessLauncher::Start(const LaunchSpec& spec) {
  if (spec.argv.empty()) return Status::InvalidArgument("argv", "empty command");
  const std::string exe = FindOnPath(spec.argv[0]);
  if (exe.empty()) return Status::Unavailable("'" + spec.argv[0] + "' not found on PATH or not executable");

  // Everything the child needs is built before it is spawned.
  std::vector<std::string> env_strings;
  for (char** e = environ; *e != nullptr; ++e) {
    std::string kv = *e;
    std::string key = kv.substr(0, kv.find('='));
    bool overridden = std::any_of(spec.env.begin(), spec.env.end(), [&](const auto& p) { return p.first == key; });
    if (!overridden) env_strings.push_back(std::move(kv));
  }
  for (const auto& [k, v] : spec.env) env_strings.push_back(k + "=" + v);
  std::vector<char*> envp;
  for (auto& s : env_strings) envp.push_back(s.data());
  envp.push_back(nullptr);
  std::vector<std::string> args = spec.argv;
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const std::string out = spec.output_file.empty() ? "/dev/null" : spec.output_file;

  // posix_spawn (vfork-like, no page-table copy) is several times cheaper than fork() here, and
  // reports a failed chdir/open/exec as its return value. The child gets its own process group,
  // an empty signal mask and default handlers for the signals the worker handles.
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!spec.cwd.empty()) posix_spawn_file_actions_addchdir_np(&actions, spec.cwd.c_str());
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP | POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  posix_spawnattr_setpgroup(&attr, 0);
  sigset_t none, defaults;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  sigemptyset(&defaults);
  for (int sig : {SIGTERM, SIGINT, SIGHUP, SIGPIPE, SIGCHLD}) sigaddset(&defaults, sig);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  pid_t pid = 0;
  int rc = posix_spawn(&pid, exe.c_str(), &actions, &attr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  posix_spawnattr_destroy(&attr);
  if (rc != 0) {
    return Status::Unavailable("could not start '" + spec.argv[0] + "'" +
                               (spec.cwd.empty() ? std::string() : " in " + spec.cwd) + ": " + std::strerror(rc));
  }
  int pidfd = static_cast<int>(syscall(SYS_pidfd_open, pid, 0));
  return std::unique_ptr<EngineProcess>(new ChildProcess(pid, pidfd));
}

}  // namespace sandswim::worker
