#include "workers/launcher.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <thread>

namespace sandswim::worker {
namespace {

using SteadyClock = std::chrono::steady_clock;  // the engine process's own time (its wall_s, its waits)

double Seconds(SteadyClock::duration d) { return std::chrono::duration<double>(d).count(); }

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
  ChildProcess(pid_t pid, int pidfd) : pid_(pid), pidfd_(pidfd), start_(SteadyClock::now()) {}
  pid_t pid() const override { return pid_; }
  ~ChildProcess() override {
    if (!reaped_) Stop(0.0);
    if (pidfd_ >= 0) close(pidfd_);
  }

  bool WaitFor(double seconds) override {
    if (reaped_) return true;
    if (TryReap()) return true;
    if (seconds <= 0) return false;
    const auto deadline =
        SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(std::chrono::duration<double>(seconds));
    if (pidfd_ >= 0) {
      // The pidfd becomes readable when the child exits: no polling delay, no busy loop.
      while (true) {
        double left = Seconds(deadline - SteadyClock::now());
        if (left <= 0) return TryReap();
        struct pollfd p {
          pidfd_, POLLIN, 0
        };
        int rc = poll(&p, 1, static_cast<int>(std::ceil(left * 1000)));
        if (rc < 0 && errno == EINTR) continue;
        return TryReap();
      }
    }
    // Without pidfd (old kernels): poll with growing sleeps.
    auto nap = std::chrono::microseconds(500);
    while (!TryReap()) {
      if (SteadyClock::now() >= deadline) return false;
      std::this_thread::sleep_for(std::min<SteadyClock::duration>(nap, deadline - SteadyClock::now()));
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
    status_.wall_s = Seconds(SteadyClock::now() - start_);
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
  SteadyClock::time_point start_;
  bool reaped_ = false;
  ExitStatus status_;
};

constexpr int kParentDied = SIGUSR2;  // PR_SET_PDEATHSIG of the guard
constexpr int kGuardSignals[] = {SIGCHLD, kParentDied, SIGTERM, SIGINT, SIGHUP, SIGQUIT, SIGPIPE, SIGUSR1};

[[noreturn]] void ReportAndExit(int fd, int stage) {
  int msg[2] = {stage, errno};
  ssize_t ignored = write(fd, msg, sizeof msg);
  (void)ignored;
  _exit(127);
}

// The guard: leader of the engine's process group, the process the worker waits for.
//  - It asks the kernel for kParentDied when the worker's thread that forked it dies (SIGKILL
//    included), and then SIGKILLs its whole group: mpirun, every rank, itself.
//  - The engine asks the kernel for SIGKILL when the guard dies, so a SIGKILL aimed at the guard
//    (the pid the worker knows) also ends the engine.
//  - Signals the worker sends to the group (SIGTERM on Stop) reach the engine directly; the
//    guard ignores them and waits for the engine, then exits as the engine did (same code, or
//    the same signal), so the worker sees the engine's exit status. wait4() on the guard
//    counts the CPU of the engine and of the ranks it reaped.
}  // namespace

[[noreturn]] void GuardMain(const GuardArgs& a) {
  sigset_t guard_set, none;
  sigemptyset(&guard_set);
  sigemptyset(&none);
  for (int sig : kGuardSignals) sigaddset(&guard_set, sig);
  sigprocmask(SIG_BLOCK, &guard_set, nullptr);
  // Default dispositions, so that every one of these is generated and waits for sigwaitinfo()
  // (an ignored SIGCHLD would not be).
  for (int sig : kGuardSignals) signal(sig, SIG_DFL);
  if (setpgid(0, 0) != 0) ReportAndExit(a.report_fd, 0);
  if (prctl(PR_SET_PDEATHSIG, kParentDied) != 0) ReportAndExit(a.report_fd, 0);
  if (getppid() != a.worker_pid) _exit(127);  // the worker died before the line above
  if (a.cwd != nullptr && chdir(a.cwd) != 0) ReportAndExit(a.report_fd, 1);
  if (a.out != nullptr) {
    int in = open("/dev/null", O_RDONLY);
    int out = open(a.out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (in < 0 || out < 0) ReportAndExit(a.report_fd, 2);
    dup2(in, 0);
    dup2(out, 1);
    dup2(out, 2);
  }
  fcntl(a.report_fd, F_SETFD, FD_CLOEXEC);  // closed by the engine's exec
  // Nothing else of the worker's (sockets, other engines' pipes) stays open in the group.
  const int keep = a.report_fd;
  for (int fd = 3; fd < keep; ++fd) close(fd);
  if (syscall(SYS_close_range, keep + 1, ~0U, 0) != 0) {
    for (int fd = keep + 1; fd < 4096; ++fd) close(fd);  // kernels before 5.9
  }
  // vfork: the guard is single-threaded and waits for the exec anyway; no page-table copy.
  const pid_t guard = getpid();
  pid_t engine = vfork();
  if (engine < 0) ReportAndExit(a.report_fd, 3);
  if (engine == 0) {
    // The engine dies with the guard too, should the guard itself be SIGKILLed (the kernel's
    // SIGKILL reaches mpirun or a direct engine; mpirun's ranks then lose their launcher).
    if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || getppid() != guard) _exit(137);
    // Default dispositions (set above) and an empty mask for the engine.
    sigprocmask(SIG_SETMASK, &none, nullptr);
    execve(a.exe, a.argv, a.envp);
    ReportAndExit(a.report_fd, 4);
  }
  close(a.report_fd);
  while (true) {
    siginfo_t info;
    int sig = sigwaitinfo(&guard_set, &info);
    if (sig == kParentDied) {
      if (getppid() == a.worker_pid) continue;  // a stray SIGUSR2 (kill, scancel --signal), not a death
      kill(0, SIGKILL);                         // the whole group, this guard included
      _exit(137);
    }
    if (sig != SIGCHLD) continue;  // a group-wide signal: the engine got it too
    int st = 0;
    pid_t r = waitpid(engine, &st, WNOHANG);
    if (r != engine) continue;
    if (WIFEXITED(st)) _exit(WEXITSTATUS(st));
    const int term = WIFSIGNALED(st) ? WTERMSIG(st) : SIGKILL;
    // Dying of the engine's signal must not also dump the guard's core over the engine's.
    const rlimit no_core{0, 0};
    setrlimit(RLIMIT_CORE, &no_core);
    signal(term, SIG_DFL);
    sigset_t only;
    sigemptyset(&only);
    sigaddset(&only, term);
    sigprocmask(SIG_UNBLOCK, &only, nullptr);
    kill(getpid(), term);
    _exit(128 + term);
  }
}

namespace {

// The guard executable next to this program (sandswim-engine-guard), or "" to fork the guard.
const std::string& GuardExecutable() {
  static const std::string path = [] {
    char buf[4096];
    ssize_t n = readlink("/proc/self/exe", buf, sizeof buf - 1);
    if (n <= 0) return std::string();
    std::string self(buf, static_cast<size_t>(n));
    std::string guard = self.substr(0, self.rfind('/') + 1) + "sandswim-engine-guard";
    return access(guard.c_str(), X_OK) == 0 ? guard : std::string();
  }();
  return path;
}

// Without the guard executable: fork this process and run the guard in the copy (the same
// guarantees, at the price of copying this process's page tables: ~4x the CPU of a spawn here).
pid_t ForkGuard(const std::string& exe, std::vector<char*>& argv, std::vector<char*>& envp, const std::string& cwd,
                const std::string& out, int report_fd) {
  GuardArgs g;
  g.exe = exe.c_str();
  g.argv = argv.data();
  g.envp = envp.data();
  g.cwd = cwd.empty() ? nullptr : cwd.c_str();
  g.out = out.c_str();
  g.report_fd = report_fd;
  g.worker_pid = getpid();
  pid_t pid = fork();
  if (pid == 0) GuardMain(g);  // never returns
  return pid;
}

// A single-process engine, started straight from this (multi-threaded) process without a guard:
// vfork (no page-table copy; this thread waits until the exec), then in the child only system
// calls on memory prepared before: default dispositions, its own process group,
// PR_SET_PDEATHSIG SIGKILL (it dies with the thread that started it, even a SIGKILLed worker),
// the run directory, stdout/stderr to `out`, nothing else inherited, an empty signal mask, exec.
// A failure before the exec is written to `*stage` / `*error` (memory the vfork child shares)
// and returns -1 after reaping the child.
pid_t SpawnSingle(const char* exe, char* const* argv, char* const* envp, const char* cwd, const char* out, int* stage,
                  int* error) {
  sigset_t all, old, none;
  sigfillset(&all);
  sigemptyset(&none);
  // No handler of this process may run in the child while it shares this process's memory.
  pthread_sigmask(SIG_SETMASK, &all, &old);
  const pid_t parent = getpid();
  volatile int failed_stage = -1;
  volatile int failed_errno = 0;
  const pid_t pid = vfork();
  if (pid == 0) {
    struct sigaction dfl;
    std::memset(&dfl, 0, sizeof dfl);
    dfl.sa_handler = SIG_DFL;
    for (int sig = 1; sig < NSIG; ++sig) sigaction(sig, &dfl, nullptr);  // fails harmlessly for some
    auto fail = [&](int st) {
      failed_errno = errno;
      failed_stage = st;
      _exit(127);
    };
    if (setpgid(0, 0) != 0) fail(0);
    if (prctl(PR_SET_PDEATHSIG, SIGKILL) != 0) fail(0);
    if (getppid() != parent) _exit(137);  // the worker died before the line above
    if (cwd != nullptr && chdir(cwd) != 0) fail(1);
    int in = open("/dev/null", O_RDONLY);
    int outfd = open(out, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (in < 0 || outfd < 0) fail(2);
    if (dup2(in, 0) < 0 || dup2(outfd, 1) < 0 || dup2(outfd, 2) < 0) fail(2);
    if (syscall(SYS_close_range, 3, ~0U, 0) != 0) {
      for (int fd = 3; fd < 4096; ++fd) close(fd);  // kernels before 5.9
    }
    sigprocmask(SIG_SETMASK, &none, nullptr);
    execve(exe, argv, envp);
    fail(4);
  }
  const int vfork_errno = errno;
  pthread_sigmask(SIG_SETMASK, &old, nullptr);
  if (pid < 0) {
    *stage = 3;
    *error = vfork_errno;
    return -1;
  }
  if (failed_stage >= 0) {
    while (waitpid(pid, nullptr, 0) < 0 && errno == EINTR) {
    }
    *stage = failed_stage;
    *error = failed_errno;
    return -1;
  }
  return pid;
}

}  // namespace

const char* LauncherName(LauncherKind kind) {
  switch (kind) {
    case LauncherKind::kMpirun:
      return "mpirun";
    case LauncherKind::kSrun:
      return "srun";
    case LauncherKind::kDirect:
      return "direct";
  }
  return "?";
}

LaunchSpec EngineCommand(LauncherKind kind, int ranks, const std::string& engine, const std::string& deck_file,
                         const std::string& log_file, const std::string& cwd, bool as_root, bool widened) {
  LaunchSpec spec;
  spec.cwd = cwd;
  spec.output_file = "engine.out";
  const std::string r = std::to_string(ranks);
  switch (kind) {
    case LauncherKind::kMpirun:
      spec.argv = {"mpirun", "-np", r, "--bind-to", "none"};
      if (widened) spec.argv.push_back("--oversubscribe");
      if (as_root) {
        spec.env = {{"OMPI_ALLOW_RUN_AS_ROOT", "1"}, {"OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1"}};
      }
      break;
    case LauncherKind::kSrun:
      // --exclusive: the step gets CPUs of its own, so several runs share one allocation side
      // by side (a step that finds none free waits for one).
      spec.argv = {"srun", "--mpi=pmix", "-n", r, "--exclusive"};
      break;
    case LauncherKind::kDirect:
      spec.single_process = true;
      break;
  }
  spec.argv.push_back(engine);
  for (const std::string& a : {std::string("-in"), deck_file, std::string("-log"), log_file, std::string("-screen"),
                               std::string("/dev/null")}) {
    spec.argv.push_back(a);
  }
  return spec;
}

Result<std::unique_ptr<EngineProcess>> GuardedLauncher::Start(const LaunchSpec& spec) {
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
  static const char* const kStage[] = {"start", "chdir", "open output", "fork", "exec"};
  auto start_failed = [&](int stage, int error) {
    return Status::Unavailable("could not start '" + spec.argv[0] + "'" +
                               (spec.cwd.empty() ? std::string() : " in " + spec.cwd) + " (" +
                               kStage[stage >= 0 && stage < 5 ? stage : 0] + "): " + std::strerror(error));
  };

  if (spec.single_process) {
    int stage = 0, error = 0;
    const pid_t pid = SpawnSingle(exe.c_str(), argv.data(), envp.data(), spec.cwd.empty() ? nullptr : spec.cwd.c_str(),
                                  out.c_str(), &stage, &error);
    if (pid < 0) return start_failed(stage, error);
    int pidfd = static_cast<int>(syscall(SYS_pidfd_open, pid, 0));
    return std::unique_ptr<EngineProcess>(new ChildProcess(pid, pidfd));
  }

  // The engine must never outlive the worker, even a worker killed with SIGKILL: mpirun and its
  // ranks would run on unwatched, and the run is leased again elsewhere. posix_spawn cannot set
  // PR_SET_PDEATHSIG, and that signal would reach only mpirun, not its ranks. So the child is a
  // small guard (GuardMain) that leads the engine's process group: it dies with the worker's
  // thread, and then kills the whole group. Failures before exec come back through a pipe.
  int report[2];
  if (pipe2(report, O_CLOEXEC) != 0) return Status::Unavailable(std::string("pipe: ") + std::strerror(errno));
  pid_t pid = -1;
  int spawn_errno = 0;
  if (const std::string& guard = GuardExecutable(); !guard.empty()) {
    // The cheap way: posix_spawn (vfork-like: no copy of this process's page tables) of the small
    // static guard, which forks the engine from its own tiny address space. Its argv:
    // WORKER_PID REPORT_FD EXE ENGINE_ARGV...; the report pipe is its fd 3.
    std::vector<std::string> gargs = {guard, std::to_string(getpid()), "3", exe};
    gargs.insert(gargs.end(), args.begin(), args.end());
    std::vector<char*> gargv;
    for (auto& a : gargs) gargv.push_back(a.data());
    gargv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    if (!spec.cwd.empty()) posix_spawn_file_actions_addchdir_np(&actions, spec.cwd.c_str());
    posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
    posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    posix_spawn_file_actions_adddup2(&actions, report[1], 3);
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attr, 0);
    spawn_errno = posix_spawn(&pid, guard.c_str(), &actions, &attr, gargv.data(), envp.data());
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
    if (spawn_errno != 0) pid = -1;
  } else {
    pid = ForkGuard(exe, argv, envp, spec.cwd, out, report[1]);
    if (pid < 0) spawn_errno = errno;
  }
  close(report[1]);
  if (pid < 0) {
    close(report[0]);
    return Status::Unavailable("could not start '" + spec.argv[0] + "'" +
                               (spec.cwd.empty() ? std::string() : " in " + spec.cwd) + ": " +
                               std::strerror(spawn_errno));
  }
  // EOF once the engine's exec succeeded (the pipe is close-on-exec), else {stage, errno}.
  int failure[2] = {0, 0};
  ssize_t got;
  do {
    got = read(report[0], failure, sizeof failure);
  } while (got < 0 && errno == EINTR);
  close(report[0]);
  if (got == static_cast<ssize_t>(sizeof failure)) {
    int st = 0;
    while (waitpid(pid, &st, 0) < 0 && errno == EINTR) {
    }
    return start_failed(failure[0], failure[1]);
  }
  int pidfd = static_cast<int>(syscall(SYS_pidfd_open, pid, 0));
  return std::unique_ptr<EngineProcess>(new ChildProcess(pid, pidfd));
}

}  // namespace sandswim::worker
