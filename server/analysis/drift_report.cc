#include "server/analysis/drift_report.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <utility>

#include "core/job_state.h"
#include "core/aggregate.h"
#include "core/drift.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "server/store/campaigns.h"
#include "server/store/drift_table.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

template <typename T>
json OrNull(const std::optional<T>& v) {
  return v ? json(*v) : json(nullptr);
}

template <typename T>
std::optional<T> OptField(const json& j, const char* name) {
  auto it = j.find(name);
  if (it == j.end() || it->is_null()) return std::nullopt;
  return it->get<T>();
}

std::string PointIdentity(const json& point) { return point.dump(); }
// A run's identity across reruns: its drive and its replicate bed (replicate 0 reads as reports
// made before replicates did).
std::string RunIdentity(const DriftPoint& p) {
  return PointIdentity(p.point) + (p.replicate == 0 ? "" : "#" + std::to_string(p.replicate));
}

// A run's rate on both nights as core/drift.h takes it (its error's dof from its 95 % interval;
// a report stored before intervals were kept: normal). REQUIRES: uz and uz_previous.
DriftBedPair PairOf(const DriftPoint& p) {
  auto dof = [](const std::optional<double>& se, const std::optional<double>& ci) {
    return se && ci && *se > 0 && *ci > 0 ? DofOfInterval(*se, *ci) : kNormalDof;
  };
  DriftBedPair b;
  b.uz = *p.uz;
  b.uz_previous = *p.uz_previous;
  b.uz_stderr = p.uz_stderr.value_or(0);
  b.uz_stderr_previous = p.uz_stderr_previous.value_or(0);
  b.dof = dof(p.uz_stderr, p.uz_ci95);
  b.dof_previous = dof(p.uz_stderr_previous, p.uz_ci95_previous);
  // The same bed only when known to be: a reused run (one result both nights) or both bed ids known
  // and equal. A report stored before bed ids were kept says 0, and an unknown bed may have been
  // re-poured (an engine or template change reruns on new beds): it gets the bed prior.
  b.same_bed = p.reused || (p.bed_id != 0 && p.bed_id == p.bed_id_previous);
  return b;
}

// A report's rows grouped by point and aggregated over their replicate beds (comparable rates
// only: conclusive, with a value).
std::map<std::string, std::pair<json, ReplicateAggregate>> AggregatesOf(const std::vector<DriftPoint>& rows) {
  std::map<std::string, std::pair<json, std::vector<ReplicateValue>>> groups;
  for (const DriftPoint& p : rows) {
    auto& g = groups[PointIdentity(p.point)];
    g.first = p.point;
    ReplicateValue v;
    v.run_id = p.run_id;
    v.replicate = p.replicate;
    v.state = p.state;
    v.conclusive = !p.inconclusive && p.uz.has_value();
    v.uz = p.uz;
    v.uz_stderr = p.uz_stderr;
    g.second.push_back(v);
  }
  std::map<std::string, std::pair<json, ReplicateAggregate>> out;
  for (auto& [id, g] : groups) out[id] = {g.first, AggregateReplicates(std::move(g.second))};
  return out;
}

// The U_z analysis version of each point's conclusive rates, by replicate bed.
using BedAnalyses = std::map<int, int>;
std::map<std::string, BedAnalyses> AnalysesOf(const std::vector<DriftPoint>& rows) {
  std::map<std::string, BedAnalyses> out;
  for (const DriftPoint& p : rows)
    if (p.uz && !p.inconclusive) out[PointIdentity(p.point)][p.replicate] = p.analysis;
  return out;
}

// Two means over a point's beds measure the same thing when one U_z analysis made every rate in
// both, or when both hold the same beds, each made by the same analysis in both (a bed re-analysed
// in one and not the other changes its mean by the estimator, not by the runs).
bool SameEstimator(const BedAnalyses& now, const BedAnalyses& before) {
  std::set<int> all;
  for (const auto& [bed, analysis] : now) all.insert(analysis);
  for (const auto& [bed, analysis] : before) all.insert(analysis);
  return all.size() == 1 || now == before;
}

std::string Tolerance(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// The one rule for the tolerance a campaign run's drift is held to: that of the definition the run
// recorded when it was submitted (schema/013), as its claims are, so that a later version of the
// campaign changes nothing about a run made before it. Only a campaign run recorded before
// definitions were kept (or one whose recorded definition no longer parses) takes its campaign's
// current definition, the built-in file's for a built-in campaign; 0 (no tolerance: the errors
// decide) when the campaign is gone as well. The campaigns.drift_tolerance_mps column is never
// read (server/store/campaigns.h).
Result<double> DriftToleranceOf(Store& store, const CampaignRunInfo& run) {
  if (run.definition.is_object()) {
    Result<Campaign> recorded = ParseCampaign(run.definition);
    if (recorded.ok()) return recorded->drift_tolerance_mps;
  }
  Result<CatalogueEntry> found = FindCampaign(store, run.campaign);
  if (found.ok()) return found->campaign.drift_tolerance_mps;
  if (found.status().code() == StatusCode::kNotFound) return 0.0;
  return found.status();
}

Result<std::optional<DriftReport>> Decode(const Result<std::optional<drift_table::StoredReport>>& stored) {
  if (!stored.ok()) return stored.status();
  if (!stored->has_value()) return std::optional<DriftReport>();
  try {
    return std::optional<DriftReport>(json::parse((*stored)->report).get<DriftReport>());
  } catch (const json::exception& e) {
    return Status::Corruption(std::string("a stored drift report does not parse: ") + e.what());
  }
}

Result<std::optional<DriftReport>> PreviousReport(Store& store, const std::string& campaign, const std::string& scale,
                                                  int64_t before_id) {
  auto t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return Decode(drift_table::Previous(*t, campaign, scale, before_id));
}

// The report a campaign run is compared with: the latest earlier report of its campaign and
// scale when that one ran the same definition (or either ran one not recorded, before
// schema/013_campaign_versions.sql), else the latest earlier one that ran the same definition,
// if any; `changed` then holds the versions the definition went between.
struct Baseline {
  std::optional<DriftReport> report;
  std::optional<DefinitionChange> changed;
};
Result<Baseline> BaselineFor(Store& store, const CampaignRunInfo& info) {
  auto t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  auto latest = drift_table::Previous(*t, info.campaign, info.scale, info.id);
  if (!latest.ok()) return latest.status();
  Baseline out;
  if (!latest->has_value()) return out;
  const drift_table::StoredReport& before = **latest;
  const bool unknown = before.definition_sha256.empty() || info.definition_sha256.empty();
  if (unknown || before.definition_sha256 == info.definition_sha256) {
    auto report = Decode(latest);
    if (!report.ok()) return report.status();
    out.report = std::move(*report);
    return out;
  }
  out.changed = DefinitionChange{before.campaign_version.value_or(0), info.campaign_version.value_or(0),
                                 before.campaign_run_id};
  auto same = Decode(drift_table::Previous(*t, info.campaign, info.scale, info.id, info.definition_sha256));
  if (!same.ok()) return same.status();
  out.report = std::move(*same);
  return out;
}

// The campaign run's distinct runs as they stand now.
Result<DriftReport> CurrentState(Store& store, const CampaignRunInfo& info, double now) {
  DriftReport report;
  report.campaign_run_id = info.id;
  report.campaign = info.campaign;
  report.scale = info.scale;
  report.trigger = info.trigger;
  report.due_time = info.due_time;
  report.campaign_run_created_at = info.created_at;
  report.created_at = now;
  auto tolerance = DriftToleranceOf(store, info);
  if (!tolerance.ok()) return tolerance.status();
  report.tolerance_mps = *tolerance;
  std::map<int64_t, bool> seen;
  for (int64_t sweep_id : info.sweep_ids) {
    auto rows = store.SweepResults(sweep_id);
    if (!rows.ok()) return rows.status();
    for (const ResultRow& row : *rows) {
      if (!seen.emplace(row.run_id, true).second) continue;
      DriftPoint p;
      p.point = PointToJson(row.point);
      p.replicate = row.replicate;
      p.bed_id = row.bed_id;
      p.run_id = row.run_id;
      p.key = row.key;
      p.state = row.state;
      if (row.state == JobState::kDone && row.result) {
        p.uz = row.result->result.uz;
        p.uz_stderr = row.result->result.uz_stderr;
        p.uz_ci95 = row.result->result.uz_ci95;
        // Only conclusive rates are compared: an inconclusive one is too short to judge a change by.
        p.inconclusive = !row.result->result.conclusive || !p.uz;
        p.analysis = row.result->result.analysis;
        p.reused = row.result->created_at < info.created_at;
      }
      report.rows.push_back(std::move(p));
    }
  }
  return report;
}

}  // namespace

void to_json(json& j, const DriftPoint& p) {
  j = {{"point", p.point},
       {"replicate", p.replicate},
       {"run_id", p.run_id},
       {"key", p.key},
       {"state", p.state},
       {"uz", OrNull(p.uz)},
       {"uz_previous", OrNull(p.uz_previous)},
       {"difference", OrNull(p.difference)},
       {"drifted", p.drifted},
       {"reused", p.reused},
       {"inconclusive", p.inconclusive},
       {"analysis", p.analysis},
       {"estimator_changed", p.estimator_changed},
       {"uz_stderr", OrNull(p.uz_stderr)},
       {"uz_stderr_previous", OrNull(p.uz_stderr_previous)},
       {"tolerance", OrNull(p.tolerance)},
       {"no_error", p.no_error},
       {"uz_ci95", OrNull(p.uz_ci95)},
       {"uz_ci95_previous", OrNull(p.uz_ci95_previous)},
       {"bed_id", p.bed_id},
       {"bed_id_previous", p.bed_id_previous},
       {"p_value", OrNull(p.p_value)},
       {"not_compared", p.not_compared}};
}

void from_json(const json& j, DriftPoint& p) {
  p.point = j.at("point");
  p.run_id = j.at("run_id").get<int64_t>();
  p.key = j.value("key", "");
  p.state = j.at("state").get<JobState>();
  p.uz = OptField<double>(j, "uz");
  p.uz_previous = OptField<double>(j, "uz_previous");
  p.difference = OptField<double>(j, "difference");
  p.drifted = j.value("drifted", false);
  p.reused = j.value("reused", false);
  p.inconclusive = j.value("inconclusive", false);
  // Reports stored before the field existed were all made by the first analysis.
  p.analysis = j.value("analysis", p.uz ? 1 : 0);
  p.estimator_changed = j.value("estimator_changed", false);
  p.replicate = j.value("replicate", 0);
  p.uz_stderr = OptField<double>(j, "uz_stderr");
  p.uz_stderr_previous = OptField<double>(j, "uz_stderr_previous");
  p.tolerance = OptField<double>(j, "tolerance");
  p.no_error = j.value("no_error", false);
  p.uz_ci95 = OptField<double>(j, "uz_ci95");
  p.uz_ci95_previous = OptField<double>(j, "uz_ci95_previous");
  p.bed_id = j.value("bed_id", int64_t{0});
  p.bed_id_previous = j.value("bed_id_previous", int64_t{0});
  p.p_value = OptField<double>(j, "p_value");
  p.not_compared = j.value("not_compared", "");
}

void to_json(json& j, const DriftAggregate& a) {
  j = {{"point", a.point},
       {"replicates", a.replicates},
       {"conclusive", a.conclusive},
       {"replicates_previous", a.replicates_previous},
       {"conclusive_previous", a.conclusive_previous},
       {"uz_mean", OrNull(a.uz_mean)},
       {"uz_stderr", OrNull(a.uz_stderr)},
       {"uz_mean_previous", OrNull(a.uz_mean_previous)},
       {"uz_stderr_previous", OrNull(a.uz_stderr_previous)},
       {"difference", OrNull(a.difference)},
       {"tolerance", OrNull(a.tolerance)},
       {"drifted", a.drifted},
       {"estimator_changed", a.estimator_changed},
       {"beds_compared", a.beds_compared},
       {"p_value", OrNull(a.p_value)},
       {"drifted_familywise", a.drifted_familywise}};
}

void from_json(const json& j, DriftAggregate& a) {
  a.point = j.at("point");
  a.replicates = j.value("replicates", 0);
  a.conclusive = j.value("conclusive", 0);
  a.replicates_previous = j.value("replicates_previous", 0);
  a.conclusive_previous = j.value("conclusive_previous", 0);
  a.uz_mean = OptField<double>(j, "uz_mean");
  a.uz_stderr = OptField<double>(j, "uz_stderr");
  a.uz_mean_previous = OptField<double>(j, "uz_mean_previous");
  a.uz_stderr_previous = OptField<double>(j, "uz_stderr_previous");
  a.difference = OptField<double>(j, "difference");
  a.tolerance = OptField<double>(j, "tolerance");
  a.drifted = j.value("drifted", false);
  a.estimator_changed = j.value("estimator_changed", false);
  a.beds_compared = j.value("beds_compared", 0);
  a.p_value = OptField<double>(j, "p_value");
  a.drifted_familywise = j.value("drifted_familywise", false);
}

void to_json(json& j, const DriftReport& r) {
  j = {{"campaign_run_id", r.campaign_run_id},
       {"campaign", r.campaign},
       {"scale", r.scale},
       {"trigger", r.trigger},
       {"due_time", OrNull(r.due_time)},
       {"campaign_run_created_at", r.campaign_run_created_at},
       {"previous_campaign_run_id", OrNull(r.previous_campaign_run_id)},
       {"tolerance_mps", r.tolerance_mps},
       {"created_at", r.created_at},
       {"points", r.points},
       {"reused", r.reused},
       {"ran", r.ran},
       {"missing", r.missing},
       {"inconclusive", r.inconclusive},
       {"estimator_changed", r.estimator_changed},
       {"compared", r.compared},
       {"drifted", r.drifted},
       {"no_error", r.no_error},
       {"summary", r.summary},
       {"rows", r.rows},
       {"aggregates", r.aggregates},
       {"points_compared", r.points_compared},
       {"points_drifted", r.points_drifted},
       {"rule", r.rule},
       {"points_drifted_familywise", r.points_drifted_familywise},
       {"campaign_drifted", r.campaign_drifted},
       {"false_alarms", r.false_alarms}};
  j["definition_changed"] = r.definition_changed ? json{{"from_version", r.definition_changed->from_version},
                                                        {"to_version", r.definition_changed->to_version},
                                                        {"since_campaign_run_id",
                                                         r.definition_changed->since_campaign_run_id}}
                                                  : json(nullptr);
}

void from_json(const json& j, DriftReport& r) {
  r.campaign_run_id = j.at("campaign_run_id").get<int64_t>();
  r.campaign = j.at("campaign").get<std::string>();
  r.scale = j.at("scale").get<std::string>();
  r.trigger = j.value("trigger", "manual");
  r.due_time = OptField<double>(j, "due_time");
  r.campaign_run_created_at = j.value("campaign_run_created_at", 0.0);
  r.previous_campaign_run_id = OptField<int64_t>(j, "previous_campaign_run_id");
  r.tolerance_mps = j.value("tolerance_mps", 0.0);
  r.created_at = j.value("created_at", 0.0);
  r.points = j.value("points", int64_t{0});
  r.reused = j.value("reused", int64_t{0});
  r.ran = j.value("ran", int64_t{0});
  r.missing = j.value("missing", int64_t{0});
  r.inconclusive = j.value("inconclusive", int64_t{0});
  r.estimator_changed = j.value("estimator_changed", int64_t{0});
  r.compared = j.value("compared", int64_t{0});
  r.drifted = j.value("drifted", int64_t{0});
  r.summary = j.value("summary", "");
  r.rows = j.value("rows", std::vector<DriftPoint>{});
  r.no_error = j.value("no_error", int64_t{0});
  r.aggregates = j.value("aggregates", std::vector<DriftAggregate>{});
  r.points_compared = j.value("points_compared", int64_t{0});
  r.points_drifted = j.value("points_drifted", int64_t{0});
  r.rule = j.value("rule", 1);  // reports made before rules were numbered: rule 1
  r.points_drifted_familywise = j.value("points_drifted_familywise", int64_t{0});
  r.campaign_drifted = j.value("campaign_drifted", false);
  r.false_alarms = j.value("false_alarms", "");
  if (auto it = j.find("definition_changed"); it != j.end() && it->is_object()) {
    r.definition_changed = DefinitionChange{it->value("from_version", 0), it->value("to_version", 0),
                                            it->value("since_campaign_run_id", int64_t{0})};
  }
}

void CompareWithPrevious(DriftReport& report, const DriftReport* previous, CronZone zone) {
  const bool fixed = report.tolerance_mps > 0;
  report.rule = kDriftRuleVersion;
  const double bed_prior = BedPriorOf(report.scale);
  // The decision over a point's beds (core/drift.h): each pair a run with itself the night before.
  auto decide = [&](std::vector<DriftBedPair> beds) {
    DriftTest test;
    test.beds = std::move(beds);
    test.tolerance_mps = report.tolerance_mps;
    test.bed_sd_rel = bed_prior;
    return DecideDrift(test);
  };
  std::map<std::string, const DriftPoint*> before;
  if (previous != nullptr) {
    report.previous_campaign_run_id = previous->campaign_run_id;
    for (const DriftPoint& p : previous->rows) before[RunIdentity(p)] = &p;
  }
  report.points = static_cast<int64_t>(report.rows.size());
  report.reused = report.ran = report.missing = report.compared = report.drifted = report.inconclusive = 0;
  report.estimator_changed = report.no_error = 0;
  int64_t other_beds = 0;  // runs on a re-poured bed at a scale with no bed-to-bed prior
  bool measured_design = true;  // every compared pair like those kMeasured was measured on
  for (DriftPoint& p : report.rows) {
    p.uz_previous.reset();
    p.uz_stderr_previous.reset();
    p.uz_ci95_previous.reset();
    p.bed_id_previous = 0;
    p.difference.reset();
    p.tolerance.reset();
    p.p_value.reset();
    p.drifted = false;
    p.estimator_changed = false;
    p.no_error = false;
    p.not_compared.clear();
    if (!p.uz && !p.inconclusive) {
      ++report.missing;
      continue;
    }
    ++(p.reused ? report.reused : report.ran);
    if (p.inconclusive) {
      ++report.inconclusive;
      continue;
    }
    auto it = before.find(RunIdentity(p));
    if (it == before.end() || !it->second->uz || it->second->inconclusive) continue;
    if (it->second->analysis != p.analysis) {
      p.estimator_changed = true;
      ++report.estimator_changed;
      continue;
    }
    p.uz_previous = it->second->uz;
    p.uz_stderr_previous = it->second->uz_stderr;
    p.uz_ci95_previous = it->second->uz_ci95;
    p.bed_id_previous = it->second->bed_id;
    p.difference = *p.uz - *p.uz_previous;
    const DriftBedPair pair = PairOf(p);
    const DriftDecision d = decide({pair});
    if (!d.compared) {
      p.not_compared = d.not_compared;
      p.no_error = d.not_compared == "no error";
      ++(p.no_error ? report.no_error : other_beds);
      continue;
    }
    // The measured rates (core/drift.cc kMeasured) are for pairs on the same bed with both
    // intervals known: any other pair makes this a design they were not measured at.
    if (!pair.same_bed || !p.uz_ci95 || !p.uz_ci95_previous) measured_design = false;
    p.tolerance = d.tolerance;
    if (d.tested) p.p_value = d.p_value;
    p.drifted = d.drifted;
    ++report.compared;
    if (p.drifted) ++report.drifted;
  }

  // Points over their replicate beds: the beds compared above, each with itself. Two means are
  // compared only when they share their estimator (SameEstimator).
  report.aggregates.clear();
  report.points_compared = report.points_drifted = report.points_drifted_familywise = 0;
  report.campaign_drifted = false;
  bool replicated = false;
  std::map<std::string, std::pair<json, ReplicateAggregate>> earlier;
  std::map<std::string, BedAnalyses> analyses_now = AnalysesOf(report.rows), analyses_before;
  if (previous != nullptr) {
    earlier = AggregatesOf(previous->rows);
    analyses_before = AnalysesOf(previous->rows);
  }
  std::vector<std::string> order;
  std::map<std::string, std::vector<DriftBedPair>> pairs;
  for (const DriftPoint& p : report.rows) {
    const std::string id = PointIdentity(p.point);
    if (std::find(order.begin(), order.end(), id) == order.end()) order.push_back(id);
    if (p.tolerance) pairs[id].push_back(PairOf(p));
  }
  auto now = AggregatesOf(report.rows);
  std::vector<double> p_values;
  std::vector<size_t> tested;  // aggregates with a p-value, in p_values' order
  for (const std::string& id : order) {
    const auto& [point, agg] = now.at(id);
    DriftAggregate a;
    a.point = point;
    a.replicates = agg.replicates;
    a.conclusive = agg.conclusive;
    a.uz_mean = agg.uz_mean;
    a.uz_stderr = agg.uz_stderr;
    replicated = replicated || agg.replicates > 1;
    if (auto it = earlier.find(id); it != earlier.end()) {
      const ReplicateAggregate& b = it->second.second;
      a.replicates_previous = b.replicates;
      a.conclusive_previous = b.conclusive;
      a.uz_mean_previous = b.uz_mean;
      a.uz_stderr_previous = b.uz_stderr;
      a.estimator_changed = a.uz_mean && a.uz_mean_previous && !SameEstimator(analyses_now[id], analyses_before[id]);
      if (a.uz_mean && a.uz_mean_previous && !a.estimator_changed && !pairs[id].empty()) {
        const DriftDecision d = decide(pairs[id]);
        a.beds_compared = d.beds;
        if (d.compared) {
          a.difference = d.difference;
          a.tolerance = d.tolerance;
          a.drifted = d.drifted;
          ++report.points_compared;
          if (a.drifted) ++report.points_drifted;
          if (d.tested) {
            a.p_value = d.p_value;
            p_values.push_back(d.p_value);
            tested.push_back(report.aggregates.size());
          }
        }
      }
    }
    report.aggregates.push_back(std::move(a));
  }
  // The campaign: did any point drift, at family-wise 5 % across the points tested (Holm)?
  const std::vector<bool> holm = HolmFlags(p_values);
  for (size_t i = 0; i < tested.size(); ++i) {
    DriftAggregate& a = report.aggregates[tested[i]];
    a.drifted_familywise = holm[i] && a.drifted;
    if (a.drifted_familywise) ++report.points_drifted_familywise;
  }
  report.campaign_drifted = report.points_drifted_familywise > 0;
  int beds = 1;
  for (const DriftAggregate& a : report.aggregates) beds = std::max(beds, a.replicates);
  report.false_alarms = DriftAlarmText(report.campaign, report.scale, beds, measured_design);

  std::string head = report.campaign + "@" + report.scale + " ";
  if (report.trigger == "schedule" && report.due_time) {
    head += "night " + FormatWallMinute(*report.due_time, zone);
  } else {
    head += "rerun cr:" + std::to_string(report.campaign_run_id) + " (" + report.trigger + ", " +
            FormatWallMinute(report.campaign_run_created_at, zone) + ")";
  }
  std::string line =
      head + ": " + std::to_string(report.points) + " points, " + std::to_string(report.reused) + " reused, " +
      std::to_string(report.ran) + " run, " + std::to_string(report.drifted) +
      (fixed ? " drifted beyond " + Tolerance(report.tolerance_mps) + " m/s" : " drifted beyond its 95 % bound");
  if (report.inconclusive > 0) line += ", " + std::to_string(report.inconclusive) + " inconclusive (not compared)";
  if (report.estimator_changed > 0) {
    line += ", " + std::to_string(report.estimator_changed) + " not compared (U_z analysis changed)";
  }
  if (report.no_error > 0) line += ", " + std::to_string(report.no_error) + " not compared (no error)";
  if (other_beds > 0) {
    line += ", " + std::to_string(other_beds) + " not compared (another bed, the scatter between beds not known)";
  }
  if (report.missing > 0) line += ", " + std::to_string(report.missing) + " failed or cancelled";
  if (replicated) {
    line += "; " + std::to_string(report.points_drifted) + " of " + std::to_string(report.points_compared) +
            " points' means over their beds drifted";
  }
  if (!tested.empty()) {
    line += report.campaign_drifted ? "; the campaign drifted: " + std::to_string(report.points_drifted_familywise) +
                                          " point(s) at family-wise 5 % (Holm)"
                                    : "; the campaign: no change beyond chance (Holm, family-wise 5 %)";
  }
  if (previous == nullptr) line += "; first report, nothing to compare";
  report.summary = line;
}

void SayDefinitionChanged(DriftReport& report, const DefinitionChange& change, bool compared) {
  report.definition_changed = change;
  const std::string what = "definition changed (version " + std::to_string(change.from_version) + " -> " +
                           std::to_string(change.to_version) + ")";
  const std::string first = "; first report, nothing to compare";
  if (!compared) {
    if (report.summary.size() >= first.size() &&
        report.summary.compare(report.summary.size() - first.size(), first.size(), first) == 0) {
      report.summary.erase(report.summary.size() - first.size());
    }
    report.summary += "; " + what + ", no earlier run of this definition to compare with";
  } else {
    report.summary += "; " + what + " since cr:" + std::to_string(change.since_campaign_run_id) +
                      ", compared with cr:" + std::to_string(report.previous_campaign_run_id.value_or(0)) +
                      " of the same definition";
  }
}

Result<std::vector<DriftReport>> ReportFinishedCampaignRuns(Store& store, double now, CronZone zone) {
  std::vector<int64_t> ids;
  {
    auto t = store.db().BeginRead();
    if (!t.ok()) return t.status();
    auto finished = drift_table::FinishedWithoutReport(*t);
    if (!finished.ok()) return finished.status();
    ids = std::move(finished).value();
  }
  std::vector<DriftReport> made;
  for (int64_t id : ids) {
    auto info = store.GetCampaignRun(id);
    if (!info.ok()) return info.status();
    auto report = CurrentState(store, *info, now);
    if (!report.ok()) return report.status();
    auto baseline = BaselineFor(store, *info);
    if (!baseline.ok()) return baseline.status();
    CompareWithPrevious(*report, baseline->report ? &*baseline->report : nullptr, zone);
    if (baseline->changed) SayDefinitionChanged(*report, *baseline->changed, baseline->report.has_value());

    auto t = store.db().Begin();
    if (!t.ok()) return t.status();
    drift_table::NewReport row;
    row.campaign_run_id = report->campaign_run_id;
    row.campaign = report->campaign;
    row.scale = report->scale;
    row.previous_campaign_run_id = report->previous_campaign_run_id;
    row.tolerance_mps = report->tolerance_mps;
    row.points = report->points;
    row.reused = report->reused;
    row.ran = report->ran;
    row.missing = report->missing;
    row.drifted = report->drifted;
    row.report = json(*report).dump();
    row.created_at = now;
    auto inserted = drift_table::Insert(*t, row);
    if (!inserted.ok()) return inserted.status();
    if (*inserted) {
      SANDSWIM_RETURN_IF_ERROR(t->Event(now, "campaign_run.drift_report", "campaign_run/" + std::to_string(id),
                                        {{"drifted", report->drifted}, {"summary", report->summary}}));
    }
    SANDSWIM_RETURN_IF_ERROR(t->Commit());
    made.push_back(std::move(report).value());
  }
  return made;
}

Result<std::optional<DriftReport>> DriftReportFor(Store& store, int64_t campaign_run_id) {
  auto t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return Decode(drift_table::ReportOf(*t, campaign_run_id));
}

Result<std::optional<DriftReport>> LatestDriftReport(Store& store, const std::string& campaign,
                                                     const std::string& scale) {
  auto t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return Decode(drift_table::Latest(*t, campaign, scale));
}

Result<std::optional<DriftReport>> LastDriftFor(Store& store, const CampaignRunInfo& run) {
  auto own = DriftReportFor(store, run.id);
  if (!own.ok() || own->has_value()) return own;
  return PreviousReport(store, run.campaign, run.scale, run.id);
}

}  // namespace sandswim
