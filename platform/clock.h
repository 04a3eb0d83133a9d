// Clock: time as the daemon, the worker and the CLI see it -- wall time ("now", for lease expiry
// and created/finished times), monotonic time (for intervals: ticks, idle rules, timeouts),
// sleeping, and waiting on a condition variable for at most a while (a sleep another thread can
// cut short) -- injected wherever time decides something, so tests drive time by hand with
// FakeClock instead of sleeping.
//
// Wall times are seconds since the Unix epoch as a double (sub-millisecond resolution); monotonic
// times are seconds from an arbitrary start and never go back.
//
// Thread safety: SystemClock is stateless; FakeClock is safe to read, advance and wait on from any
// thread.
#ifndef SANDSWIM_PLATFORM_CLOCK_H_
#define SANDSWIM_PLATFORM_CLOCK_H_

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace sandswim {

class Clock {
 public:
  virtual ~Clock() = default;
  // Seconds since the Unix epoch.
  virtual double Now() = 0;
  // Seconds from an arbitrary start; never goes back (a wall clock set back does not move it).
  virtual double Monotonic() = 0;
  // Returns once `seconds` of monotonic time have passed (at once for seconds <= 0).
  virtual void SleepFor(double seconds) = 0;
  // Waits on `cv`, whose mutex `lock` holds (as std::condition_variable::wait_for does), until
  // `done()` or until `seconds` of monotonic time have passed; returns done(). A notify of `cv`
  // makes it look at done() again. REQUIRES: `lock` is locked; seconds is finite.
  virtual bool WaitFor(std::condition_variable& cv, std::unique_lock<std::mutex>& lock, double seconds,
                       const std::function<bool()>& done) = 0;
};

class SystemClock : public Clock {
 public:
  double Now() override {
    using namespace std::chrono;
    return duration<double>(system_clock::now().time_since_epoch()).count();
  }
  double Monotonic() override {
    using namespace std::chrono;
    return duration<double>(steady_clock::now().time_since_epoch()).count();
  }
  void SleepFor(double seconds) override {
    if (seconds > 0) std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  }
  bool WaitFor(std::condition_variable& cv, std::unique_lock<std::mutex>& lock, double seconds,
               const std::function<bool()>& done) override {
    return cv.wait_for(lock, std::chrono::duration<double>(std::max(seconds, 0.0)), done);
  }
};

// A clock that moves only when told to. Wall time starts at `start` (a fixed, plausible epoch
// time), monotonic time at 0. Advance moves both; Set moves wall time only (as a wall clock set by
// hand); SleepFor advances both by the time asked and returns at once (a sleep is a thread telling
// time to move). WaitFor does not move time: it returns when done() holds or when others have
// moved the clock past its end (Advance or SleepFor wake it), so a test can hold a periodic thread
// in its wait, see it there (AwaitWaiting) and move time past it.
class FakeClock : public Clock {
 public:
  explicit FakeClock(double start = 1.7e9) : now_(start) {}
  double Now() override { return now_.load(); }
  double Monotonic() override { return monotonic_.load(); }
  void SleepFor(double seconds) override {
    if (seconds > 0) Advance(seconds);
  }
  bool WaitFor(std::condition_variable& cv, std::unique_lock<std::mutex>& lock, double seconds,
               const std::function<bool()>& done) override {
    const double until = Monotonic() + seconds;
    {
      std::lock_guard<std::mutex> w(waiters_mu_);
      waiters_.push_back(&cv);
    }
    waiters_cv_.notify_all();
    while (!done() && Monotonic() < until) {
      // Advance notifies `cv`; the short real wait covers one that came between the check and
      // the wait (it cannot take the caller's mutex to close that gap).
      cv.wait_for(lock, std::chrono::milliseconds(2));
    }
    {
      std::lock_guard<std::mutex> w(waiters_mu_);
      waiters_.erase(std::find(waiters_.begin(), waiters_.end(), &cv));
    }
    return done();
  }
  void Set(double t) { now_.store(t); }
  void Advance(double seconds) {
    Add(now_, seconds);
    Add(monotonic_, seconds);
    std::lock_guard<std::mutex> w(waiters_mu_);
    for (std::condition_variable* cv : waiters_) cv->notify_all();
  }
  // Threads inside WaitFor now.
  int waiting() {
    std::lock_guard<std::mutex> w(waiters_mu_);
    return static_cast<int>(waiters_.size());
  }
  // Blocks (in real time, at most `real_timeout_s`) until `n` threads are inside WaitFor; false
  // when they never got there.
  bool AwaitWaiting(int n, double real_timeout_s = 10) {
    std::unique_lock<std::mutex> w(waiters_mu_);
    return waiters_cv_.wait_for(w, std::chrono::duration<double>(real_timeout_s),
                                [&] { return static_cast<int>(waiters_.size()) >= n; });
  }

 private:
  static void Add(std::atomic<double>& a, double seconds) {
    double old = a.load();
    while (!a.compare_exchange_weak(old, old + seconds)) {
    }
  }
  std::atomic<double> now_;
  std::atomic<double> monotonic_{0};
  std::mutex waiters_mu_;
  std::condition_variable waiters_cv_;             // notified when a thread starts waiting
  std::vector<std::condition_variable*> waiters_;  // guarded by waiters_mu_: one entry per waiting thread
};

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_CLOCK_H_
