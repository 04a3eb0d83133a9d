#include "server/periodic.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <functional>
#include <map>
#include <mutex>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "platform/clock.h"

namespace sandswim {
namespace {

// Counts calls and lets a test wait until a number of them has happened.
class CallCounter {
 public:
  void Called() {
    std::lock_guard<std::mutex> lock(mu_);
    ++calls_;
    cv_.notify_all();
  }
  // False when n calls have not happened within 10 s (a job that never runs fails, not hangs).
  bool WaitFor(int n) {
    std::unique_lock<std::mutex> lock(mu_);
    return cv_.wait_for(lock, std::chrono::seconds(10), [&] { return calls_ >= n; });
  }
  int calls() {
    std::lock_guard<std::mutex> lock(mu_);
    return calls_;
  }

 private:
  std::mutex mu_;
  std::condition_variable cv_;
  int calls_ = 0;
};

// A FakeClock that counts, per thread, the looks a waiting thread takes at its wait's condition
// (each look also reads the time: FakeClock::WaitFor checks done() and then the clock). A thread
// that has looked twice since the clock moved has seen the new time and, after the first look,
// either waited on (still inside its wait) or left it and come back after its job ran: so the
// job's calls, read then, say whether it ran early. No real sleep decides anything.
class LookCountingClock : public FakeClock {
 public:
  bool WaitFor(std::condition_variable& cv, std::unique_lock<std::mutex>& lock, double seconds,
               const std::function<bool()>& done) override {
    return FakeClock::WaitFor(cv, lock, seconds, [&] {
      {
        std::lock_guard<std::mutex> l(looks_mu_);
        ++looks_[std::this_thread::get_id()];
      }
      looks_cv_.notify_all();
      return done();
    });
  }
  // Moves time, then blocks (in real time, at most 10 s) until `threads` threads have each looked
  // twice since; false when they did not.
  bool AdvanceAndAwaitLooks(double seconds, int threads) {
    Advance(seconds);
    {
      std::lock_guard<std::mutex> l(looks_mu_);
      looks_.clear();  // after the move: every look counted from here reads the new time
    }
    std::unique_lock<std::mutex> l(looks_mu_);
    return looks_cv_.wait_for(l, std::chrono::seconds(10), [&] {
      int looked = 0;
      for (const auto& [id, n] : looks_) looked += n >= 2;
      return looked >= threads;
    });
  }

 private:
  std::mutex looks_mu_;
  std::condition_variable looks_cv_;
  std::map<std::thread::id, int> looks_;
};

// Time is a FakeClock's: a job's thread waits in the clock (AwaitWaiting sees it there) until
// the test moves time past its period; a call before that is caught.
TEST(PeriodicJobsTest, AJobRunsOncePerPeriodOfItsClockUntilStopped) {
  LookCountingClock clock;
  CallCounter counter;
  PeriodicJobs jobs(&clock);
  jobs.Add("minutely", 60, [&] { counter.Called(); });
  jobs.Start();
  for (int n = 1; n <= 3; ++n) {
    ASSERT_TRUE(clock.AwaitWaiting(1)) << "call " << n;
    // Not yet a period since the last call returned: the job's thread sees the time and waits on.
    ASSERT_TRUE(clock.AdvanceAndAwaitLooks(59.5, 1)) << "call " << n;
    EXPECT_EQ(counter.calls(), n - 1) << "ran before its period, call " << n;
    clock.Advance(0.5);
    ASSERT_TRUE(counter.WaitFor(n)) << "call " << n;
  }
  ASSERT_TRUE(clock.AwaitWaiting(1));
  EXPECT_EQ(counter.calls(), 3);  // each period's call, none before its period ended
  jobs.Stop();
  EXPECT_EQ(clock.waiting(), 0);
  // Fifty periods later a job that outlived Stop() would have run again.
  clock.Advance(50 * 60);
  EXPECT_EQ(counter.calls(), 3);
  jobs.Stop();  // idempotent
  EXPECT_EQ(counter.calls(), 3);
}

TEST(PeriodicJobsTest, RunAtStartRunsBeforeTheFirstPeriodAndStopDoesNotWaitForTheNext) {
  LookCountingClock clock;
  CallCounter counter;
  PeriodicJobs jobs(&clock);
  jobs.Add(
      "nightly", 3600, [&] { counter.Called(); }, /*run_at_start=*/true);
  jobs.Add("hourly", 3600, [&] { ADD_FAILURE() << "ran before its first period"; });
  jobs.Start();
  ASSERT_TRUE(counter.WaitFor(1));
  ASSERT_TRUE(clock.AwaitWaiting(2));  // both wait for their hour
  ASSERT_TRUE(clock.AdvanceAndAwaitLooks(3599, 2));  // both saw the time (an early "hourly" fails above)
  jobs.Stop();  // returns although both jobs wait for another second
  EXPECT_EQ(counter.calls(), 1);
}

TEST(PeriodicJobsTest, StopLetsARunningCallFinish) {
  std::atomic<bool> entered{false}, finished{false};
  std::mutex mu;
  std::condition_variable cv;
  PeriodicJobs jobs;
  jobs.Add(
      "slow", 3600,
      [&] {
        entered = true;
        cv.notify_all();
        std::unique_lock<std::mutex> lock(mu);
        cv.wait_for(lock, std::chrono::milliseconds(50));
        finished = true;
      },
      /*run_at_start=*/true);
  jobs.Start();
  {
    std::unique_lock<std::mutex> lock(mu);
    cv.wait(lock, [&] { return entered.load(); });
  }
  jobs.Stop();
  EXPECT_TRUE(finished);
}

TEST(PeriodicJobsTest, APeriodOfZeroDisablesTheJob) {
  PeriodicJobs jobs;
  jobs.Add(
      "off", 0, [] { ADD_FAILURE() << "a disabled job ran"; }, /*run_at_start=*/true);
  jobs.Add("on", 1, [] {});
  EXPECT_THAT(jobs.names(), ::testing::ElementsAre("on"));
  jobs.Start();
  jobs.Stop();
}

}  // namespace
}  // namespace sandswim
