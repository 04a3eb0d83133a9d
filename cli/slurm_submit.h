// `sandswim slurm submit`: puts sandswim workers on a Slurm cluster, as a pilot (one long
// sandswim-worker per allocation, deploy/slurm/pilot.sbatch) or as a job array (one one-shot
// worker per element, deploy/slurm/array.sbatch).
//
// SubmitToSlurm builds the sbatch command (slurm::PilotSbatchArgs) and runs it through the
// injected slurm::SlurmCommands (tests: a fake). The daemon's URL, its token and the worker's
// settings reach the batch script as environment variables of the sbatch process
// (SANDSWIM_SERVER, SANDSWIM_TOKEN, SANDSWIM_RANKS, SANDSWIM_WORKER, SANDSWIM_WORKDIR,
// SANDSWIM_END_MARGIN), which sbatch exports to the job: the token never appears in an argv.
//
// Thread safety: none needed (values in, one sbatch call).
#ifndef SANDSWIM_CLI_SLURM_SUBMIT_H_
#define SANDSWIM_CLI_SLURM_SUBMIT_H_

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/status.h"
#include "platform/slurm.h"

namespace sandswim::cli {

struct SlurmSubmitOptions {
  slurm::PilotRequest request;  // request.script "" : pilot.sbatch / array.sbatch in scripts_dir
  std::string scripts_dir;      // where the batch scripts are
  std::string server;           // daemon URL as the compute nodes reach it
  std::string token;            // "" : the daemon has none
  std::string worker;           // sandswim-worker on the nodes ("" : on PATH)
  std::string workdir;          // run directories on the nodes ("" : the script's default)
  double end_margin_s = -1;     // < 0: the worker's default
};

struct SlurmSubmission {
  int64_t job_id = 0;
  std::vector<std::string> sbatch;                       // the command run
  std::vector<std::pair<std::string, std::string>> env;  // what it exported (token redacted)
};

// InvalidArgument naming the flag for bad options; FailedPrecondition with sbatch's own message
// when Slurm refuses the job; Unavailable when sbatch cannot be run.
Result<SlurmSubmission> SubmitToSlurm(slurm::SlurmCommands& slurm, const SlurmSubmitOptions& options);

// Where the batch scripts are by default: $SANDSWIM_SLURM_SCRIPTS, else the installed
// share/sandswim/slurm, else the source tree's deploy/slurm (a build that was not installed).
std::string DefaultSlurmScriptsDir(const char* env_value);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_SLURM_SUBMIT_H_
