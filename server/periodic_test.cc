#include "server/periodic.h"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

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

TEST(PeriodicJobsTest, AJobRunsAgainAndAgainUntilStopped) {
  CallCounter counter;
  PeriodicJobs jobs;
  jobs.Add("often", 0.001, [&] { counter.Called(); });
  jobs.Start();
  ASSERT_TRUE(counter.WaitFor(3));
  jobs.Stop();
  const int after_stop = counter.calls();
  // Fifty periods later a job that outlived Stop() would have run again.
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(counter.calls(), after_stop);
  jobs.Stop();  // idempotent
  EXPECT_EQ(counter.calls(), after_stop);
}

TEST(PeriodicJobsTest, RunAtStartRunsBeforeTheFirstPeriodAndStopDoesNotWaitForTheNext) {
  CallCounter counter;
  PeriodicJobs jobs;
  jobs.Add(
      "nightly", 3600, [&] { counter.Called(); }, /*run_at_start=*/true);
  jobs.Add("hourly", 3600, [&] { ADD_FAILURE() << "ran before its first period"; });
  jobs.Start();
  ASSERT_TRUE(counter.WaitFor(1));
  jobs.Stop();  // returns although both jobs wait for an hour
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
