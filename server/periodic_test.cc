#include "server/periodic.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
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

// Time is a FakeClock's: a job's thread waits in the clock (AwaitWaiting sees it there) until
// the test moves time past its period.
TEST(PeriodicJobsTest, AJobRunsOncePerPeriodOfItsClockUntilStopped) {
  FakeClock clock;
  CallCounter counter;
  PeriodicJobs jobs(&clock);
  jobs.Add("minutely", 60, [&] { counter.Called(); });
  jobs.Start();
  for (int n = 1; n <= 3; ++n) {
    ASSERT_TRUE(clock.AwaitWaiting(1)) << "call " << n;
    clock.Advance(59.5);  // not yet a period since the last call returned
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
  FakeClock clock;
  CallCounter counter;
  PeriodicJobs jobs(&clock);
  jobs.Add(
      "nightly", 3600, [&] { counter.Called(); }, /*run_at_start=*/true);
  jobs.Add("hourly", 3600, [&] { ADD_FAILURE() << "ran before its first period"; });
  jobs.Start();
  ASSERT_TRUE(counter.WaitFor(1));
  ASSERT_TRUE(clock.AwaitWaiting(2));  // both wait for their hour
  clock.Advance(3599);
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
