// Slurm: the one boundary between sandswim and a Slurm cluster's client commands (sbatch, squeue,
// scontrol, scancel), and the pure logic around them.
//
// SlurmCommands runs one client command and returns what it printed. It is abstract so the
// pilot submission (cli `sandswim slurm submit`) and the worker's allocation deadline can be
// tested with a fake; ProcessSlurmCommands is the real one (platform/subprocess.h: no shell, so no
// argument is ever re-parsed; stdout and stderr captured).
//
// Pure functions (no processes): ParseSlurmDuration reads Slurm's time syntax (--time and
// squeue's %L); PilotSbatchArgs builds the sbatch command line of a pilot or an array;
// ParseSbatchJobId reads `sbatch --parsable`; ShouldLease is the worker's stop-leasing rule.
//
// Thread safety: ProcessSlurmCommands is thread-safe; AllocationDeadline is not (one per worker,
// called from the slots under the worker's lock or from one thread).
#ifndef SANDSWIM_PLATFORM_SLURM_H_
#define SANDSWIM_PLATFORM_SLURM_H_

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "core/status.h"
#include "platform/subprocess.h"

namespace sandswim::slurm {

using ::sandswim::CommandOutput;  // platform/subprocess.h

class SlurmCommands {
 public:
  virtual ~SlurmCommands() = default;
  // Runs argv (argv[0] looked up on PATH) with `env` added to this process's environment.
  // Unavailable when it cannot be started (Slurm's clients not installed); otherwise the exit
  // code and output, whatever the exit code.
  virtual Result<CommandOutput> Run(const std::vector<std::string>& argv,
                                    const std::vector<std::pair<std::string, std::string>>& env = {}) = 0;
};

// A command that has not finished after `timeout_s` is killed (SIGKILL) and reported Unavailable:
// a hung squeue never holds up the daemon's or the worker's shutdown.
class ProcessSlurmCommands : public SlurmCommands {
 public:
  // `processes` (default: the real ones) must outlive this.
  explicit ProcessSlurmCommands(double timeout_s = 60, Subprocesses* processes = nullptr)
      : timeout_s_(timeout_s), processes_(processes != nullptr ? processes : &posix_) {}
  Result<CommandOutput> Run(const std::vector<std::string>& argv,
                            const std::vector<std::pair<std::string, std::string>>& env = {}) override;

 private:
  double timeout_s_;
  PosixSubprocesses posix_;
  Subprocesses* processes_;
};

// Slurm's duration syntax, in seconds: "M", "M:S", "H:M:S", "D-H", "D-H:M", "D-H:M:S" (as sbatch
// --time takes it and squeue %L prints it). "UNLIMITED", "INFINITE", "NOT_SET": nullopt.
// InvalidArgument (field `field`) for anything else.
Result<std::optional<double>> ParseSlurmDuration(std::string_view text, const std::string& field = "time");

// A pilot (one long worker per allocation) or an array (one one-shot worker per element).
struct PilotRequest {
  int nodes = 1;
  int ranks_per_run = 1;
  int tasks_per_node = 0;  // CPUs (tasks) per node the pilot asks for; 0: ranks_per_run
  std::string time;        // Slurm duration, required
  int array = 0;           // > 0: a job array of this many elements, one run each
  int throttle = 0;        // array elements running at once (%k); 0: no limit
  std::string partition;   // "" : the cluster's default
  std::string account;
  std::string job_name = "sandswim";
  std::string script;         // deploy/slurm/pilot.sbatch or array.sbatch
  std::string output;         // sbatch --output pattern; "" : Slurm's default
  int signal_lead_s = 120;    // pilot: USR1 this long before the time limit (--signal=B:USR1@N)
  double end_margin_s = 300;  // the workers' --end-margin: a time limit at or under it leases nothing
};

// The sbatch argv (starting with "sbatch"); InvalidArgument naming the field for bad values
// (nodes, ranks_per_run < 1; time not a Slurm duration; throttle without array or > array; ...).
// The daemon URL, ranks and token reach the script through the environment (see
// deploy/slurm/README.md), never through argv, so the token is not visible in `ps`/squeue.
Result<std::vector<std::string>> PilotSbatchArgs(const PilotRequest& request);

// The job id from `sbatch --parsable` output ("123" or "123;cluster").
Result<int64_t> ParseSbatchJobId(std::string_view out);

// Whether a worker may lease one more run: yes when it is not in an allocation (`seconds_left`
// empty) or when the run would finish before the allocation ends. A run is expected to take
// `expected_run_s` (the longest run this worker has done) when known, else `margin_s`.
bool ShouldLease(std::optional<double> seconds_left, std::optional<double> expected_run_s, double margin_s);

// The end of a worker's allocation, asked of Slurm (`squeue -h -j ID -o %L`) and cached for
// `refresh_s` (an admin may extend the time limit; slurmctld should not be asked per lease).
// `now` is a monotonic clock in seconds.
class AllocationDeadline {
 public:
  AllocationDeadline(SlurmCommands& slurm, std::string job_id, std::function<double()> now, double refresh_s = 60);
  // Seconds until the allocation ends; nullopt when it has no limit. When Slurm cannot be
  // asked, the last known answer counts down (and the error is returned when there is none).
  Result<std::optional<double>> SecondsLeft();

 private:
  SlurmCommands& slurm_;
  std::string job_id_;
  std::function<double()> now_;
  double refresh_s_;
  bool known_ = false;
  double asked_at_ = 0;
  std::optional<double> left_at_ask_;
};

}  // namespace sandswim::slurm

#endif  // SANDSWIM_PLATFORM_SLURM_H_
