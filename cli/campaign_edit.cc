#include "cli/campaign_edit.h"

#include "cli/format.h"
#include "platform/files.h"

#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>

namespace sandswim::cli {
namespace {

using json = nlohmann::json;

Status WriteText(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  return out ? Status::Ok() : Status::IOError("cannot write " + path);
}

// The definition in `text`, or why it is not one (the reason a user needs to find the place).
Result<json> ParseDefinition(const std::string& text) {
  json definition;
  try {
    definition = json::parse(text);
  } catch (const json::parse_error& e) {
    return Status::InvalidArgument("definition",
                                   "not JSON: malformed at byte " + std::to_string(e.byte) + " (" + e.what() + ")");
  }
  if (!definition.is_object()) {
    return Status::InvalidArgument("definition", "expected a JSON object ({\"name\": ..., \"sweeps\": [...]})");
  }
  return definition;
}

}  // namespace

std::string EditorCommand(const std::function<const char*(const char*)>& getenv) {
  for (const char* name : {"VISUAL", "EDITOR"}) {
    const char* value = getenv(name);
    if (value != nullptr && *value != '\0') return value;
  }
  return "vi";
}

Status OpenInEditor(const std::string& command, const std::string& path) {
  // As a shell would while its child has the terminal: ^C and ^\ are the editor's, not ours.
  struct sigaction ignore = {};
  struct sigaction old_int = {};
  struct sigaction old_quit = {};
  ignore.sa_handler = SIG_IGN;
  sigemptyset(&ignore.sa_mask);
  sigaction(SIGINT, &ignore, &old_int);
  sigaction(SIGQUIT, &ignore, &old_quit);
  const std::string script = command + " \"$1\"";
  pid_t pid = fork();
  if (pid == 0) {
    signal(SIGINT, SIG_DFL);
    signal(SIGQUIT, SIG_DFL);
    execl("/bin/sh", "sh", "-c", script.c_str(), "sh", path.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  int status = 0;
  int saved = errno;
  if (pid > 0) {
    while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
  } else {
    saved = errno;
  }
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGQUIT, &old_quit, nullptr);
  const std::string hint = " (set EDITOR or VISUAL to an editor that waits until the file is closed)";
  if (pid < 0) return Status::Unavailable("cannot start the editor \"" + command + "\": " + std::strerror(saved));
  if (WIFSIGNALED(status)) {
    return Status::Unavailable("the editor \"" + command + "\" was killed by signal " +
                               std::to_string(WTERMSIG(status)));
  }
  const int code = WEXITSTATUS(status);
  if (code == 127) return Status::Unavailable("the editor \"" + command + "\" was not found" + hint);
  if (code != 0) {
    return Status::Unavailable("the editor \"" + command + "\" exited with status " + std::to_string(code) + hint);
  }
  return Status::Ok();
}

Result<EditOutcome> EditUntilSaved(const std::string& text, const std::string& dir, const std::string& stem,
                                   const EditEdges& edges, std::ostream& err) {
  std::string path = dir + "/sandswim-" + stem + "-XXXXXX.json";
  const int fd = mkstemps(path.data(), 5);
  if (fd < 0) return Status::IOError("cannot make a temporary file in " + dir + ": " + std::strerror(errno));
  close(fd);
  if (Status s = WriteText(path, text); !s.ok()) return s;

  EditOutcome outcome;
  std::string before = text;
  bool refused = false;
  while (true) {
    if (Status s = edges.open(path); !s.ok()) {
      return Status(s.code(), s.reason() + "; your text is kept in " + path, s.field());
    }
    auto after = ReadWholeFile(path);
    if (!after.ok()) return after.status();
    if (*after == before) {
      if (!refused) {
        unlink(path.c_str());
        outcome.kind = EditOutcome::Kind::kUnchanged;
        return outcome;
      }
      break;  // re-opened after a refusal and left as it was: the user gives up
    }
    before = *after;
    auto definition = ParseDefinition(*after);
    Result<json> saved = definition.ok() ? edges.save(*definition) : Result<json>(definition.status());
    if (saved.ok()) {
      unlink(path.c_str());
      outcome.kind = EditOutcome::Kind::kSaved;
      outcome.reply = *saved;
      return outcome;
    }
    refused = true;
    outcome.refusal = saved.status();
    err << "sandswim: " << Describe(saved.status()) << "\n";
    // A daemon that is not there, or a token it refuses, is not fixed in the editor.
    const StatusCode code = saved.status().code();
    if (code == StatusCode::kUnavailable || code == StatusCode::kUnauthenticated) break;
    if (!edges.ask("re-open the editor to fix it?")) break;
  }
  outcome.kind = EditOutcome::Kind::kKept;
  outcome.kept_path = path;
  return outcome;
}

}  // namespace sandswim::cli
