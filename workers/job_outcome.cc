#include "workers/job_outcome.h"

#include <string>

#include "core/deck.h"

namespace sandswim::worker {

JobOutcome JudgeJob(api::JobKind kind, int64_t expected_steps, const ExitFacts& facts, const EngineLog& log,
                    const DriveInfo& drive, const Result<std::vector<SoSample>>& samples,
                    const std::optional<PrecisionTarget>& precision) {
  JobOutcome out;
  if (auto failure = ClassifyExit(kind, facts, log, expected_steps)) {
    out.failure = *failure;
    out.engine_exit = true;
    return out;
  }
  if (kind == api::JobKind::kBed) {
    api::BedResult bed;  // a completed bed has its grain figures (ClassifyExit)
    bed.grains = log.bed_grains->grains;
    bed.so_z = log.bed_grains->so_z;
    bed.grain_top = log.bed_grains->grain_top;
    if (log.bed_equilibrium) {
      bed.equilibrated = log.bed_equilibrium->equilibrated;
      bed.ke_ratio = log.bed_equilibrium->ke_peak > 0 ? log.bed_equilibrium->ke / log.bed_equilibrium->ke_peak : 0;
    }
    out.bed = bed;
    return out;
  }
  if (!samples.ok()) {
    out.failure = api::Failure{"bad_output", std::string(kTrajectoryDumpFile) + ": " + samples.status().reason()};
    return out;
  }
  auto result = AnalyzeRun(*samples, RunInputsFrom(drive, log, precision));
  if (!result.ok()) {
    out.failure = api::Failure{"bad_output", result.status().reason()};
    return out;
  }
  out.result = *result;
  out.trajectory = Downsample(*samples);
  return out;
}

StopVerdict FollowRun(const std::vector<SoSample>& so_far, const DriveInfo& drive,
                      const std::optional<DriveStartMarker>& start, const PrecisionTarget& target) {
  EngineLog log;
  log.drive_start = start;
  auto r = AnalyzeRun(so_far, RunInputsFrom(drive, log, target));
  if (!r.ok()) return StopVerdict::kContinue;  // too few samples yet
  return DecideStop(*r, target);
}

}  // namespace sandswim::worker
