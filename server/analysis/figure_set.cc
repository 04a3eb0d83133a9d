#include "server/analysis/figure_set.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "core/branch.h"
#include "core/aggregate.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"

namespace sandswim {

// ---- Figures -----------------------------------------------------------------------------------

std::vector<std::string> TrajectoryBranches(const SweepAnalysis& a) {
  // The distinct drives of each branch (A, f, |Omega|): a pair of one each (the paper's Fig. 4)
  // stays on one plot.
  std::set<std::tuple<double, double, double>> rising, sinking;
  for (const RunTrajectory& r : a.runs) {
    if (r.point.mode != Mode::kOscillatory || BranchOf(r.point) == Branch::kNone) continue;
    (BranchOf(r.point) == Branch::kRising ? rising : sinking).insert({r.point.A, r.point.f, std::fabs(r.point.Omega)});
  }
  if (!rising.empty() && !sinking.empty() && std::max(rising.size(), sinking.size()) > 1)
    return {std::string(BranchName(Branch::kRising)), std::string(BranchName(Branch::kSinking))};
  return {""};
}

Plot SweepTrajectoriesFigure(const SweepAnalysis& a, const std::string& branch) {
  // A name that is not a branch's (the route refuses one) draws the sinking branch, as it did.
  const Branch side = ParseBranch(branch).value_or(Branch::kSinking);
  std::vector<RunTrajectory> runs;
  for (const RunTrajectory& r : a.runs) {
    if (branch.empty() || (r.point.mode == Mode::kOscillatory && BranchOf(r.point) == side)) runs.push_back(r);
  }
  const std::string what = branch.empty() ? std::string("Δz(t) of every run")
                                          : "Δz(t), " + std::string(BranchName(side)) + " branch (" +
                                                std::string(OmegaSide(side)) + ")";
  return SweepTrajectoriesPlot(
      "sweep " + std::to_string(a.info.id) + " " + PlplotLiteral(a.info.name) + " (" + a.info.scale + "): " + what,
      runs, a.fits.choice.param);
}

Plot SweepUzFigure(const SweepAnalysis& a) {
  return SweepUzPlot(
      "sweep " + std::to_string(a.info.id) + " " + PlplotLiteral(a.info.name) + " (" + a.info.scale + "): U#dz#u",
      a.samples, a.fits);
}

std::string NoUzToPlot(const SweepAnalysis& a) {
  if (a.swept_values < 2) {
    const std::string param = a.fits.choice.param.empty() ? "Omega" : a.fits.choice.param;
    return "its points share one value of " + param +
           ": a U_z figure against it would mean nothing (its U_z is in the table)";
  }
  if (a.samples.empty()) return "nothing finished yet";
  for (const SweepSample& s : a.samples) {
    if (s.has_uz) return "";
  }
  return "no U_z to plot: none of its " + std::to_string(a.samples.size()) +
         " finished run(s) has a whole period (or block) in its steady window";
}

Plot SnapshotSlicePlot(int64_t run_id, const Point& point, const api::Snapshot& meta, const BedSlice& slice) {
  Plot plot;
  const std::string when = meta.fraction == 0     ? "start"
                           : meta.fraction == 1   ? "end"
                           : meta.fraction == 0.5 ? "middle"
                                                  : Num(meta.fraction, 3) + " of the run";
  // The title sits over a narrow plot: the drive without the mode's name where Ω says it.
  std::string drive = PointLabel(point, "");
  const std::string oscillatory = std::string(ModeName(Mode::kOscillatory)) + ", ";
  if (drive.rfind(oscillatory, 0) == 0) drive = drive.substr(oscillatory.size());
  plot.title = "run " + std::to_string(run_id) + " (" + drive + "), t = " + Num(meta.t_s, 3) + " s: " + when;
  plot.x_label = "y (m)";
  plot.y_label = "z (m)";
  Discs discs;
  discs.value_label = "|v| (m/s)";
  double top = slice.so.z + slice.so.r;
  for (const SliceDisc& d : slice.grains) {
    discs.x.push_back(d.y);
    discs.y.push_back(d.z);
    discs.r.push_back(d.r);
    discs.value.push_back(d.speed);
    top = std::max(top, d.z + d.r);
  }
  // The SO's own speed colours it too, so it reads on the same scale as the grains.
  discs.x.push_back(slice.so.y);
  discs.y.push_back(slice.so.z);
  discs.r.push_back(slice.so.r);
  discs.value.push_back(slice.so.speed);
  plot.discs = std::move(discs);
  Series so;
  so.label = "SO, |v| = " + Num(slice.so.speed, 2) + " m/s";
  constexpr int kOutline = 72;
  for (int k = 0; k <= kOutline; ++k) {
    const double a = 2 * M_PI * k / kOutline;
    so.x.push_back(slice.so.y + slice.so.r * std::cos(a));
    so.y.push_back(slice.so.z + slice.so.r * std::sin(a));
  }
  plot.series.push_back(std::move(so));
  plot.equal_aspect = true;
  plot.limits = std::array<double, 4>{slice.y_lo, slice.y_hi, slice.z_lo, top + kMaterials.d_grain};
  return plot;
}

std::optional<Plot> ModesFigure(const CampaignRunInfo& cr, const std::vector<SweepAnalysis>& analyses,
                                Coordinate coordinate) {
  std::vector<RunTrajectory> runs;
  std::set<int64_t> seen;
  for (const SweepAnalysis& a : analyses) {
    for (const RunTrajectory& r : a.runs) {
      if (r.point.mode == Mode::kOscillatory || !seen.insert(r.run_id).second) continue;
      runs.push_back(r);
    }
  }
  if (runs.empty()) return std::nullopt;
  const std::string what = coordinate == Coordinate::kX ? "Δx(t)" : "Δz(t)";
  return SweepTrajectoriesPlot("campaign run " + std::to_string(cr.id) + " " + PlplotLiteral(cr.campaign) + " (" +
                                   cr.scale + "): " + what + " of each drive mode",
                               runs, "", coordinate);
}

Result<Plot> RunFigure(Store& store, int64_t run_id) {
  auto run = store.GetRun(run_id, Store::Deck::kLeftOut);
  if (!run.ok()) return run.status();
  if (!run->trajectory || run->trajectory->t.empty()) {
    return Status::FailedPrecondition(
        "id", "run " + std::to_string(run_id) + " has no trajectory yet (state " + ToString(run->summary.state) + ")");
  }
  return RunTrajectoryPlot(run_id, run->summary.point, *run->trajectory, run->result ? &run->result->result : nullptr);
}

std::string RunFigureName(int64_t run_id) { return "run-" + std::to_string(run_id) + "-trajectory"; }
std::string SweepTrajectoriesName(int64_t sweep_id, const std::string& branch) {
  return "sweep-" + std::to_string(sweep_id) + "-trajectories" + (branch.empty() ? "" : "-" + branch);
}
std::string ModesFigureName(int64_t campaign_run_id, Coordinate coordinate) {
  return "campaign-run-" + std::to_string(campaign_run_id) + (coordinate == Coordinate::kX ? "-modes-x" : "-modes-z");
}

std::string SweepUzName(int64_t sweep_id) { return "sweep-" + std::to_string(sweep_id) + "-uz"; }

}  // namespace sandswim
