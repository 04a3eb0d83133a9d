// Calibration of the claims' rules on the truth engine (tests/truth/truth_law.h): whole campaigns
// simulated in process through the project's real analysis and claims code, so that the error
// rates of whatever rules are linked are measured, not assumed.
//
// One simulated campaign (Calibrator::Simulate): the campaign's sweeps planned at the design's
// scale as the daemon plans them (core/sweep.h PlanSubmission: points shared by sweeps run once,
// durations and precision targets at the scale); each run's trajectory from the truth engine on
// its replicate bed (the bed effect shared by the campaign's runs on that bed); the worker's part
// as the worker does it: a run with a precision target is followed (workers/job_outcome.h
// FollowRun, on the samples so far, every `follow_every_s` of simulated time and at each whole
// block) and asked to stop, which takes effect `follow_lag_s` later; the result is
// AnalyzeRun(samples, RunInputsFrom(drive, log, target)) as in JudgeJob; the rows of each sweep go
// through the daemon's own pure path (server/analysis/report.h AnalyzeSweepResults, server/analysis/claim_check.h
// ClaimSweepOf) into a ClaimInput, then EvaluateClaims.
//
// Thread safety: a Calibrator is immutable after construction; Simulate may run on many threads.
#ifndef SANDSWIM_TESTS_TRUTH_CALIBRATION_H_
#define SANDSWIM_TESTS_TRUTH_CALIBRATION_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/claim_rates.h"
#include "core/claims.h"
#include "core/status.h"
#include "core/sweep.h"
#include "server/store/store.h"
#include "tests/truth/truth_law.h"

namespace sandswim::truth {

struct Design {
  std::string campaign = "paper-58";  // a built-in campaign
  std::string scale = "smoke";
  int beds = 0;                       // K replicate beds per point (0: the campaign's, 1 by default)
  double duration_multiplier = 1;     // on every asked duration and the precision target's maximum
  bool precision = true;              // false: no precision target (each run lasts its asked duration)
  bool follow = true;                 // false: targets and durations as planned, but no worker ends
                                      // a run early (a fast stand-in engine outruns the worker)
  double follow_every_s = 0.02;       // s of simulated time between the worker's looks
  double follow_lag_s = 0.02;         // s from its request to the run's end
};

// One run of a simulated campaign.
struct SimRun {
  Point point;
  int replicate = 0;
  double true_uz = 0;  // the bed's (what the run estimates)
  double law_uz = 0;   // the law's (over beds)
  double planned_s = 0, simulated_s = 0;
  std::string stop_reason;
  bool has_target = false;
  std::optional<api::RunResult> result;  // absent: the analysis refused the dump
  std::string failure;
};

struct SimCampaign {
  std::vector<SimRun> runs;             // in plan order
  std::vector<ClaimVerdict> verdicts;   // in the campaign's claims' order
  std::vector<ClaimSweep> sweeps;       // as EvaluateClaims saw them
  std::vector<ClaimBed> beds;           // as EvaluateClaims saw them
};

class Calibrator {
 public:
  static Result<Calibrator> Make(const Design& design);
  // `world`: the draw of beds and noise (the same world gives the same campaign).
  SimCampaign Simulate(const Law& law, const Noise& noise, uint64_t world, uint64_t night = 0) const;
  // One run as Simulate runs each (the worker following it to `target`), on `bed`, lasting at most
  // `duration_s`; `row` (when given) gets the store's row for it, run id `run_id`.
  SimRun RunOne(const Law& law, const Noise& noise, const Bed& bed, const Point& point, double duration_s,
                const std::optional<PrecisionTarget>& target, uint64_t world, uint64_t night, int64_t run_id,
                ResultRow* row = nullptr) const;
  const Campaign& campaign() const { return campaign_; }
  const Scale& scale() const { return *scale_; }
  const Design& design() const { return design_; }
  const Plan& plan() const { return plan_; }
  const std::vector<Claim>& claims() const { return campaign_.claims; }
  double PlannedSimSeconds() const;  // sum of the runs' planned durations
  // The design's key as the verdicts compute it (core/claim_rates.h): the campaign's definition
  // hash, the scale, K = the plan's beds, the rules' and the analysis's versions.
  DesignKey Key() const;

 private:
  Design design_;
  Campaign campaign_;
  Plan plan_;
  const Scale* scale_ = nullptr;
  // Per sweep (campaign order): its name and rows as plan indexes, in the store's order
  // (expansion order, replicate beds inside).
  std::vector<std::pair<std::string, std::vector<size_t>>> sweep_rows_;
};

// Whether a claim part is true under a law (nullopt: the law does not decide it -- F6, the grain
// count; F2's "past |Omega|" part, which is about the box, not the rate; F2 under sign_wrong).
// `part` "" asks about the whole claim: false when a part is, true when every part decided is true
// and none is undecided.
std::optional<bool> TruthOf(const Law& law, const std::string& claim_id, const std::string& part);

// Counts of verdicts, per law, claim and part ("" the whole claim), with the runs' coverage.
struct Counts {
  int64_t holds = 0, differs = 0, inconclusive = 0;
  int64_t n() const { return holds + differs + inconclusive; }
};
struct Coverage {
  int64_t n = 0, covered = 0;
};
struct LawTally {
  std::string law;
  int64_t campaigns = 0;
  std::map<std::pair<std::string, std::string>, Counts> cells;  // (claim id, part) -> counts
  std::vector<std::pair<std::string, std::string>> order;       // first-seen order of the cells
  Coverage runs_all, runs_stopped_early, runs_full, points_vs_law;
  Coverage points_stopped_early;  // points vs law, those with a run stopped at its precision target
  int64_t runs = 0, conclusive = 0;
  double sum_rel_error = 0;  // over conclusive runs: (U_z - true) / |true|
  double simulated_s = 0;    // summed over campaigns
  double seconds = 0;        // wall time spent
  void Add(const SimCampaign& c, const Law& law);
};
// Simulates `campaigns` worlds (seeds first_world, first_world + 1, ...) on `threads` threads.
LawTally RunLaw(const Calibrator& cal, const Law& law, const Noise& noise, int64_t campaigns, uint64_t first_world,
                int threads);

// The markdown table of tallies (one row per law, claim and part) and its JSON: the table the
// verdicts quote (core/claim_rates.h), its "design" holding the key and the noise it was made with.
std::string CalibrationMarkdown(const std::vector<LawTally>& tallies, const Design& design);
nlohmann::json CalibrationJson(const std::vector<LawTally>& tallies, const Calibrator& cal, const Noise& noise);
nlohmann::json NoiseToJson(const Noise& noise);

// The drift report (server/analysis/drift_report.h CompareWithPrevious, core/drift.h, the campaign's
// derived tolerance): two nights of the same campaign on the same beds with new run noise, the
// second under `law` with every U_z times `change` (1: nothing changed, so every flag is a false
// alarm; else the flags are the power to see that change). Per run, per point (over its beds), and
// per campaign: some point drifted at 5 % per point, and the campaign drifted (Holm, family-wise
// 5 %). Rule 1 (a normal quantile per run, core/drift.h) on the same runs, beside it.
struct DriftAlarms {
  int64_t campaigns = 0;
  int64_t runs_compared = 0, runs_drifted = 0, points_compared = 0, points_drifted = 0;  // the current rule
  int64_t campaigns_any_point = 0;  // at least one point drifted (5 % per point)
  int64_t campaigns_drifted = 0;    // the campaign drifted (Holm)
  int64_t runs_drifted_rule1 = 0;   // of runs_compared
  int64_t campaigns_any_run_rule1 = 0;
};
DriftAlarms MeasureDriftAlarms(const Calibrator& cal, const Law& law, const Noise& noise, int64_t campaigns,
                               uint64_t first_world, int threads, double change = 1);

}  // namespace sandswim::truth

#endif  // SANDSWIM_TESTS_TRUTH_CALIBRATION_H_
