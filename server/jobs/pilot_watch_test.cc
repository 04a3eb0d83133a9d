#include "server/jobs/pilot_watch.h"

#include <filesystem>
#include <memory>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/keys.h"
#include "platform/clock.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

namespace fs = std::filesystem;

slurm::CommandOutput Out(int code, const std::string& out, const std::string& err = "") {
  slurm::CommandOutput o;
  o.exit_code = code;
  o.out = out;
  o.err = err;
  return o;
}

TEST(GoneSlurmJobsTest, FinalStatesAndAbsentJobsAreGone) {
  const std::vector<std::string> asked = {"10", "11", "12", "13", "14"};
  auto gone = GoneSlurmJobs(asked, Out(0, "10 RUNNING\n11 CANCELLED\n12 COMPLETING\n13 NODE_FAIL\n"));
  ASSERT_TRUE(gone.ok());
  EXPECT_EQ(*gone, (std::vector<std::string>{"11", "13", "14"}));  // 14: Slurm no longer knows it
  auto pending = GoneSlurmJobs({"20"}, Out(0, "20 PENDING\n"));
  EXPECT_TRUE(pending->empty());
}

TEST(GoneSlurmJobsTest, NoneKnownIsAllGoneButNoAnswerIsNothing) {
  auto none = GoneSlurmJobs({"7", "8"}, Out(1, "", "slurm_load_jobs error: Invalid job id specified\n"));
  ASSERT_TRUE(none.ok());
  EXPECT_EQ(*none, (std::vector<std::string>{"7", "8"}));
  auto down = GoneSlurmJobs({"7"}, Out(1, "", "slurm_load_jobs error: Unable to contact slurm controller\n"));
  EXPECT_EQ(down.status().code(), StatusCode::kUnavailable);
}

// squeue, scripted; records what it was asked.
class FakeSlurm : public slurm::SlurmCommands {
 public:
  Result<slurm::CommandOutput> answer = Out(0, "");
  std::vector<std::vector<std::string>> calls;
  Result<slurm::CommandOutput> Run(const std::vector<std::string>& argv,
                                   const std::vector<std::pair<std::string, std::string>>&) override {
    calls.push_back(argv);
    return answer;
  }
};

class PilotWatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(store_);
    queue_ = std::make_unique<LeaseQueue>(store_.get(), &clock_);
    auto req = ParseSubmitRequest(nlohmann::json::parse(R"({"name": "pw", "scale": "smoke",
      "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
      "axes": [{"param": "Omega", "values": [-80, 80]}], "combine": "product"})"));
    ASSERT_TRUE(Submit(*store_, *req, "LIGGGHTS test", clock_.Now()).ok());
    // The bed, done.
    auto bed = queue_->Lease({"w", "h", 1});
    ASSERT_TRUE(bed.ok() && bed->has_value());
    ASSERT_TRUE(queue_->PutBedRestart((*bed)->token, "r", Sha256Hex("r"), store_.dir().string()).ok());
    api::Completion c;
    c.ok = true;
    c.bed_result = api::BedResult{};
    ASSERT_EQ(queue_->Complete((*bed)->token, c)->state, "done");
  }
  void TearDown() override {
    queue_.reset();
  }
  std::string State(int64_t run) { return ToString(store_->GetRun(run)->summary.state); }

  FakeClock clock_;
  testing::TempStore store_{"pw"};
  std::unique_ptr<LeaseQueue> queue_;
  FakeSlurm slurm_;
};

TEST_F(PilotWatchTest, NoSlurmLeaseNoSqueue) {
  ASSERT_TRUE(queue_->Lease({"laptop", "here", 1}).ok());
  PilotWatch watch(queue_.get(), &slurm_, &clock_);
  auto check = watch.CheckOnce();
  ASSERT_TRUE(check.ok());
  EXPECT_EQ(check->jobs, 0);
  EXPECT_TRUE(slurm_.calls.empty());
}

TEST_F(PilotWatchTest, ReclaimsOnlyTheRunsOfJobsSlurmNoLongerRuns) {
  auto a = queue_->Lease({"p1", "n1", 1, "501"});
  auto b = queue_->Lease({"p2", "n2", 1, "502"});
  ASSERT_TRUE(a.ok() && a->has_value() && b.ok() && b->has_value());
  clock_.Advance(31);  // both workers silent for half the TTL
  slurm_.answer = Out(0, "501 CANCELLED\n502 RUNNING\n");
  PilotWatch watch(queue_.get(), &slurm_, &clock_);
  auto check = watch.CheckOnce();
  ASSERT_TRUE(check.ok()) << check.status().ToString();
  EXPECT_EQ(check->jobs, 2);
  EXPECT_EQ(check->gone, (std::vector<std::string>{"501"}));
  EXPECT_EQ(check->reclaimed, 1);
  ASSERT_EQ(slurm_.calls.size(), 1u);
  EXPECT_THAT(slurm_.calls[0], ::testing::ElementsAre("squeue", "-h", "-t", "all", "-o", "%A %T", "-j", "501,502"));
  EXPECT_EQ(State((*a)->id), "queued");
  EXPECT_EQ(State((*b)->id), "running");
}

TEST_F(PilotWatchTest, SlurmNotAnsweringReclaimsNothing) {
  auto a = queue_->Lease({"p1", "n1", 1, "601"});
  ASSERT_TRUE(a.ok() && a->has_value());
  slurm_.answer = Out(1, "", "slurm_load_jobs error: Unable to contact slurm controller (connect failure)");
  PilotWatch watch(queue_.get(), &slurm_, &clock_);
  EXPECT_EQ(watch.CheckOnce().status().code(), StatusCode::kUnavailable);
  slurm_.answer = Status::Unavailable("'squeue' not found on PATH");
  EXPECT_EQ(watch.CheckOnce().status().code(), StatusCode::kUnavailable);
  EXPECT_EQ(State((*a)->id), "running");
}

}  // namespace
}  // namespace sandswim
