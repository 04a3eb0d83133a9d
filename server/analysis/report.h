// Report: one self-contained HTML report per campaign run (every figure inlined as SVG, the fit
// table, the drift report), made of the run's sweep analyses (sweep_analysis.h), their figures
// (figure_set.h, drawn once per set of results through a FigureCache, figure_cache.h) and the
// campaign's claims (claim_check.h).
//
// The report opens with the campaign's claims (core/claims.h): each with its verdict, the numbers
// behind it and what the paper reports, side by side; a campaign without claims says so. An
// adaptive campaign run's claims are shown as their deciding look froze them, and its rounds
// follow (one row a round, as the dashboard shows them: server/jobs/rounds.h).
//
// The HTML is one file: no external stylesheet, script, font or image; every internal link is an
// anchor ("#sweep-12", "#run-40") of an element in the same page, and the figures are inline
// <svg> elements (their XML prolog stripped). RenderReportHtml() is pure; CampaignReport() does
// the reading.
//
// Thread safety: free functions over a thread-safe Store and FigureCache.
#ifndef SANDSWIM_SERVER_ANALYSIS_REPORT_H_
#define SANDSWIM_SERVER_ANALYSIS_REPORT_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/claims.h"
#include "core/fit.h"
#include "core/job_state.h"
#include "core/snapshot.h"
#include "core/status.h"
#include "server/analysis/drift_report.h"
#include "server/analysis/figure_cache.h"
#include "server/analysis/figure_set.h"
#include "server/analysis/sweep_analysis.h"
#include "server/store/rounds.h"
#include "server/store/store.h"

namespace sandswim {

// What the report shows, already drawn (SVG text as RenderPlot makes it).
struct ReportRun {
  int64_t run_id = 0;
  std::string label;  // PointLabel
  JobState state = JobState::kQueued;
  std::string uz_text;              // DescribeUz ("" without a result)
  std::optional<double> dz_rate;    // m/s, dz over the whole run
  std::string window_end;           // why the steady window ended
  std::string inconclusive_reason;  // "" when conclusive
  std::string trajectory_svg;       // "" when none
  // The run's figure and its "#run-ID" anchor are shown here (false where an earlier sweep of the
  // report, sharing the run, shows them).
  bool anchored = true;
};
struct ReportSweep {
  SweepInfo info;
  SweepFits fits;
  // Δz(t) per branch (TrajectoryBranches), each "" when none of its runs has finished.
  std::vector<std::pair<std::string, std::string>> trajectories_svg;  // {branch, svg}
  std::string uz_svg;                                                 // "" when nothing to plot
  std::string no_uz;                                                  // NoUzToPlot
  std::vector<ReportRun> runs;
};
// A full-bed snapshot of a run, as its y-z slice (the paper's Fig. 5).
struct ReportSnapshot {
  int64_t run_id = 0;
  std::string label;  // PointLabel of the run's drive
  api::Snapshot meta;
  std::string slice_svg;
};
struct ReportInput {
  CampaignRunInfo campaign_run;
  // The campaign's claims and their verdicts (server/analysis/claim_check.h): the report's first section.
  std::vector<ClaimVerdict> claims;
  std::string claims_note;  // e.g. where the claims come from, or why there are none
  // An adaptive campaign run's verdicts frozen at their deciding look (claim_check.h; `claims`
  // shows them already): each says at which round.
  std::map<std::string, rounds::FrozenVerdict> frozen_claims;
  // An adaptive campaign run's settings (defaults filled in) and rounds as GET
  // /api/v1/campaign-runs/{id} has them (rounds::RoundsReply): the section after the claims.
  // Null: the run has a fixed design (rounds::RunsInRounds), and the report no rounds section.
  nlohmann::json adaptive;
  nlohmann::json rounds = nlohmann::json::array();
  std::string rounds_problem;  // "the rounds could not be read: ...": said in place of the section
  // The drive modes side by side (ModesFigure): "" when the campaign run has none.
  std::string modes_x_svg, modes_z_svg;
  // Every snapshot the campaign run's runs took, by run and idx (empty: none asked for them).
  std::vector<ReportSnapshot> snapshots;
  std::vector<ReportSweep> sweeps;
  std::optional<DriftReport> drift;
  // What could not be made (a figure the renderer failed on, the claims check): listed at the top,
  // each also said where its part would be.
  std::vector<std::string> problems;
  double generated_at = 0;  // unix seconds
};
std::string RenderReportHtml(const ReportInput& input);

// Reads and draws everything of a campaign run (its claims' verdicts first) and renders the
// report. NotFound for an unknown id.
// `data_dir`: where the runs' snapshots are (server/store/snapshot_files.h SnapshotPath); ""
// leaves their slices out.
Result<std::string> CampaignReport(Store& store, FigureCache& figures, int64_t campaign_run_id, double now,
                                   const std::string& data_dir = "");

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_REPORT_H_
