// SweepAnalysis: a sweep's finished runs as the analysis sees them -- its samples (U_z and its
// error per run, pooled over replicate beds), the trajectories, and the paper's fit of the law
// ChooseFit() picks (core/fit.h) -- read from the Store. The claims (claim_check.h), the figures
// (figure_set.h) and the report (report.h) are made from it.
//
// Thread safety: free functions over a thread-safe Store.
#ifndef SANDSWIM_SERVER_ANALYSIS_SWEEP_ANALYSIS_H_
#define SANDSWIM_SERVER_ANALYSIS_SWEEP_ANALYSIS_H_

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/fit.h"
#include "core/status.h"
#include "server/analysis/figures.h"
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

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_SWEEP_ANALYSIS_H_
