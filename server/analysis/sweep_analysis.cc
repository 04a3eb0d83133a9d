#include "server/analysis/sweep_analysis.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "core/job_state.h"
#include "core/aggregate.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"

namespace sandswim {

// ---- Analysis ----------------------------------------------------------------------------------

SweepAnalysis AnalyzeSweepResults(const SweepInfo& info, const std::vector<ResultRow>& rows) {
  SweepAnalysis a;
  a.info = info;
  // A point run on several replicate beds is one sample: its aggregate (core/aggregate.h), whose
  // standard error over the beds weights the fit and whose 95 % interval the figure draws.
  std::map<DriveId, std::vector<const ResultRow*>> replicates;
  for (const ResultRow& row : rows) replicates[DriveIdOf(row.point)].push_back(&row);
  std::set<DriveId> aggregated;
  for (const ResultRow& row : rows) {
    const std::vector<const ResultRow*>& beds = replicates.at(DriveIdOf(row.point));
    if (beds.size() > 1 && aggregated.insert(DriveIdOf(row.point)).second) {
      std::vector<ReplicateValue> values;
      const ResultRow* first_done = nullptr;
      for (const ResultRow* b : beds) {
        ReplicateValue v;
        v.run_id = b->run_id;
        v.replicate = b->replicate;
        v.state = b->state;
        if (b->state == JobState::kDone && b->result) {
          if (first_done == nullptr) first_done = b;
          v.conclusive = b->result->result.conclusive;
          v.uz = b->result->result.uz;
          v.uz_stderr = b->result->result.uz_stderr;
          v.uz_ci95 = b->result->result.uz_ci95;
        }
        values.push_back(v);
      }
      if (first_done != nullptr) {  // a point none of whose beds has finished is not a sample yet
        const ReplicateAggregate agg = AggregateReplicates(values, BedPriorOf(info.scale));
        SweepSample sample;
        sample.point = row.point;
        sample.run_id = first_done->run_id;
        sample.has_uz = agg.uz_mean.has_value();
        // Conclusive only over all K beds (core/aggregate.h): the mean of the beds that happened to
        // be conclusive is shown, not fitted.
        sample.conclusive = agg.complete;
        sample.uz = agg.uz_mean.value_or(0);
        sample.uz_stderr = agg.uz_stderr.value_or(0);
        sample.uz_ci95 = agg.uz_ci95.value_or(0);
        if (!sample.conclusive) sample.inconclusive_reason = DescribeAggregate(agg) + (agg.note.empty() ? "" : ": " + agg.note);
        a.samples.push_back(std::move(sample));
      }
    }
    if (row.state != JobState::kDone || !row.result) continue;
    if (beds.size() > 1) continue;  // its sample is the aggregate
    const api::RunResult& r = row.result->result;
    SweepSample sample;
    sample.point = row.point;
    sample.run_id = row.run_id;
    sample.conclusive = r.conclusive && r.uz.has_value();
    sample.uz = r.uz.value_or(0);
    sample.has_uz = r.uz.has_value();
    sample.uz_stderr = r.uz_stderr.value_or(0);
    sample.uz_ci95 = r.uz_ci95.value_or(0);
    if (const double prior = BedPriorOf(info.scale); prior > 0 && sample.conclusive) {
      // One bed: the point's error adds the scale's bed-to-bed prior (core/aggregate.h), as the
      // claims' points do; the run's own error stays in its result.
      ReplicateValue v;
      v.run_id = row.run_id;
      v.state = row.state;
      v.conclusive = true;
      v.uz = r.uz;
      v.uz_stderr = r.uz_stderr;
      v.uz_ci95 = r.uz_ci95;
      const ReplicateAggregate one = AggregateReplicates({v}, prior);
      sample.uz_stderr = one.uz_stderr.value_or(sample.uz_stderr);
      sample.uz_ci95 = one.uz_ci95.value_or(sample.uz_ci95);
    }
    sample.inconclusive_reason = r.inconclusive_reason.empty() && !r.conclusive ? DescribeUz(r) : r.inconclusive_reason;
    a.samples.push_back(std::move(sample));
  }
  // The law is what the sweep varies (all its points), whatever has finished so far.
  std::vector<Point> points;
  for (const ResultRow& row : rows) points.push_back(row.point);
  a.fits = FitSweep(a.samples, ChooseFit(points));
  std::set<double> swept;
  for (const Point& p : points) swept.insert(SweptValue(p, a.fits.choice.param));
  a.swept_values = swept.size();
  return a;
}

Result<SweepAnalysis> AnalyzeSweep(Store& store, int64_t sweep_id) {
  auto info = store.GetSweep(sweep_id);
  if (!info.ok()) return info.status();
  auto rows = store.SweepResults(sweep_id);
  if (!rows.ok()) return rows.status();
  SweepAnalysis a = AnalyzeSweepResults(*info, *rows);
  // Every finished run's trajectory, on every bed, in one read.
  auto trajectories = store.SweepTrajectories(sweep_id);
  if (!trajectories.ok()) return trajectories.status();
  for (const ResultRow& row : *rows) {
    if (row.state != JobState::kDone || !row.result) continue;
    auto trajectory = trajectories->find(row.run_id);
    if (trajectory != trajectories->end() && !trajectory->second.t.empty())
      a.runs.push_back({row.run_id, row.point, std::move(trajectory->second), row.replicate});
  }
  return a;
}

Result<std::vector<SweepAnalysis>> AnalyzeCampaignRun(Store& store, const CampaignRunInfo& campaign_run) {
  std::vector<SweepAnalysis> analyses;
  for (int64_t sweep_id : campaign_run.sweep_ids) {
    auto a = AnalyzeSweep(store, sweep_id);
    if (!a.ok()) return a.status();
    analyses.push_back(std::move(a).value());
  }
  return analyses;
}

}  // namespace sandswim
