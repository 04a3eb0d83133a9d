#include "server/jobs/pilot_watch.h"

#include <set>
#include <sstream>

namespace sandswim {
namespace {

bool Final(const std::string& state) {
  static const std::set<std::string> kFinal = {"COMPLETED", "CANCELLED", "FAILED",   "TIMEOUT",      "NODE_FAIL",
                                               "PREEMPTED", "BOOT_FAIL", "DEADLINE", "OUT_OF_MEMORY"};
  return kFinal.count(state) > 0;
}

}  // namespace

Result<std::vector<std::string>> GoneSlurmJobs(const std::vector<std::string>& asked, const slurm::CommandOutput& out) {
  if (out.exit_code != 0) {
    if (out.err.find("Invalid job id") != std::string::npos) return asked;  // none of them is known
    return Status::Unavailable("squeue exited " + std::to_string(out.exit_code) + ": " + out.err.substr(0, 300));
  }
  std::set<std::string> alive;
  std::istringstream lines(out.out);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    std::string id, state;
    if (!(fields >> id >> state)) continue;
    // "CANCELLED by 0" prints as "CANCELLED"; states are one word in %T.
    if (!Final(state)) alive.insert(id);
  }
  std::vector<std::string> gone;
  for (const std::string& job : asked) {
    if (alive.count(job) == 0) gone.push_back(job);
  }
  return gone;
}

Result<PilotCheck> PilotWatch::CheckOnce() {
  PilotCheck check;
  const double asked_at = clock_->Now();  // leases granted later are not judged by this answer
  Result<std::vector<std::string>> jobs = leases_->RunningSlurmJobs();
  if (!jobs.ok()) return jobs.status();
  check.jobs = static_cast<int64_t>(jobs->size());
  if (jobs->empty()) return check;
  std::string list;
  for (const std::string& job : *jobs) list += (list.empty() ? "" : ",") + job;
  Result<slurm::CommandOutput> out = slurm_->Run({"squeue", "-h", "-t", "all", "-o", "%A %T", "-j", list});
  if (!out.ok()) return out.status();
  Result<std::vector<std::string>> gone = GoneSlurmJobs(*jobs, *out);
  if (!gone.ok()) return gone.status();
  for (const std::string& job : *gone) {
    Result<int64_t> n = leases_->ReclaimSlurmJob(job, asked_at);
    if (!n.ok()) return n.status();
    check.reclaimed += *n;
  }
  check.gone = std::move(*gone);
  return check;
}

}  // namespace sandswim
