// Clock: time as the daemon, the worker and the CLI see it -- wall time ("now", for lease expiry
// and created/finished times), monotonic time (for intervals: ticks, idle rules, timeouts) and
// sleeping -- injected wherever time decides something, so tests drive time by hand with
// FakeClock instead of sleeping.
//
// Wall times are seconds since the Unix epoch as a double (sub-millisecond resolution); monotonic
// times are seconds from an arbitrary start and never go back.
//
// Thread safety: SystemClock is stateless; FakeClock is safe to read and advance from any thread.
#ifndef SANDSWIM_PLATFORM_CLOCK_H_
#define SANDSWIM_PLATFORM_CLOCK_H_

#include <atomic>
#include <chrono>
#include <thread>

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
};

// A clock that moves only when told to. Wall time starts at `start` (a fixed, plausible epoch
// time), monotonic time at 0. Advance moves both; Set moves wall time only (as a wall clock set by
// hand); SleepFor advances both by the time asked and returns at once.
class FakeClock : public Clock {
 public:
  explicit FakeClock(double start = 1.7e9) : now_(start) {}
  double Now() override { return now_.load(); }
  double Monotonic() override { return monotonic_.load(); }
  void SleepFor(double seconds) override {
    if (seconds > 0) Advance(seconds);
  }
  void Set(double t) { now_.store(t); }
  void Advance(double seconds) {
    Add(now_, seconds);
    Add(monotonic_, seconds);
  }

 private:
  static void Add(std::atomic<double>& a, double seconds) {
    double old = a.load();
    while (!a.compare_exchange_weak(old, old + seconds)) {
    }
  }
  std::atomic<double> now_;
  std::atomic<double> monotonic_{0};
};

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_CLOCK_H_
