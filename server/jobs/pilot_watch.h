// PilotWatch: frees the runs of Slurm jobs that are gone, sooner than their leases expire. A
// worker inside an allocation sends its SLURM_JOB_ID with every lease request; a pilot killed
// with its node, its worker SIGKILLed or killed at its time limit cannot hand its runs back, and
// they would otherwise wait out the lease TTL. CheckOnce() asks Slurm about the jobs that hold
// leases on running jobs now -- one `squeue -h -t all -o "%A %T" -j ID,ID,...` -- and reclaims
// (LeaseQueue::ReclaimSlurmJob) the leases of each job Slurm reports in a finished state or no
// longer knows, granted before it asked, whose worker has been silent for half the lease TTL.
// A job that is pending, running, suspended or still completing is left alone; when squeue cannot
// answer (not installed, controller down) nothing is reclaimed; and a worker that heartbeats is
// never reclaimed, even if squeue does not see its job (another cluster, PrivateData=jobs, a
// stale SLURM_JOB_ID). The TTL still applies to everything.
//
// GoneSlurmJobs is the pure part: which of the asked jobs squeue's output says are gone.
//
// Thread safety: CheckOnce() from one thread at a time (the daemon's watch thread).
#ifndef SANDSWIM_SERVER_JOBS_PILOT_WATCH_H_
#define SANDSWIM_SERVER_JOBS_PILOT_WATCH_H_

#include <cstdint>
#include <string>
#include <vector>

#include "core/status.h"
#include "platform/clock.h"
#include "platform/slurm.h"
#include "server/jobs/lease_queue.h"

namespace sandswim {

// The jobs of `asked` that squeue's answer (`out`, from the command above) shows gone: listed in a
// final state (COMPLETED, CANCELLED, FAILED, TIMEOUT, NODE_FAIL, PREEMPTED, BOOT_FAIL, DEADLINE,
// OUT_OF_MEMORY) or not listed at all. squeue exits 1 with "Invalid job id" when it knows none of
// them: all are gone. Unavailable for any other failure (the controller did not answer).
Result<std::vector<std::string>> GoneSlurmJobs(const std::vector<std::string>& asked, const slurm::CommandOutput& out);

struct PilotCheck {
  int64_t jobs = 0;               // Slurm jobs holding leases on running jobs
  std::vector<std::string> gone;  // of those, the ones Slurm no longer runs
  int64_t reclaimed = 0;          // runs and beds sent back to the queue (or failed)
};

class PilotWatch {
 public:
  // REQUIRES: both outlive the watch.
  PilotWatch(LeaseQueue* leases, slurm::SlurmCommands* slurm, Clock* clock)
      : leases_(leases), slurm_(slurm), clock_(clock) {}

  // One look: no squeue at all when no lease belongs to a Slurm job.
  Result<PilotCheck> CheckOnce();

 private:
  LeaseQueue* leases_;
  slurm::SlurmCommands* slurm_;
  Clock* clock_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_JOBS_PILOT_WATCH_H_
