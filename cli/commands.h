// Commands: every `sandswim` subcommand, in one table (commands.cc, kCommands, read top to
// bottom): name, one-line summary, examples for --help, how it declares its flags, what it runs.
//
// RunCli() parses argv with CLI11 and runs one subcommand. Everything outside the process is in
// Environment, so tests can run commands against a fake daemon and capture the output.
//
// Output: data on `out`, diagnostics (errors, submission summaries, the progress of
// `submit --wait`) on `err`. Every error is ONE line "sandswim: <reason>".
// Exit codes: kExitOk, kExitError (the daemon refused, is not there, an unknown id, ...),
// kExitUsage (bad arguments: CLI11's parse errors and malformed ids), kExitRunsFailed (the runs
// finished, but some failed: `watch`, `submit --wait`). Cancelled runs are not failures.
//
// Colour: only when the stream is a terminal, $NO_COLOR is unset or empty, $TERM is not "dumb",
// and --no-color was not given.
//
// Thread safety: RunCli() uses the Environment from the calling thread only.
#ifndef SANDSWIM_CLI_COMMANDS_H_
#define SANDSWIM_CLI_COMMANDS_H_

#include <functional>
#include <iosfwd>
#include <memory>
#include <string>
#include <vector>

#include "cli/client.h"
#include "core/status.h"
#include "platform/clock.h"
#include "platform/slurm.h"

namespace sandswim::cli {

inline constexpr int kExitOk = 0;
inline constexpr int kExitError = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitRunsFailed = 3;

struct Environment {
  std::ostream* out = nullptr;
  std::ostream* err = nullptr;
  std::istream* in = nullptr;
  bool out_is_tty = false;
  bool err_is_tty = false;
  std::function<const char*(const char*)> getenv;
  Clock* clock = nullptr;  // watch's time and sleep (tests: a FakeClock; nullptr: the system's)
  // Makes the REST client (tests: a fake).
  std::function<std::unique_ptr<DaemonClient>(const ClientOptions&)> make_client;
  // The LIGGGHTS version string for `expand` when --engine-version is not given.
  std::function<Result<std::string>()> probe_engine;
  // Runs Slurm's client commands for `slurm submit` (tests: a fake; unset: the real ones).
  std::function<std::unique_ptr<slurm::SlurmCommands>()> make_slurm;
  // Opens a file in the user's editor for `campaign edit` and waits (tests: a fake; unset:
  // cli/campaign_edit.h OpenInEditor, on this terminal).
  std::function<Status(const std::string& command, const std::string& path)> run_editor;
};

// Parses argv (argv[0] is the program name) and runs the subcommand. Returns the exit code.
int RunCli(int argc, const char* const* argv, Environment& env);

// Names of the subcommands, in table order (for tests and docs).
std::vector<std::string> CommandNames();

// The client's version ("0.1.0").
const char* ClientVersion();

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_COMMANDS_H_
