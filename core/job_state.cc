#include "core/job_state.h"

#include <ostream>

#include <nlohmann/json.hpp>

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

void to_json(nlohmann::json& j, JobState s) { j = std::string(JobStateName(s)); }

void from_json(const nlohmann::json& j, JobState& s) {
  const std::string text = j.get<std::string>();
  std::optional<JobState> parsed = ParseJobState(text);
  if (!parsed) {
    throw nlohmann::json::other_error::create(
        501, "state: '" + text + "' is not one of " + std::string(JobStateNames()), &j);
  }
  s = *parsed;
}

std::ostream& operator<<(std::ostream& os, JobState s) { return os << JobStateName(s); }

bool IsFinished(JobState s) { return s == JobState::kDone || s == JobState::kFailed || s == JobState::kCancelled; }

}  // namespace sandswim
