// CampaignEdit: the loop of `sandswim campaign edit NAME`: a definition in a temporary file, the
// user's editor on it, then a save (the daemon's PUT, which validates and stores nothing it
// refuses); on a refusal the error is shown and the user may re-open the file to fix it.
//
// The loop ends when
//   - a save succeeds (the file is removed): kSaved, with the daemon's answer;
//   - the first edit leaves the file as it was (removed; nothing is sent): kUnchanged;
//   - after a refusal the user answers no, or re-opens and leaves the file as it was: kKept, and
//     the file stays where it is, so nothing typed is lost (the caller says where and how to put it).
// A text that is not a JSON object is refused here, before anything is sent, the same way.
//
// The editor is VISUAL, else EDITOR, else vi, run by /bin/sh with the file's path as its last
// argument (so EDITOR="code --wait" works), on the user's terminal: not through
// platform/subprocess.h, whose Run takes stdin from /dev/null and whose Spawn leads a new process
// group, neither of which an editor on a terminal survives.
//
// Everything outside (the editor, the question, the save) is injected, so tests run the loop with
// fakes; only the temporary file is real.
//
// Thread safety: call from one thread.
#ifndef SANDSWIM_CLI_CAMPAIGN_EDIT_H_
#define SANDSWIM_CLI_CAMPAIGN_EDIT_H_

#include <functional>
#include <ostream>
#include <string>

#include <nlohmann/json.hpp>

#include "core/status.h"

namespace sandswim::cli {

// VISUAL, else EDITOR (each when set and not empty), else "vi".
std::string EditorCommand(const std::function<const char*(const char*)>& getenv);

// Runs `command` "$path" through /bin/sh on this terminal and waits. An error names the command when
// it cannot be started, exits non-zero or is killed.
Status OpenInEditor(const std::string& command, const std::string& path);

struct EditEdges {
  // Opens the file at `path` in the user's editor and waits for it to close.
  std::function<Status(const std::string& path)> open;
  // Asks a yes/no question whose default is yes; false on "n"/"no" or the end of the input.
  std::function<bool(const std::string& question)> ask;
  // Saves a definition; a refusal names the field and the reason.
  std::function<Result<nlohmann::json>(const nlohmann::json& definition)> save;
};

struct EditOutcome {
  enum class Kind { kSaved, kUnchanged, kKept };
  Kind kind = Kind::kUnchanged;
  nlohmann::json reply;   // kSaved: what `save` answered
  std::string kept_path;  // kKept: the file holding the user's last text
  Status refusal;         // kKept: the last refusal
};

// The loop above, starting from `text` in a new file <dir>/sandswim-<stem>-XXXXXX.json; refusals
// are printed on `err` ("sandswim: FIELD: reason"). Errors: the file cannot be written or read,
// or the editor fails (the file is then kept and its path is in the error).
Result<EditOutcome> EditUntilSaved(const std::string& text, const std::string& dir, const std::string& stem,
                                   const EditEdges& edges, std::ostream& err);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_CAMPAIGN_EDIT_H_
