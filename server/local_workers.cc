#include "server/local_workers.h"

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <thread>

#include <spdlog/spdlog.h>

namespace sandswim {

std::string ExecutableDir() {
  std::error_code ec;
  auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return ".";
  return exe.parent_path().string();
}

std::string HostName() {
  char host[256] = {0};
  gethostname(host, sizeof(host) - 1);
  return host;
}

namespace {
constexpr const char* kLocalMark = ":local-";
}  // namespace

std::string LocalWorkerName(const std::string& host, pid_t daemon_pid) {
  return host + kLocalMark + std::to_string(daemon_pid);
}

bool IsLocalWorkerName(const std::string& worker, const std::string& host) {
  const std::string prefix = host + kLocalMark;
  if (worker.size() <= prefix.size() || worker.compare(0, prefix.size(), prefix) != 0) return false;
  return worker.find_first_not_of("0123456789", prefix.size()) == std::string::npos;
}

namespace {

std::string DescribeExit(int status) {
  if (WIFEXITED(status)) return "exited with status " + std::to_string(WEXITSTATUS(status));
  if (WIFSIGNALED(status)) return std::string("was killed by signal ") + strsignal(WTERMSIG(status));
  return "stopped";
}

}  // namespace

LocalWorkers::LocalWorkers(LocalWorkersOptions options, Subprocesses* processes, Clock* clock)
    : options_(std::move(options)), processes_(processes), clock_(clock) {}

LocalWorkers::~LocalWorkers() { Stop(); }

Status LocalWorkers::Start() {
  if (options_.count <= 0) return Status::Ok();
  if (options_.argv.empty() || access(options_.argv[0].c_str(), X_OK) != 0) {
    return Status::FailedPrecondition(
        "--local-workers", "the worker executable " + (options_.argv.empty() ? std::string("?") : options_.argv[0]) +
                               " is missing or not executable: build sandswim-worker next to sandswimd, "
                               "or run with --local-workers 0 and start workers yourself");
  }
  slots_.assign(static_cast<size_t>(options_.count), Slot{});
  for (Slot& slot : slots_) {
    slot.backoff_s = options_.min_backoff_s;
    Launch(slot);
  }
  return Status::Ok();
}

void LocalWorkers::Launch(Slot& slot) {
  auto pid = processes_->Spawn(options_.argv);
  double now = clock_->Now();
  if (!pid.ok()) {
    spdlog::error("local worker: {}; retrying in {:.0f} s (check that {} runs by itself)", pid.status().ToString(),
                  slot.backoff_s, options_.argv[0]);
    slot.pid = 0;
    slot.restart_at = now + slot.backoff_s;
    slot.backoff_s = std::min(slot.backoff_s * 2, options_.max_backoff_s);
    return;
  }
  slot.pid = *pid;
  slot.started_at = now;
  spdlog::info("local worker started: pid {}", slot.pid);
}

void LocalWorkers::Tick() {
  if (stopped_) return;
  double now = clock_->Now();
  for (Slot& slot : slots_) {
    if (slot.pid != 0) {
      auto status = processes_->Reap(slot.pid);
      if (!status) continue;
      if (now - slot.started_at >= options_.healthy_after_s) slot.backoff_s = options_.min_backoff_s;
      spdlog::warn(
          "local worker pid {} {}; restarting it in {:.0f} s (its log is in the daemon's "
          "output; a worker that keeps dying usually cannot reach the daemon or the engine)",
          slot.pid, DescribeExit(*status), slot.backoff_s);
      // Whatever the worker left in its group (an orphaned mpirun) goes with it.
      processes_->SignalGroup(slot.pid, SIGKILL);
      slot.pid = 0;
      slot.restart_at = now + slot.backoff_s;
      slot.backoff_s = std::min(slot.backoff_s * 2, options_.max_backoff_s);
    } else if (now >= slot.restart_at) {
      ++restarts_;
      Launch(slot);
    }
  }
}

void LocalWorkers::Stop() {
  if (stopped_) return;
  stopped_ = true;
  for (Slot& slot : slots_) {
    if (slot.pid != 0) processes_->SignalGroup(slot.pid, SIGTERM);
  }
  double deadline = clock_->Now() + options_.grace_s;
  while (true) {
    bool any_alive = false;
    for (Slot& slot : slots_) {
      if (slot.pid == 0) continue;
      if (processes_->Reap(slot.pid)) {
        processes_->SignalGroup(slot.pid, SIGKILL);  // stragglers of its group
        slot.pid = 0;
      } else {
        any_alive = true;
      }
    }
    if (!any_alive) return;
    if (clock_->Now() >= deadline) break;
    processes_->Pause(0.05);
  }
  for (Slot& slot : slots_) {
    if (slot.pid == 0) continue;
    spdlog::warn("local worker pid {} ignored SIGTERM for {:.0f} s; killing it", slot.pid, options_.grace_s);
    processes_->SignalGroup(slot.pid, SIGKILL);
    for (int i = 0; i < 100 && !processes_->Reap(slot.pid); ++i) processes_->Pause(0.01);
    slot.pid = 0;
  }
}

void LocalWorkers::RunUntilStopped(double period_s) {
  std::unique_lock<std::mutex> lock(mu_);
  while (!stop_requested_) {
    lock.unlock();
    Tick();
    lock.lock();
    cv_.wait_for(lock, std::chrono::duration<double>(period_s), [this] { return stop_requested_; });
  }
  lock.unlock();
  Stop();
}

void LocalWorkers::RequestStop() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_requested_ = true;
  }
  cv_.notify_all();
}

std::vector<pid_t> LocalWorkers::pids() const {
  std::vector<pid_t> out;
  for (const Slot& slot : slots_) out.push_back(slot.pid);
  return out;
}

}  // namespace sandswim
