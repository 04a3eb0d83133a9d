// Cost model: what runs and beds cost in engine time, and when a set of them will be done.
//
// A run costs particles x steps x the wall seconds one particle-step takes (the engine's rate) on
// the host and rank count it runs on. Particles and steps are known before a run starts: the bed's
// grains (before the bed exists, an estimate from the box's volume, EstimatedGrains) plus the SO,
// and the deck's step count (core/deck.h DriveSteps: its most; a precision target or a boundary
// may end it earlier). The rate is measured, never assumed from the paper: FitRate pools the runs
// done so far (a result's steps, grains and wall time) and the progress of running ones (their
// simulated steps over their wall time so far, so an estimate exists from a run's first minute).
// Before anything has run, DefaultRate() is the rate measured on this project's 2-core machine. A bed is costed per grain the same way (its preparation's wall time
// over its grains; DefaultBedRate before one is done).
//
// Every estimate carries a relative 1-sigma error and says what it rests on ("basis"), so the
// CLI, the API and the dashboard can show "5h10m ± 40m (from 12 runs on this host)".
//
// Thread safety: pure functions and values.
#ifndef SANDSWIM_CORE_COST_H_
#define SANDSWIM_CORE_COST_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/scale.h"
#include "core/sweep.h"

namespace sandswim {

// The smoke bed (6,683 particles) driven on one rank of this project's 2-core machine: 1.4-1.8e6
// particle-steps/s with the other core busy; bench_engine_rate measured 6.3e5-1.0e6
// while the machine's load average was 10-11. The error says how far a new host may differ; any
// measured run replaces it.
inline constexpr double kDefaultSecondsPerParticleStep = 6.5e-7;
inline constexpr double kDefaultRateRelError = 0.3;
// A smoke bed of 6,682 grains took 708-840 s on one rank (docs/measurements.md, the baseline on three replicate beds).
inline constexpr double kDefaultBedSecondsPerGrain = 0.115;
// A fitted rate is never claimed better than this: the host's other work comes and goes.
inline constexpr double kMinRateRelError = 0.1;

// One measured stretch of engine work: `work` particle-steps (a run) or grains (a bed) done in
// `wall_s` seconds.
struct RateSample {
  double work = 0;
  double wall_s = 0;
};

// Wall seconds per unit of work (a particle-step, or a grain of a bed), with its relative 1-sigma
// error as a predictor of more work of the same kind, and what it rests on.
struct EngineRate {
  double s_per_unit = 0;
  double rel_error = 0;
  int samples = 0;  // 0: a default, not a measurement
  std::string basis;
};

EngineRate DefaultRate();     // drive runs, per particle-step
EngineRate DefaultBedRate();  // bed preparation, per grain

// An engine rate measured on `ranks` MPI ranks (the cost model keeps runs' and beds' per rank count).
struct RankRate {
  int ranks = 1;
  EngineRate rate;
};
// One smoke run on 2 ranks did 1.42x the particle-steps per second of one rank (this
// project's 2-core machine, both cores free for it). For a rank count nothing was measured on, each
// doubling of ranks is taken to be this much faster; the guess's relative error is
// kDefaultRateRelError, added to the rate's own.
inline constexpr double kDefaultTwoRankSpeedup = 1.42;
// The bed rate (per grain) on `ranks` ranks: the one `by_ranks` holds for that rank count; else
// its one-rank rate (DefaultBedRate() when it has none) over kDefaultTwoRankSpeedup^log2(ranks),
// its basis saying so. ranks < 1 counts as 1.
EngineRate BedRateOnRanks(const std::vector<RankRate>& by_ranks, int ranks);

// Pools the samples: total wall time over total work. Error: the samples' own rates' relative
// spread over sqrt(n), at least kMinRateRelError; with one sample, the larger of that floor and
// half the default's error. Samples with no work or no time are left out; none left: `fallback`.
EngineRate FitRate(const std::vector<RateSample>& samples, const EngineRate& fallback, const std::string& basis);

// ---- The machine's current share -------------------------------------------------------------

// How far back the running runs' progress is read to say what share of the machine they get now.
inline constexpr double kShareWindowS = 600;
// A run's stretch in a window counts once it spans this long (a heartbeat's step is a dump's).
inline constexpr double kMinShareStretchS = 120;

// The running runs' rate now against the cost model's: `factor` = their wall seconds per
// particle-step over the last window / the model's (3: they run at a third of their usual rate),
// from every live running run's stretch in the window, pooled (total wall over total work).
//
// The rule (chosen by its error on the real record, tests/bench/eta_replay.py): the ETA's rates are
// the model's times `scale` = sqrt(factor), halfway (geometrically) between the long-run rate and
// the last window's, because the share of a loaded machine moves within minutes and neither end
// foretells the next hour alone. Its relative error, added in quadrature to the rate's, is
// hypot(|ln factor| / 2, |ln(factor / factor_before)|): how far the truth may lie toward either end,
// and how much the share moved from the window before (or, before there is one, from the runs'
// attempts so far). The error is a half-range on a log scale: the ETA's band is s / e^r .. s x e^r.
// Chosen and scored on the same 5 runs of the density-ratio campaign (in-sample): it erred by 24 %
// (median; the long average 31 %, the last window alone 29 %) and its 1 sigma held the truth 67 %
// of the time (13 %, 41 %). Left one run out (chosen on the other four, scored on the fifth), the
// rule chosen was this one each time (once with no rule meeting the 60 % coverage on the four) and
// held out it erred by 24 % (median over the 69 held-out predictions; 13 % to 88 % by run) and
// covered 67 % (38 % to 93 % by run). Five runs on one loaded machine, their readings not
// independent: the 1 sigma is not calibrated.
struct Share {
  bool measured = false;  // false: no running run spans kMinShareStretchS in the window
  double factor = 1;
  double scale = 1;       // sqrt(factor): what the rates are multiplied by
  int engines = 0;        // the runs it rests on
  double window_s = 0;    // the longest stretch it rests on
  std::optional<double> factor_before;
  std::string before_basis;  // "the 10 min before" | "their attempts so far"
  double rel_error = 0;   // hypot(|ln factor| / 2, |ln(factor / factor_before)|)
};
// `recent`: each live running run's stretch in the last window (particle-steps done, wall time);
// `before`: the window before it, where the run has one; `so_far`: each run's whole attempt. The
// ETA's rates are AtShare(model rate, share).
Share CurrentShare(const std::vector<RateSample>& recent, const std::vector<RateSample>& before,
                   const std::vector<RateSample>& so_far, const EngineRate& model, double window_s);
// `rate` at the current share: s_per_unit x scale, its error widened by the share's (in
// quadrature), its basis saying what it used ("2 engines at 0.31 of that rate over the last 10
// min ...; taken halfway: 0.56"). Unmeasured: `rate` unchanged.
EngineRate AtShare(const EngineRate& rate, const Share& share);

// ---- Before work: what a plan costs ------------------------------------------------------------

struct PlanCost {
  int64_t runs = 0;
  int64_t beds = 0;
  double particle_steps = 0;  // at most (every run to its deck's end)
  double run_core_s = 0;      // particle_steps x rate (one rank a run)
  double bed_core_s = 0;      // every bed on one rank
  double rel_error = 0;
  // Wall time on `slots` engines of one rank each: beds first (one slot each, in parallel), then
  // the runs spread over every slot; never less than the longest bed plus its longest run.
  double WallSeconds(int slots) const;
  double longest_bed_s = 0, longest_run_s = 0;
  // Each bed's work in grains of a Table 1 bed (its grains x Table 1's step over its own), and the
  // run rate's error alone: what PlanWallOn needs to cost beds on other rank counts.
  std::vector<double> bed_work;
  double run_rel_error = 0;
};
// A plan's runs (core/sweep.h: each its deck's steps at its materials' time step, on
// plan.beds[bed]) and beds; bed_grains[i] is plan.beds[i]'s grain count where known (a bed
// prepared already), else EstimatedGrains(plan's scale, the bed's materials) is used, and a bed
// costs its grains times Table 1's step over its own (core/materials.h TimeStep). Every run takes
// grains + 1 (the SO) particles.
PlanCost CostOfPlan(const Plan& plan, const std::vector<std::optional<double>>& bed_grains,
                    const EngineRate& run_rate, const EngineRate& bed_rate);

// The ranks each of a plan's `beds` beds is prepared on by a worker of `slots` one-rank slots that
// lends its idle slots' cores to a job granted with the queue dry, up to `max_ranks` ranks in all
// (workers/worker.h; `sandswimd --local-workers N` starts such a worker with N slots and
// --max-ranks N; other workers only with --max-ranks). The lease queue grants beds before runs,
// one a slot; each grant but the last bed's finds another bed still leasable, and the last bed's
// finds nothing (every run waits for a bed: core/api.h LeaseGrant::queue_dry), so it takes the
// slots still idle: slots - beds + 1 ranks when beds <= slots, capped at max_ranks; with more
// beds than slots the last one is granted while the others still run: 1. Runs are costed on one
// rank (the queue's last runs may be widened too: an upper bound).
std::vector<int> BedRanks(int beds, int slots, int max_ranks);

// A plan's wall time on `slots` one-rank slots of such a worker (max_ranks <= 1: no widening),
// with each bed on its BedRanks at BedRateOnRanks(bed_rates, ranks); otherwise as
// PlanCost::WallSeconds: beds first, then the runs over every slot, never less than the longest
// bed plus the longest run.
struct PlanWall {
  double s = 0;
  double rel_error = 0;        // 1 sigma: the run rate's and the beds' (at their ranks), by their time
  std::vector<int> bed_ranks;  // as BedRanks
};
PlanWall PlanWallOn(const PlanCost& cost, int slots, int max_ranks, const std::vector<RankRate>& bed_rates);

// ---- During work: when will it be done ---------------------------------------------------------

// One thing left to do in a sweep or campaign run.
struct WorkLeft {
  enum class Kind { kRun, kBed } kind = Kind::kRun;
  bool running = false;
  double particles = 0;    // run: grains + SO; bed: grains (estimated while not prepared)
  int64_t steps = 0;       // run: the deck's most
  int64_t steps_done = 0;  // run: from its progress (simulated time / dt)
  double elapsed_s = 0;    // running: wall time since it started
  // Run with a precision target: the earliest step its target can end it at (core/precision.h
  // EarliestTargetStopS); it ends somewhere between this and `steps`. 0: no target.
  int64_t min_steps = 0;
};

// The share of their deck's steps the scope's done runs used (a precision target or a boundary
// ends runs early): what the runs left are expected to use.
struct StepShare {
  int done = 0;      // done runs it rests on; 0: none yet (mean and sd unused)
  double mean = 1;   // their mean share
  double sd = 0;     // one run's share's standard deviation about that mean
};

struct Eta {
  double seconds = 0;
  double rel_error = 0;  // 1 sigma
  std::string basis;     // what the rates rest on, and what the estimate assumes
};

// Work left over `slots` engines (at least 1). What each run left is expected to take:
//   - before any run of the scope is done: a run with a precision target ends anywhere between
//     its earliest target stop and its deck's end, so it is expected at the middle of what is left
//     of that range, with the range's spread (its length / sqrt(12)) as its error, one error for
//     all of them (one campaign's runs reach their targets alike); a run without a target counts
//     to its deck's end;
//   - once some are done: `share` of its steps (inside its range), with two errors: the share's
//     own scatter, run by run, and its mean's (sd / sqrt(done)), the same for every run (sd
//     widened by Student's t at one sigma for done - 1 degrees of freedom). A run
//     that has already outlived the share is expected at the middle of the rest of its range.
// Either error is never more than half the run's range allows. A running bed's remaining time is
// its estimate less its elapsed time, at least 0. As PlanCost::WallSeconds: the beds left first
// (their runs wait for them; beds share the slots), then the runs over every slot, and never less
// than the longest bed plus the longest run (one engine cannot be shared). The stated error
// combines the rates' errors and the runs' lengths'. nullopt when nothing is left.
std::optional<Eta> EstimateEta(const std::vector<WorkLeft>& left, const EngineRate& run_rate,
                               const EngineRate& bed_rate, const StepShare& share, int slots);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_COST_H_
