#include "cli/slurm_submit.h"

#include <unistd.h>

namespace sandswim::cli {

#ifndef SANDSWIM_SLURM_SCRIPTS_INSTALLED
#define SANDSWIM_SLURM_SCRIPTS_INSTALLED "/usr/local/share/sandswim/slurm"
#endif
#ifndef SANDSWIM_SLURM_SCRIPTS_SOURCE
#define SANDSWIM_SLURM_SCRIPTS_SOURCE ""
#endif

std::string DefaultSlurmScriptsDir(const char* env_value) {
  if (env_value != nullptr && *env_value != '\0') return env_value;
  const std::string installed = SANDSWIM_SLURM_SCRIPTS_INSTALLED;
  if (access((installed + "/pilot.sbatch").c_str(), R_OK) == 0) return installed;
  return SANDSWIM_SLURM_SCRIPTS_SOURCE;
}

Result<SlurmSubmission> SubmitToSlurm(slurm::SlurmCommands& slurm, const SlurmSubmitOptions& options) {
  if (options.server.rfind("http://", 0) != 0 && options.server.rfind("https://", 0) != 0) {
    return Status::InvalidArgument("--server", "the daemon URL the compute nodes reach, http://HOST:PORT");
  }
  slurm::PilotRequest request = options.request;
  if (options.end_margin_s >= 0) request.end_margin_s = options.end_margin_s;
  if (request.script.empty()) {
    if (options.scripts_dir.empty()) {
      return Status::InvalidArgument("--script", "no batch script: pass --script or set $SANDSWIM_SLURM_SCRIPTS");
    }
    request.script = options.scripts_dir + (request.array > 0 ? "/array.sbatch" : "/pilot.sbatch");
  }
  if (access(request.script.c_str(), R_OK) != 0) {
    return Status::InvalidArgument("--script", "cannot read the batch script " + request.script);
  }
  auto argv = slurm::PilotSbatchArgs(request);
  if (!argv.ok()) {
    // The request's fields are named like the flags: "nodes" -> "--nodes".
    const Status& s = argv.status();
    return Status(s.code(), s.reason(), s.field().empty() ? "" : "--" + s.field());
  }
  SlurmSubmission out;
  out.sbatch = *argv;
  std::vector<std::pair<std::string, std::string>> env = {{"SANDSWIM_SERVER", options.server},
                                                          {"SANDSWIM_RANKS", std::to_string(request.ranks_per_run)}};
  if (!options.worker.empty()) env.emplace_back("SANDSWIM_WORKER", options.worker);
  if (!options.workdir.empty()) env.emplace_back("SANDSWIM_WORKDIR", options.workdir);
  if (options.end_margin_s >= 0) env.emplace_back("SANDSWIM_END_MARGIN", std::to_string(options.end_margin_s));
  out.env = env;
  if (!options.token.empty()) {
    env.emplace_back("SANDSWIM_TOKEN", options.token);
    out.env.emplace_back("SANDSWIM_TOKEN", "(set)");
  }
  auto ran = slurm.Run(*argv, env);
  if (!ran.ok()) return ran.status();
  if (ran->exit_code != 0) {
    std::string why = ran->err.empty() ? ran->out : ran->err;
    while (!why.empty() && (why.back() == '\n' || why.back() == ' ')) why.pop_back();
    return Status::FailedPrecondition("sbatch", "Slurm refused the job: " + why);
  }
  auto id = slurm::ParseSbatchJobId(ran->out);
  if (!id.ok()) return id.status();
  out.job_id = *id;
  return out;
}

}  // namespace sandswim::cli
