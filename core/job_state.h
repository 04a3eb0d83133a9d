// JobState: where a bed or a run is in its life (SPEC.md "run"), and its one spelling as text:
// the database's state column, the REST API's JSON and the CLI's filters keep these strings.
// Structs hold a JobState; the text is made at the edges (JobStateName/ToString at SQL writes and
// messages, to_json/from_json for JSON) and parsed where it comes in (the store's reads, JSON).
//
//   queued -> running -> done | failed        (a lease expiring or a retry: running -> queued)
//   queued | running -> cancelled              (runs only: no live sweep wants it any more)
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_JOB_STATE_H_
#define SANDSWIM_CORE_JOB_STATE_H_

#include <array>
#include <iosfwd>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

namespace sandswim {

enum class JobState { kQueued, kRunning, kDone, kFailed, kCancelled };

inline constexpr std::array<JobState, 5> kJobStates = {JobState::kQueued, JobState::kRunning, JobState::kDone,
                                                        JobState::kFailed, JobState::kCancelled};

// "queued" | "running" | "done" | "failed" | "cancelled".
std::string_view JobStateName(JobState s);
// The inverse of JobStateName; nullopt for any other text.
std::optional<JobState> ParseJobState(std::string_view text);
// JobStateName as a std::string, for messages.
inline std::string ToString(JobState s) { return std::string(JobStateName(s)); }
// "queued, running, done, failed, cancelled": for messages that list what a state may be.
std::string_view JobStateNames();
// Whether a state's text (as the CLI reads it from the API's JSON) is `s`; a text that is no state
// is in none.
inline bool InState(std::string_view text, JobState s) { return text == JobStateName(s); }
// JSON: the state's name; from_json throws nlohmann::json::other_error for a text that is no state.
void to_json(nlohmann::json& j, JobState s);
void from_json(const nlohmann::json& j, JobState& s);
// The name, so test failures and logs print "done" rather than a number.
std::ostream& operator<<(std::ostream& os, JobState s);
// done, failed and cancelled: nothing more happens to the job.
bool IsFinished(JobState s);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_JOB_STATE_H_
