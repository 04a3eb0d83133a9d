#include "core/job_state.h"

#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace sandswim {
namespace {

TEST(JobStateTest, EveryStateRoundTripsThroughItsNameAndTheListNamesThemAll) {
  std::string listed;
  for (JobState s : kJobStates) {
    EXPECT_EQ(ParseJobState(JobStateName(s)), s);
    listed += (listed.empty() ? "" : ", ") + std::string(JobStateName(s));
  }
  EXPECT_EQ(listed, JobStateNames());
  EXPECT_FALSE(ParseJobState("Done").has_value());
  EXPECT_FALSE(ParseJobState("").has_value());
  EXPECT_FALSE(IsFinished(JobState::kRunning));
  EXPECT_TRUE(IsFinished(JobState::kCancelled));
}

TEST(JobStateTest, JsonCarriesTheNameAndRefusesAnyOtherText) {
  for (JobState s : kJobStates) {
    const nlohmann::json j = s;
    EXPECT_EQ(j, std::string(JobStateName(s)));
    EXPECT_EQ(j.get<JobState>(), s);
  }
  EXPECT_EQ(nlohmann::json({{"state", JobState::kDone}}).dump(), R"({"state":"done"})");
  EXPECT_THROW(nlohmann::json("finished").get<JobState>(), nlohmann::json::exception);
  EXPECT_THROW(nlohmann::json(2).get<JobState>(), nlohmann::json::exception);
}

}  // namespace
}  // namespace sandswim
