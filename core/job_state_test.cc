#include "core/job_state.h"

#include <string>

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace sandswim
