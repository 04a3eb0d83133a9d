// PeriodicJobs: the daemon's background work that runs every so often (lease expiry, the Slurm
// pilot watch, the scheduler's nightly reruns and drift reports), as one facility instead of a
// hand-rolled thread, mutex and condition variable each.
//
// Add() names a job, its period and the function to call; Start() gives every job a thread that
// calls it (first at once when `run_at_start`, else after one period), then once per period after
// the previous call returned, until Stop(). A call is never interrupted: Stop() wakes the waiting
// threads and joins them once their current call has returned. A job reports its own errors (the
// function logs them); the facility only keeps the rhythm. A period <= 0 disables the job.
// Periods are the clock's monotonic time (platform/clock.h): a FakeClock drives them in tests.
//
// Thread safety: Add() and Start() from one thread before Stop(); Stop() from any thread, once
// (the destructor calls it). Each job's function runs on its own thread, never twice at once.
#ifndef SANDSWIM_SERVER_PERIODIC_H_
#define SANDSWIM_SERVER_PERIODIC_H_

#include <condition_variable>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "platform/clock.h"

namespace sandswim {

class PeriodicJobs {
 public:
  // REQUIRES: `clock`, when given, outlives the jobs; nullptr: the system's clock.
  explicit PeriodicJobs(Clock* clock = nullptr) : clock_(clock != nullptr ? clock : &system_clock_) {}
  ~PeriodicJobs();
  PeriodicJobs(const PeriodicJobs&) = delete;
  PeriodicJobs& operator=(const PeriodicJobs&) = delete;

  // REQUIRES: before Start().
  void Add(std::string name, double period_s, std::function<void()> job, bool run_at_start = false);
  void Start();
  // Wakes every job's thread and joins them (a running call finishes first). Idempotent.
  void Stop();

  // Names of the jobs that run (period > 0), in the order added.
  std::vector<std::string> names() const;

 private:
  struct Job {
    std::string name;
    double period_s = 0;
    std::function<void()> fn;
    bool run_at_start = false;
  };
  void Loop(const Job& job);

  SystemClock system_clock_;
  Clock* clock_;
  std::vector<Job> jobs_;
  std::vector<std::thread> threads_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;  // guarded by mu_
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_PERIODIC_H_
