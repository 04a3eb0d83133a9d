#include "core/job_state.h"

namespace sandswim {

std::string_view JobStateName(JobState s) {
  switch (s) {
    case JobState::kQueued:
      return "queued";
    case JobState::kRunning:
      return "running";
    case JobState::kDone:
      return "done";
    case JobState::kFailed:
      return "failed";
    case JobState::kCancelled:
      return "cancelled";
  }
  return "queued";
}

std::optional<JobState> ParseJobState(std::string_view text) {
  for (JobState s : kJobStates) {
    if (JobStateName(s) == text) return s;
  }
  return std::nullopt;
}

std::string_view JobStateNames() { return "queued, running, done, failed, cancelled"; }

bool IsFinished(JobState s) { return s == JobState::kDone || s == JobState::kFailed || s == JobState::kCancelled; }

}  // namespace sandswim
