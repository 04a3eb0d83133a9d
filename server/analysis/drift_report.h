// DriftReport: after a campaign run finishes (every run of its sweeps is done, failed or
// cancelled), per run and per point, U_z now vs the previous report of the same campaign and
// scale, flagged where it changed. The decision is core/drift.h's (DecideDrift, drift rule
// `rule`): rule 2 holds a run's change to the 95 % bound of the difference from both runs' own
// errors with Welch's degrees of freedom (Student t), a point's to that of its beds' mean paired
// difference (each bed against itself: the bed's effect cancels), and, when the campaign sets
// drift_tolerance_mps (> 0), also to that tolerance: the one of the definition the campaign run
// recorded, not the campaign's current one (drift_report.cc DriftToleranceOf). A rate without an error is not compared
// ("no error"). Across the campaign's points, Holm's procedure at family-wise 5 % says whether the
// campaign as a whole drifted (`campaign_drifted`); `false_alarms` quotes the rule's false-alarm
// rates measured on the truth engine at the design (core/drift.h DriftAlarmText).
//
// Reports are stored (table drift_reports, schema/002_nightly.sql), one per campaign run, and
// keep the U_z values they saw: a forced rerun replaces the result row of a run it shares with
// earlier campaign runs, so "before" must come from the earlier report, not from `results`.
// Runs are matched across reruns by their drive (PointToJson of the point, duration included)
// and replicate bed, not by run key, so a new engine version or template is compared with the
// old one (a re-poured bed, another bed id, adds the scale's bed-to-bed scatter); points by their
// drive alone. "previous" is the latest report of the same campaign and
// scale with a smaller campaign run id; the first report of a campaign+scale compares with
// nothing (every point "new"). A report stored before `rule` existed reads as rule 1.
//
// A run counts as "reused" when its result row predates the campaign run, "run" when it was
// computed for it, "missing" when the run failed or was cancelled (no U_z this time).
//
// Thread safety: free functions over a thread-safe Store; ReportFinishedCampaignRuns is meant
// for one thread (the scheduler's) at a time; a second caller at most recomputes a report the
// first already stored (the insert is ignored).
#ifndef SANDSWIM_SERVER_DRIFT_REPORT_H_
#define SANDSWIM_SERVER_DRIFT_REPORT_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/cron.h"
#include "core/job_state.h"
#include "core/status.h"
#include "server/store/store.h"

namespace sandswim {

// One run (a point on one replicate bed).
struct DriftPoint {
  nlohmann::json point;  // PointToJson(point): the identity across reruns, with `replicate`
  int replicate = 0;     // its bed's replicate index
  int64_t run_id = 0;
  std::string key;
  JobState state = JobState::kQueued;        // the run's state when the report was made
  std::optional<double> uz;                  // m/s now (done runs)
  std::optional<double> uz_previous;         // m/s in the previous report
  std::optional<double> difference;          // uz - uz_previous, when both exist
  bool drifted = false;                      // |difference| > tolerance
  bool reused = false;                       // the result predates this campaign run
  bool inconclusive = false;                 // done, but too few whole periods: never compared
  int analysis = 0;                          // api::RunResult::analysis of uz (0: no result); a report
                                             // stored before the field existed reads as 1
  bool estimator_changed = false;            // the previous report's uz came from another analysis:
                                             // never compared
  std::optional<double> uz_stderr;           // m/s, the run's own standard error now
  std::optional<double> uz_stderr_previous;  // and in the previous report
  std::optional<double> tolerance;           // m/s, what |difference| was held to
  bool no_error = false;                     // a rate has no error: not compared
  std::optional<double> uz_ci95;             // m/s, the run's own 95 % half-width now (its dof)
  std::optional<double> uz_ci95_previous;    // and in the previous report
  int64_t bed_id = 0;                        // the bed it ran on (0: not known)
  int64_t bed_id_previous = 0;
  std::optional<double> p_value;             // of the difference against no change (compared rows)
  std::string not_compared;                  // why a run with a rate on both nights was not compared
};
// {"point":{...},"replicate","run_id","key","state","uz","uz_previous","difference","drifted",
//  "reused","inconclusive","analysis","estimator_changed","uz_stderr","uz_stderr_previous",
//  "tolerance","no_error","uz_ci95","uz_ci95_previous","bed_id","bed_id_previous","p_value",
//  "not_compared"}
// (absent values are null).
void to_json(nlohmann::json& j, const DriftPoint& p);
void from_json(const nlohmann::json& j, DriftPoint& p);

// One point over its replicate beds: its aggregate's mean now and before.
struct DriftAggregate {
  nlohmann::json point;                                  // PointToJson(point)
  int replicates = 0, conclusive = 0;                    // now (core/aggregate.h)
  int replicates_previous = 0, conclusive_previous = 0;  // before
  std::optional<double> uz_mean, uz_stderr;              // m/s, now
  std::optional<double> uz_mean_previous, uz_stderr_previous;
  std::optional<double> difference, tolerance;
  bool drifted = false;
  // Not compared: the point's rates now and before were not all made by one U_z analysis.
  bool estimator_changed = false;
  int beds_compared = 0;           // the beds conclusive on both nights that `difference` is over
  std::optional<double> p_value;   // of the difference against no change
  bool drifted_familywise = false; // drifted at family-wise 5 % across the campaign's points (Holm)
};
void to_json(nlohmann::json& j, const DriftAggregate& a);
void from_json(const nlohmann::json& j, DriftAggregate& a);

// The campaign's definition changed between the run a report would have been compared with and
// this one (schema/013_campaign_versions.sql): its versions, and the campaign run of the old one.
struct DefinitionChange {
  int from_version = 0;
  int to_version = 0;
  int64_t since_campaign_run_id = 0;
};

struct DriftReport {
  int64_t campaign_run_id = 0;
  std::string campaign;
  std::string scale;
  std::string trigger;             // "manual" | "schedule"
  std::optional<double> due_time;  // schedule: the due minute
  double campaign_run_created_at = 0;
  std::optional<int64_t> previous_campaign_run_id;
  double tolerance_mps = 0;  // its recorded definition's; 0: derived from the errors (see above)
  double created_at = 0;
  int64_t points = 0, reused = 0, ran = 0, missing = 0, compared = 0, drifted = 0, inconclusive = 0;
  int64_t estimator_changed = 0;           // points not compared: the U_z analysis changed
  int64_t no_error = 0;                    // runs not compared: a derived tolerance and no error
  std::vector<DriftPoint> rows;            // the campaign run's distinct runs, in sweep order
  std::vector<DriftAggregate> aggregates;  // its points, over their replicate beds
  int64_t points_compared = 0, points_drifted = 0;
  int rule = 1;                   // the drift rule (core/drift.h kDriftRuleVersion) that made it
  int64_t points_drifted_familywise = 0;
  bool campaign_drifted = false;  // some point drifted at family-wise 5 % (Holm)
  std::string false_alarms;       // the rule's measured false-alarm rates at this design (DriftAlarmText)
  std::string summary;  // the one-line summary the daemon logs
  // Set when the latest earlier report ran another definition: then "previous" is the latest
  // earlier report of the SAME definition (none: nothing compared) and the summary says
  // "definition changed (version a -> b)".
  std::optional<DefinitionChange> definition_changed;
};
// {"campaign_run_id","campaign","scale","trigger","due_time","campaign_run_created_at",
//  "previous_campaign_run_id","tolerance_mps","created_at","points","reused","ran","missing",
//  "compared","drifted","inconclusive","estimator_changed","no_error","summary","rows":[DriftPoint...],
//  "aggregates":[DriftAggregate...],"points_compared","points_drifted","rule","points_drifted_familywise",
//  "campaign_drifted","false_alarms"}
void to_json(nlohmann::json& j, const DriftReport& r);
void from_json(const nlohmann::json& j, DriftReport& r);

// Pure: fills rows' uz_previous/difference/drifted and the counts of `report` from `previous`
// (nullptr: the first report), then the summary line (times in `zone`'s wall clock):
//   "paper-58@smoke night 2026-11-23 02:00: 58 points, 56 reused, 2 run, 1 drifted beyond 0.005 m/s"
//   ("... 1 drifted beyond its 95 % bound" with a derived tolerance)
//   "paper-58@smoke rerun cr:7 (manual, 2026-11-23 14:05): ..."
// plus ", N inconclusive (not compared)", ", N not compared (U_z analysis changed)",
// ", N failed or cancelled", ", N not compared (no error)", "; P of Q points' means over their
// beds drifted" (when some point ran on more than one bed) and "; first report, nothing to
// compare" when they apply, and, when points were compared, "; the campaign: no change beyond
// chance (Holm, family-wise 5 %)" or "; the campaign drifted: N point(s) at family-wise 5 % (Holm)". ("points" in the line counts runs, as it always has.) A rate is
// compared only with one made by the same analysis (api::kAnalysisVersion): after an upgrade the
// first report compares nothing it cannot.
void CompareWithPrevious(DriftReport& report, const DriftReport* previous, CronZone zone);

// Records `change` in `report` and says it in the summary: "; definition changed (version 2 -> 3)
// since cr:7, compared with cr:5 of the same definition" when `compared`, else (replacing "first
// report, nothing to compare") "; definition changed (version 2 -> 3), no earlier run of this
// definition to compare with".
void SayDefinitionChanged(DriftReport& report, const DefinitionChange& change, bool compared);

// Makes, stores and returns a report for every campaign run that has none yet and whose runs
// are all terminal, oldest first, each compared with the latest earlier report of its campaign
// and scale that ran the same definition (see DriftReport::definition_changed). `now` stamps
// created_at.
Result<std::vector<DriftReport>> ReportFinishedCampaignRuns(Store& store, double now, CronZone zone = CronZone::kLocal);

// The report of one campaign run (nullopt: none yet).
Result<std::optional<DriftReport>> DriftReportFor(Store& store, int64_t campaign_run_id);
// The latest report of a campaign (at `scale`, or at any scale when empty); nullopt: none.
Result<std::optional<DriftReport>> LatestDriftReport(Store& store, const std::string& campaign,
                                                     const std::string& scale = "");
// The report GET /campaign-runs/{id} shows as "last_drift": the run's own report, else the
// latest earlier report of its campaign and scale.
Result<std::optional<DriftReport>> LastDriftFor(Store& store, const CampaignRunInfo& run);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_DRIFT_REPORT_H_
