// Job outcome: what a finished job's engine left behind means -- the pure half of running a job.
// The worker's runner (worker.h) prepares the run directory, supervises the engine and reports;
// this decides, from the exit facts, the engine log, the run's drive facts (its lease) and the
// SO's samples (read once, as the dump grew), whether the job failed and why, or what it found:
// a run's result and downsampled trajectory (core/trajectory.h), a bed's figures.
//
// Thread safety: a pure function.
#ifndef SANDSWIM_WORKERS_JOB_OUTCOME_H_
#define SANDSWIM_WORKERS_JOB_OUTCOME_H_

#include <cstdint>
#include <optional>
#include <vector>

#include "core/api.h"
#include "core/deck.h"
#include "core/engine_log.h"
#include "core/status.h"
#include "core/trajectory.h"

namespace sandswim::worker {

struct JobOutcome {
  std::optional<api::Failure> failure;
  // The failure is the engine's exit (ClassifyExit), which a stop of the whole worker may explain
  // (the runner then hands the job back instead of failing it).
  bool engine_exit = false;
  std::optional<api::BedResult> bed;          // an ok bed: the log's figures (the runner adds the restart's checksum)
  std::optional<api::RunResult> result;       // an ok run
  std::optional<api::Trajectory> trajectory;  // an ok run, downsampled
};

// `samples` are the SO's samples of the run's dump (or why it could not be read); ignored for beds.
// `precision` is the run's target (its lease's): the result says whether it was met.
// `bed_dump` is a bed's dump of all its atoms (core/bed_figures.h), absent when the deck wrote
// none: its figures join the log's. A bed that missed the kinetic-energy criterion fails as
// "not_equilibrated" with its figures (the daemon does not retry it: the same deck gives the same
// bed).
// Why the lease's deck is not the job its content key names (core/keys.h: the key recomputed from
// the deck, the bed's key for a run, and the lease's key_engine), or nullopt when it is -- or when
// the lease cannot say (no key_engine: an older daemon, a deck stored before migration 3). The
// worker runs the deck text it is sent: one that does not match its key is not run
// ("key_mismatch").
std::optional<api::Failure> CheckDeckKey(const api::LeaseGrant& grant);

JobOutcome JudgeJob(api::JobKind kind, int64_t expected_steps, const ExitFacts& facts, const EngineLog& log,
                    const DriveInfo& drive, const Result<std::vector<SoSample>>& samples,
                    const std::optional<PrecisionTarget>& precision = std::nullopt,
                    const std::optional<std::string>& bed_dump = std::nullopt);

// Whether a run that follows a precision target should end now: core/precision.h DecideStop on
// the analysis its result will be made with, of the samples so far. `start` is the log's drive
// start marker (it gives the bed surface); without it the surface's clearance is not checked.
StopVerdict FollowRun(const std::vector<SoSample>& so_far, const DriveInfo& drive,
                      const std::optional<DriveStartMarker>& start, const PrecisionTarget& target);

}  // namespace sandswim::worker

#endif  // SANDSWIM_WORKERS_JOB_OUTCOME_H_
