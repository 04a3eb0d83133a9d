#include "workers/job_outcome.h"

#include <cstdio>
#include <string>

#include "core/bed_figures.h"
#include "core/deck.h"
#include "core/keys.h"

namespace sandswim::worker {

namespace {

std::string Sci(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2g", v);
  return buf;
}

// A completed bed: its log's figures and its dump's (core/bed_figures.h); a bed that missed the
// kinetic-energy criterion is not used.
JobOutcome JudgeBed(const EngineLog& log, const std::optional<std::string>& bed_dump) {
  JobOutcome out;
  api::BedResult bed;  // a completed bed has its grain figures (ClassifyExit)
  bed.grains = log.bed_grains->grains;
  bed.so_z = log.bed_grains->so_z;
  bed.grain_top = log.bed_grains->grain_top;
  if (log.bed_equilibrium) {
    bed.equilibrated = log.bed_equilibrium->equilibrated;
    bed.ke_ratio = log.bed_equilibrium->ke_peak > 0 ? log.bed_equilibrium->ke / log.bed_equilibrium->ke_peak : 0;
  }
  if (bed_dump) {
    Result<BedFigures> f = MeasureBed(*bed_dump);
    if (!f.ok()) {
      out.failure = api::Failure{"bad_output", std::string(kBedDumpFile) + ": " + f.status().reason()};
      return out;
    }
    bed.bed_height = f->bed_height;
    bed.so_depth = f->so_depth;
    bed.packing_fraction = f->packing_fraction;
    bed.shell_grains = f->shell_grains;
  }
  if (log.bed_equilibrium && !bed.equilibrated) {
    out.failure = api::Failure{
        "not_equilibrated",
        "the bed missed the kinetic-energy criterion (Sec. 2.3): after its undamped check the kinetic energy was " +
            Sci(bed.ke_ratio) + " of its peak, not <= 1e-4 (" + std::to_string(bed.grains) +
            " grains, highest at z = " + Sci(bed.grain_top) +
            " m); it is not used and its runs fail with it. "
            "A bed this far from rest needs a longer equilibration (templates/bed.in check_samples)"};
    return out;
  }
  out.bed = bed;
  return out;
}

}  // namespace

std::optional<api::Failure> CheckDeckKey(const api::LeaseGrant& grant) {
  if (grant.key_engine.empty()) return std::nullopt;
  const bool run = grant.kind == api::JobKind::kRun;
  if (run && (!grant.bed || grant.bed->key.empty())) {
    return api::Failure{"key_mismatch", "the run's lease names no bed key: its deck cannot be checked against its "
                                        "content key, and is not run"};
  }
  const std::string key = run ? RunKey(grant.deck, grant.bed->key, grant.key_engine) : BedKey(grant.deck, grant.key_engine);
  if (key == grant.key) return std::nullopt;
  return api::Failure{"key_mismatch",
                      "the deck sent with the lease hashes to content key " + key + ", not the lease's " + grant.key +
                          ": it was changed on its way (or the daemon and this worker disagree on how keys are made: "
                          "run the same sandswim version on both); not run. Serve the daemon over HTTPS "
                          "(sandswimd --tls) when workers reach it over a network"};
}

JobOutcome JudgeJob(api::JobKind kind, int64_t expected_steps, const ExitFacts& facts, const EngineLog& log,
                    const DriveInfo& drive, const Result<std::vector<SoSample>>& samples,
                    const std::optional<PrecisionTarget>& precision, const std::optional<std::string>& bed_dump) {
  JobOutcome out;
  if (auto failure = ClassifyExit(kind, facts, log, expected_steps)) {
    out.failure = *failure;
    out.engine_exit = true;
    return out;
  }
  if (kind == api::JobKind::kBed) return JudgeBed(log, bed_dump);
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
  return DecideStop(*r, PlanStop(so_far, *r, target));
}

}  // namespace sandswim::worker
