// Clock: the daemon's notion of "now", injected wherever time decides something (lease expiry,
// created/finished times), so tests drive time by hand with FakeClock instead of sleeping.
//
// Times are seconds since the Unix epoch as a double (sub-millisecond resolution).
//
// Thread safety: SystemClock is stateless; FakeClock is safe to read and advance from any thread.
#ifndef SANDSWIM_PLATFORM_CLOCK_H_
#define SANDSWIM_PLATFORM_CLOCK_H_

#include <atomic>
#include <chrono>

namespace sandswim {

class Clock {
 public:
  virtual ~Clock() = default;
  // Seconds since the Unix epoch.
  virtual double Now() = 0;
};

class SystemClock : public Clock {
 public:
  double Now() override {
    using namespace std::chrono;
    return duration<double>(system_clock::now().time_since_epoch()).count();
  }
};

// A clock that moves only when told to. Starts at `start` (a fixed, plausible epoch time).
class FakeClock : public Clock {
 public:
  explicit FakeClock(double start = 1.7e9) : now_(start) {}
  double Now() override { return now_.load(); }
  void Set(double t) { now_.store(t); }
  void Advance(double seconds) { now_.store(now_.load() + seconds); }

 private:
  std::atomic<double> now_;
};

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_CLOCK_H_
