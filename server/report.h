// Report: a sweep's analysis (its finished runs, the paper's fit, its figures) and one
// self-contained HTML report per campaign run (every figure inlined as SVG, the fit table, the
// drift report).
//
// AnalyzeSweep() reads a sweep's finished runs (U_z, its standard error, the trajectory) from
// the Store and fits the law ChooseFit() picks (core/fit.h). The figures of a sweep and of a run
// are built from it with server/figures.h and kept by a FigureCache (so the report and the REST
// routes draw each figure once per set of results).
//
// The report opens with the campaign's claims (core/claims.h): each with its verdict, the numbers
// behind it and what the paper reports, side by side; a campaign without claims says so.
//
// The HTML is one file: no external stylesheet, script, font or image; every internal link is an
// anchor ("#sweep-12", "#run-40") of an element in the same page, and the figures are inline
// <svg> elements (their XML prolog stripped). RenderReportHtml() is pure; CampaignReport() does
// the reading.
//
// Thread safety: free functions over a thread-safe Store and FigureCache.
#ifndef SANDSWIM_SERVER_REPORT_H_
#define SANDSWIM_SERVER_REPORT_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/claims.h"
#include "core/fit.h"
#include "core/snapshot.h"
#include "core/status.h"
#include "server/drift_report.h"
#include "server/figures.h"
#include "server/store/store.h"

namespace sandswim {

struct SweepAnalysis {
  SweepInfo info;
  std::vector<SweepSample> samples;  // finished runs with a U_z, in expansion order
  std::vector<RunTrajectory> runs;   // finished runs with a trajectory, in expansion order
  SweepFits fits;                    // of `samples`
  // Distinct values of the plotted parameter (SweptValue of fits.choice.param) over every point
  // the sweep plans: a U_z figure needs two.
  size_t swept_values = 0;
};
// NotFound when the sweep does not exist.
Result<SweepAnalysis> AnalyzeSweep(Store& store, int64_t sweep_id);
// Its pure part: the samples, fits and swept values of a sweep's result rows (`runs`, the
// trajectories, stays empty), so that a caller holding rows without a Store (the truth engine's
// calibration, tests/truth/) analyses them exactly as the daemon does.
SweepAnalysis AnalyzeSweepResults(const SweepInfo& info, const std::vector<ResultRow>& rows);
// Every sweep of a campaign run, in its order.
Result<std::vector<SweepAnalysis>> AnalyzeCampaignRun(Store& store, const CampaignRunInfo& campaign_run);

// The branches a sweep's Δz(t) figures are drawn by, as the paper's panels a and b: {"rising",
// "sinking"} when its oscillatory runs have both signs of Omega (Omega < 0 rises in the paper,
// Omega > 0 sinks) and a branch has more than one drive; else {""}: one figure of every run (a
// baseline pair stays together, as in the paper's Fig. 4).
std::vector<std::string> TrajectoryBranches(const SweepAnalysis& analysis);

// The figures of a sweep. InvalidArgument ("plot") from RenderPlot when nothing is finished (or,
// for a branch, none of its runs).
// `branch`: "" every run; "rising" the runs at Omega < 0; "sinking" those at Omega > 0.
Plot SweepTrajectoriesFigure(const SweepAnalysis& analysis, const std::string& branch = "");
Plot SweepUzFigure(const SweepAnalysis& analysis);
// Why the sweep has no U_z figure ("" when it has one): its points share one value of the plotted
// parameter (a plot against it would mean nothing: a drive-mode sweep of one point), nothing has
// finished, or no finished run has a U_z (each one's window held no whole period).
std::string NoUzToPlot(const SweepAnalysis& analysis);
// FailedPrecondition when the run has no trajectory yet.
Result<Plot> RunFigure(Store& store, int64_t run_id);

// The drive modes side by side (the paper's Fig. 2): every finished run of the campaign run whose
// drive is not the oscillatory one (vibration, rotation, both), once each, Δx(t) or Δz(t) on one
// plot. nullopt when the campaign run has none.
std::optional<Plot> ModesFigure(const CampaignRunInfo& campaign_run, const std::vector<SweepAnalysis>& analyses,
                                Coordinate coordinate);

// The paper's Fig. 5 for one snapshot of a run: the y-z slice through the SO, every grain the
// plane cuts a disc of its cut radius coloured by its speed, the SO outlined (a line series), the
// axes at one scale from the box's y range and from its floor to just above the highest disc.
Plot SnapshotSlicePlot(int64_t run_id, const Point& point, const api::Snapshot& meta, const BedSlice& slice);

// Cache names of the figures (FigureCache::Get): "run-ID-trajectory", "sweep-ID-trajectories",
// "sweep-ID-uz", "campaign-run-ID-modes-x" / "-modes-z".
std::string RunFigureName(int64_t run_id);
std::string SweepTrajectoriesName(int64_t sweep_id, const std::string& branch = "");  // + "-rising"
std::string SweepUzName(int64_t sweep_id);
std::string ModesFigureName(int64_t campaign_run_id, Coordinate coordinate);  // "...-modes-x" / "-modes-z"

// What the report shows, already drawn (SVG text as RenderPlot makes it).
struct ReportRun {
  int64_t run_id = 0;
  std::string label;  // PointLabel
  std::string state;
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
  // The campaign's claims and their verdicts (server/claim_check.h): the report's first section.
  std::vector<ClaimVerdict> claims;
  std::string claims_note;  // e.g. where the claims come from, or why there are none
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
// `data_dir`: where the runs' snapshots are (server/lease_queue.h SnapshotPath); "" leaves their
// slices out.
Result<std::string> CampaignReport(Store& store, FigureCache& figures, int64_t campaign_run_id, double now,
                                   const std::string& data_dir = "");

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_REPORT_H_
