// FigureSet: the figures of a sweep, a run and a campaign run as Plots (server/analysis/figures.h)
// built from a SweepAnalysis -- the Δz(t) of a sweep's runs per branch, U_z against the swept
// parameter with its fit, a run's trajectory, the drive modes side by side, a snapshot's y-z slice
// -- and the names they are cached by (server/analysis/figure_cache.h).
//
// Thread safety: free functions; RunFigure reads a thread-safe Store.
#ifndef SANDSWIM_SERVER_ANALYSIS_FIGURE_SET_H_
#define SANDSWIM_SERVER_ANALYSIS_FIGURE_SET_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/snapshot.h"
#include "core/status.h"
#include "server/analysis/figures.h"
#include "server/analysis/sweep_analysis.h"
#include "server/store/store.h"

namespace sandswim {

// The branches a sweep's Δz(t) figures are drawn by, as the paper's panels a and b: {"rising",
// "sinking"} when its oscillatory runs have both signs of Omega (Omega < 0 rises in the paper,
// Omega > 0 sinks) and a branch has more than one drive; else {""}: one figure of every run (a
// baseline pair stays together, as in the paper's Fig. 4).
std::vector<std::string> TrajectoryBranches(const SweepAnalysis& analysis);

// The figures of a sweep, as plots to draw (nothing is drawn here). With nothing finished (or, for
// a branch, none of its runs) the plot has no series, and drawing it (RenderPlot, FigureCache) is
// InvalidArgument ("plot").
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

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_FIGURE_SET_H_
