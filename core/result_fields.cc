#include "core/result_fields.h"

#include "core/trajectory.h"

namespace sandswim {

const std::vector<ResultField>& ResultFields() {
  using api::Execution;
  using api::RunResult;
  constexpr ResultOrigin kAnalysis = ResultOrigin::kAnalysis;
  constexpr ResultOrigin kRun = ResultOrigin::kRun;
  constexpr ResultOrigin kExecution = ResultOrigin::kExecution;
  constexpr ResultOrigin kStore = ResultOrigin::kStore;
  static const std::vector<ResultField> kFields = {
      MakeResultField<&RunResult::uz>("uz", "Uz", "m/s", kAnalysis),
      MakeResultField<&RunResult::uz_stderr>("uz_stderr", "Uz_stderr", "m/s", kAnalysis),
      MakeResultField<&RunResult::uz_ci95>("uz_ci95", "Uz_ci95", "m/s", kAnalysis),
      MakeResultField<&RunResult::uz_stderr_note>("uz_stderr_note", "", "", kAnalysis),
      MakeResultField<&RunResult::uz_blocks>("uz_blocks", "Uz_blocks", "", kAnalysis),
      MakeResultField<&RunResult::block_s>("block_s", "block_s", "s", kAnalysis),
      MakeResultField<&RunResult::block_kind>("block_kind", "block_kind", "", kAnalysis),
      MakeResultField<&RunResult::window_t0>("window_t0", "window_t0", "s", kAnalysis),
      MakeResultField<&RunResult::window_t1>("window_t1", "window_t1", "s", kAnalysis),
      MakeResultField<&RunResult::window_end>("window_end", "window_end", "", kAnalysis),
      MakeResultField<&RunResult::conclusive>("conclusive", "conclusive", "", kAnalysis),
      MakeResultField<&RunResult::inconclusive_reason>("inconclusive_reason", "inconclusive_reason", "", kAnalysis),
      MakeResultField<&RunResult::trending>("trending", "trending", "", kAnalysis),
      MakeResultField<&RunResult::trend_p>("trend_p", "trend_p", "", kAnalysis),
      MakeResultField<&RunResult::trend_slope>("trend_slope", "trend_slope", "m/s^2", kAnalysis),
      MakeResultField<&RunResult::trend_slope_se>("trend_slope_se", "trend_slope_se", "m/s^2", kAnalysis),
      MakeResultField<&RunResult::trend_note>("trend_note", "trend_note", "", kAnalysis),
      MakeResultField<&RunResult::dz>("dz", "dz", "m", kRun),
      MakeResultField<&RunResult::dz_rate>("dz_rate", "dz_rate", "m/s", kAnalysis),
      MakeResultField<&RunResult::z_osc_amplitude>("z_osc_amplitude", "z_osc_amplitude", "m", kAnalysis),
      MakeResultField<&RunResult::x_osc_amplitude>("x_osc_amplitude", "x_osc_amplitude", "m", kAnalysis),
      MakeResultField<&RunResult::x_drift>("x_drift", "x_drift", "m", kRun),
      MakeResultField<&RunResult::z0>("z0", "", "m", kRun),
      MakeResultField<&RunResult::broke_surface>("broke_surface", "broke_surface", "", kRun),
      MakeResultField<&RunResult::near_floor>("near_floor", "near_floor", "", kRun),
      MakeResultField<&RunResult::stop_reason>("stop_reason", "stop_reason", "", kRun),
      MakeResultField<&RunResult::stop_note>("stop_note", "stop_note", "", kAnalysis),
      MakeResultField<&RunResult::precision_met>("precision_met", "precision_met", "", kAnalysis),
      MakeResultField<&RunResult::sim_time_s>("sim_time_s", "sim_time_s", "s", kRun),
      MakeResultField<&RunResult::steps>("steps", "", "", kRun),
      MakeResultField<&RunResult::grains>("grains", "grains", "", kRun),
      // A report without "analysis" was made by a worker that predates it: the old estimator.
      MakeResultField<&RunResult::analysis>("analysis", "analysis", "", kAnalysis, 1),
      MakeResultField<&RunResult::analysed_from>("analysed_from", "analysed_from", "", kAnalysis, "dump"),
      MakeResultField<&Execution::engine_version>("engine_version", "engine_version", "", kExecution),
      MakeResultField<&Execution::host>("host", "", "", kExecution),
      MakeResultField<&Execution::ranks>("ranks", "", "", kExecution),
      MakeResultField<&Execution::launcher>("launcher", "", "", kExecution),
      MakeResultField<&Execution::wall_s>("wall_s", "", "s", kExecution),
      MakeResultField<&Execution::cpu_s>("cpu_s", "", "s", kExecution),
      // 0 for results stored before migration 4.
      MakeResultField<&Execution::lease_to_start_s>("lease_to_start_s", "", "s", kExecution),
      MakeResultField<&StoredResult::key>("key", "", "", kStore),
      MakeResultField<&StoredResult::created_at>("created_at", "", "s", kStore),
  };
  return kFields;
}

void to_json(nlohmann::json& j, const StoredResult& r) {
  j = nlohmann::json::object();
  for (const ResultField& f : ResultFields()) {
    nlohmann::json v = f.get(r);
    if (!v.is_null()) j[f.name] = std::move(v);
  }
  j["uz_text"] = DescribeUz(r.result);
}

}  // namespace sandswim
