#include "tests/truth/calibration.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <mutex>
#include <set>
#include <thread>

#include "core/deck.h"
#include "core/drift.h"
#include "core/engine_log.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/drift_report.h"
#include "server/analysis/report.h"
#include "workers/job_outcome.h"

namespace sandswim::truth {
namespace {

bool Contains(const std::string& s, const std::string& what) { return s.find(what) != std::string::npos; }

std::string Pct(int64_t k, int64_t n) {
  if (n == 0) return "–";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", 100.0 * static_cast<double>(k) / static_cast<double>(n));
  return buf;
}

std::string PctInterval(int64_t k, int64_t n) {
  if (n == 0) return "–";
  auto [lo, hi] = WilsonInterval(k, n);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f [%.1f, %.1f]", 100.0 * static_cast<double>(k) / static_cast<double>(n),
                100 * lo, 100 * hi);
  return buf;
}

}  // namespace

Result<Calibrator> Calibrator::Make(const Design& design) {
  Calibrator c;
  c.design_ = design;
  c.scale_ = FindScale(design.scale);
  if (c.scale_ == nullptr) return Status::InvalidArgument("scale", "unknown scale '" + design.scale + "'");
  Result<Campaign> campaign = BuiltinCampaign(design.campaign);
  if (!campaign.ok()) return campaign.status();
  c.campaign_ = *campaign;
  for (SweepSpec& s : c.campaign_.sweeps) {
    s.scale = design.scale;
    if (design.beds > 0) s.replicates = design.beds;
    if (design.duration_multiplier != 1) {
      s.base.duration_s *= design.duration_multiplier;
      for (SweepAxis& a : s.axes)
        if (a.param == "duration_s")
          for (double& v : a.values) v *= design.duration_multiplier;
      std::optional<PrecisionTarget> target = s.precision ? s.precision : c.scale_->default_precision;
      if (target) {
        target->max_duration_s *= design.duration_multiplier;
        s.precision = target;
      }
    }
  }
  PlanOptions options;
  options.keep_decks = false;
  Result<std::vector<ScalePlan>> plans = PlanSubmission(c.campaign_.sweeps, "truth-engine", options, true);
  if (!plans.ok()) return plans.status();
  if (plans->size() != 1) return Status::Internal("a campaign at one scale plans one group");
  c.plan_ = (*plans)[0].plan;
  for (const SweepSpec& s : c.campaign_.sweeps) {
    Result<std::vector<Point>> points = ExpandSweep(s);
    if (!points.ok()) return points.status();
    std::vector<size_t> rows;
    for (const Point& p : *points) {
      for (int r = 0; r < s.Replicates(); ++r) {
        for (size_t i = 0; i < c.plan_.runs.size(); ++i) {
          if (c.plan_.runs[i].replicate == r && SameDrive(c.plan_.runs[i].point, p)) {
            rows.push_back(i);
            break;
          }
        }
      }
    }
    c.sweep_rows_.emplace_back(s.name, std::move(rows));
  }
  return c;
}

DesignKey Calibrator::Key() const {
  DesignKey k;
  k.campaign = design_.campaign;
  Result<nlohmann::json> definition = BuiltinCampaignDefinition(design_.campaign);
  k.definition_hash = definition.ok() ? CampaignDefinitionHash(*definition, campaign_.claims) : std::string();
  k.scale = design_.scale;
  k.beds = static_cast<int>(plan_.beds.size());
  k.bed_sd_rel = BedPriorOf(k.scale);
  return k;
}

double Calibrator::PlannedSimSeconds() const {
  double s = 0;
  for (const PlannedRun& r : plan_.runs) s += r.run_duration_s;
  return s;
}

SimRun Calibrator::RunOne(const Law& law, const Noise& noise, const Bed& bed, const Point& point, double duration_s,
                          const std::optional<PrecisionTarget>& target, uint64_t world, uint64_t night,
                          int64_t run_id, ResultRow* out_row) const {
  const DriveInfo drive = DriveFacts(point, *scale_);
  RunSpec spec;
  spec.point = point;
  spec.duration_s = duration_s;
  spec.z_floor = scale_->z_floor;
  spec.lag_s = design_.follow_lag_s;
  const DriveStartMarker start{bed.grains, bed.z0, bed.surface};
  // The worker: it looks at the growing dump now and then (its heartbeat), but here only when
  // its answer can have changed -- at each block's end (a look between two sees no new block),
  // from the first time the window can hold the target's min_periods blocks, at most every
  // follow_every_s -- and whenever the SO has come within the clearance of a boundary since its
  // last look (the window may have closed). A real worker looks more often, to the same effect.
  const double block = drive.f > 0 ? 1 / drive.f : WindowRule{}.undriven_block_s;
  const double every = std::max(design_.follow_every_s, block);
  const double clearance = WindowRule{}.clearance_m, r_so = kMaterials.d_so / 2;
  double next_look = target ? std::max(every, target->min_periods * block) : every;
  bool near_boundary = false;
  if (target && design_.follow) {
    spec.stop_hook = [&, target](const std::vector<SoSample>& so_far, std::string* reason) {
      const SoSample& s = so_far.back();
      const bool near = s.z + r_so + clearance >= bed.surface || s.z - r_so - clearance <= scale_->z_floor;
      const bool first_near = near && !near_boundary;
      near_boundary = near_boundary || near;
      if (s.t < next_look - 1e-12 && !first_near) return false;
      while (next_look <= s.t + 1e-12) next_look += every;
      const StopVerdict v = worker::FollowRun(so_far, drive, start, *target);
      if (v == StopVerdict::kContinue) return false;
      *reason = v == StopVerdict::kTargetMet ? "target" : "window";
      return true;
    };
  }
  const uint64_t seed = RunSeed(world ^ (night * 0x9e3779b97f4a7c15ULL), bed.replicate, point);
  EngineRun engine = GenerateRun(law, noise, bed, spec, seed);
  SimRun run;
  run.point = point;
  run.replicate = bed.replicate;
  run.true_uz = engine.true_uz;
  run.law_uz = LawUz(law, point);
  run.planned_s = spec.duration_s;
  run.simulated_s = engine.samples.back().t;
  run.stop_reason = engine.stop.reason;
  run.has_target = target.has_value();
  EngineLog log;
  log.drive_start = engine.start;
  log.drive_stop = engine.stop;
  Result<api::RunResult> result = AnalyzeRun(engine.samples, RunInputsFrom(drive, log, target));
  if (result.ok())
    run.result = *result;
  else
    run.failure = "bad_output: " + result.status().reason();
  if (out_row != nullptr) {
    ResultRow row;
    row.run_id = run_id;
    row.point = point;
    row.run_duration_s = duration_s;
    row.bed_id = bed.replicate + 1;
    row.replicate = bed.replicate;
    if (result.ok()) {
      row.state = JobState::kDone;
      row.result = StoredResult{*result, {}, {}, 0};
    } else {
      row.state = JobState::kFailed;
    }
    *out_row = std::move(row);
  }
  return run;
}

SimCampaign Calibrator::Simulate(const Law& law, const Noise& noise, uint64_t world, uint64_t night) const {
  SimCampaign out;
  std::vector<Bed> beds;
  for (const PlannedBed& b : plan_.beds) beds.push_back(MakeBed(world, b.replicate, noise, *scale_));
  std::vector<ResultRow> all_rows;
  for (size_t i = 0; i < plan_.runs.size(); ++i) {
    const PlannedRun& planned = plan_.runs[i];
    const Bed& bed = beds.at(static_cast<size_t>(planned.replicate));
    std::optional<PrecisionTarget> target = design_.precision ? planned.precision : std::nullopt;
    const double duration = design_.precision ? planned.run_duration_s : planned.point.duration_s;
    ResultRow row;
    SimRun run = RunOne(law, noise, bed, planned.point, duration, target, world, night,
                        static_cast<int64_t>(i) + 1, &row);
    row.key = planned.key;
    row.run_duration_s = planned.run_duration_s;
    if (row.result) row.result->key = planned.key;
    out.runs.push_back(std::move(run));
    all_rows.push_back(std::move(row));
  }
  ClaimInput input;
  input.scale = design_.scale;
  int64_t sweep_id = 0;
  for (const auto& [name, indexes] : sweep_rows_) {
    std::vector<ResultRow> rows;
    std::map<int64_t, std::string> failures;
    for (size_t i : indexes) {
      rows.push_back(all_rows[i]);
      if (!out.runs[i].failure.empty()) failures[all_rows[i].run_id] = out.runs[i].failure;
    }
    SweepInfo info;
    info.id = ++sweep_id;
    info.name = name;
    info.scale = design_.scale;
    input.sweeps.push_back(ClaimSweepOf(AnalyzeSweepResults(info, rows), rows, failures));
  }
  for (size_t b = 0; b < beds.size(); ++b) {
    ClaimBed bed;
    bed.id = static_cast<int64_t>(b) + 1;
    bed.replicate = beds[b].replicate;
    bed.state = JobState::kDone;
    bed.grains = beds[b].grains;
    bed.bed_height = beds[b].surface - scale_->z_floor;
    input.beds.push_back(bed);
  }
  out.verdicts = EvaluateClaims(campaign_.claims, input);
  out.sweeps = std::move(input.sweeps);
  out.beds = std::move(input.beds);
  return out;
}

std::optional<bool> TruthOf(const Law& law, const std::string& claim_id, const std::string& part) {
  if (part.empty()) {
    // The whole claim: decided by its parts as the law states them.
    std::vector<std::string> parts;
    if (claim_id == "F1") parts = {"sign"};
    if (claim_id == "F2") parts = {"rising: |U_z| grows", "rising: saturates", "sinking: |U_z| grows",
                                   "sinking: saturates", "past |Omega|"};
    if (claim_id == "F3") parts = {"rising: U_z", "sinking: linear"};
    if (claim_id == "F4") parts = {"peaks"};
    if (claim_id == "F5") parts = {"vibration alone rises", "rises fastest", "stays within", "z oscillates",
                                   "x oscillates"};
    if (parts.empty()) return std::nullopt;
    bool all = true;
    for (const std::string& p : parts) {
      std::optional<bool> t = TruthOf(law, claim_id, p);
      if (t && !*t) return false;
      all = all && t.has_value();
    }
    return all ? std::optional<bool>(true) : std::nullopt;
  }
  if (claim_id == "F6") return std::nullopt;
  if (claim_id == "F1") return law.name != "sign_wrong";
  if (claim_id == "F2") {
    if (Contains(part, "past |Omega|") || law.name == "sign_wrong") return std::nullopt;
    if (law.name == "flat_Omega") return Contains(part, "saturat") ? std::nullopt : std::optional<bool>(false);
    if (law.name == "no_saturation") return !Contains(part, "saturat");
    return true;
  }
  if (claim_id == "F3") return !(law.name == "affine_A" && Contains(part, "rising"));
  if (claim_id == "F4") return law.name != "no_peak_f";
  if (claim_id == "F5") {
    if (law.name != "modes_equal") return true;
    return !(Contains(part, "fastest") || Contains(part, "oscillat"));
  }
  return std::nullopt;
}

void LawTally::Add(const SimCampaign& c, const Law& law_) {
  ++campaigns;
  for (const ClaimVerdict& v : c.verdicts) {
    auto add = [&](const std::string& part, Verdict verdict) {
      const auto key = std::make_pair(v.claim.id, part);
      auto [it, inserted] = cells.try_emplace(key);
      if (inserted) order.push_back(key);
      Counts& n = it->second;
      (verdict == Verdict::kHolds ? n.holds : verdict == Verdict::kDiffers ? n.differs : n.inconclusive)++;
    };
    add("", v.verdict);
    for (const ClaimPart& p : v.parts) add(p.name, p.verdict);
  }
  for (const SimRun& r : c.runs) {
    ++runs;
    simulated_s += r.simulated_s;
    if (!r.result || !r.result->uz) continue;
    const api::RunResult& res = *r.result;
    if (res.conclusive) {
      ++conclusive;
      if (r.true_uz != 0) sum_rel_error += (*res.uz - r.true_uz) / std::fabs(r.true_uz);
    }
    if (!res.uz_ci95) continue;
    const bool in = std::fabs(*res.uz - r.true_uz) <= *res.uz_ci95;
    ++runs_all.n;
    runs_all.covered += in;
    Coverage& part = res.stop_reason == "target" ? runs_stopped_early : runs_full;
    ++part.n;
    part.covered += in;
  }
  // Point intervals (a sweep's sample: the run, or its beds' aggregate) against the law's U_z; apart,
  // the points one of whose runs the precision target stopped (their error rests on the periods
  // after the pilot: core/precision.h).
  std::set<DriveId> stopped;
  for (const SimRun& r : c.runs)
    if (r.result && r.result->stop_reason == "target") stopped.insert(DriveIdOf(r.point));
  for (const ClaimSweep& s : c.sweeps) {
    for (const SweepSample& x : s.samples) {
      if (!x.has_uz || !x.conclusive || x.uz_ci95 <= 0) continue;
      const bool in = std::fabs(x.uz - LawUz(law_, x.point)) <= x.uz_ci95;
      ++points_vs_law.n;
      points_vs_law.covered += in;
      if (stopped.count(DriveIdOf(x.point))) {
        ++points_stopped_early.n;
        points_stopped_early.covered += in;
      }
    }
  }
}

LawTally RunLaw(const Calibrator& cal, const Law& law, const Noise& noise, int64_t campaigns, uint64_t first_world,
                int threads) {
  const auto started = std::chrono::steady_clock::now();
  std::atomic<int64_t> next{0};
  std::mutex mu;
  LawTally total;
  total.law = law.name;
  // Each thread tallies its own campaigns; the tallies are merged in world order afterwards, so the
  // table's row order does not depend on the threads.
  std::vector<std::pair<int64_t, SimCampaign>> done;
  auto work = [&] {
    std::vector<std::pair<int64_t, SimCampaign>> mine;
    for (int64_t i; (i = next++) < campaigns;) mine.emplace_back(i, cal.Simulate(law, noise, first_world + i));
    std::lock_guard<std::mutex> lock(mu);
    for (auto& m : mine) done.push_back(std::move(m));
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, threads); ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  std::sort(done.begin(), done.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [i, c] : done) total.Add(c, law);
  total.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return total;
}


std::string CalibrationMarkdown(const std::vector<LawTally>& tallies, const Design& design) {
  std::string out = "Design: campaign " + design.campaign + " at " + design.scale + ", " +
                    (design.beds > 0 ? std::to_string(design.beds) : std::string("the campaign's")) +
                    " bed(s) per point, durations x" + Num(design.duration_multiplier) +
                    (design.precision ? ", precision targets as planned" : ", no precision target") + ".\n\n";
  out +=
      "| law | claim | part | true? | n | holds % [95 %] | differs % [95 %] | inconclusive % | reads as |\n"
      "| --- | --- | --- | --- | ---: | --- | --- | ---: | --- |\n";
  for (const LawTally& t : tallies) {
    const Law* law = FindLaw(t.law);
    for (const auto& key : t.order) {
      const Counts& c = t.cells.at(key);
      std::optional<bool> truth = law ? TruthOf(*law, key.first, key.second) : std::nullopt;
      std::string reads;
      if (truth && *truth) reads = "power " + Pct(c.holds, c.n()) + " %, false differs " + Pct(c.differs, c.n()) + " %";
      if (truth && !*truth) reads = "false holds " + Pct(c.holds, c.n()) + " %";
      out += "| " + t.law + " | " + key.first + " | " + (key.second.empty() ? "(claim)" : key.second) + " | " +
             (truth ? (*truth ? "true" : "FALSE") : "–") + " | " + std::to_string(c.n()) + " | " +
             PctInterval(c.holds, c.n()) + " | " + PctInterval(c.differs, c.n()) + " | " +
             Pct(c.inconclusive, c.n()) + " | " + reads + " |\n";
    }
  }
  out +=
      "\n| law | campaigns | runs | conclusive % | mean (U_z - true)/|true| % | run 95 % interval coverage: all | "
      "stopped at target | ran on | point intervals vs law | points with a run stopped at target | "
      "simulated s per campaign | campaigns/s |\n"
      "| --- | ---: | ---: | ---: | ---: | --- | --- | --- | --- | --- | ---: | ---: |\n";
  for (const LawTally& t : tallies) {
    auto cov = [](const Coverage& c) { return PctInterval(c.covered, c.n) + " (n " + std::to_string(c.n) + ")"; };
    out += "| " + t.law + " | " + std::to_string(t.campaigns) + " | " + std::to_string(t.runs) + " | " +
           Pct(t.conclusive, t.runs) + " | " +
           (t.conclusive ? Num(100 * t.sum_rel_error / static_cast<double>(t.conclusive), 3) : std::string("–")) +
           " | " + cov(t.runs_all) + " | " + cov(t.runs_stopped_early) + " | " + cov(t.runs_full) + " | " +
           cov(t.points_vs_law) + " | " + cov(t.points_stopped_early) + " | " +
           (t.campaigns ? Num(t.simulated_s / static_cast<double>(t.campaigns), 4) : std::string("–")) + " | " +
           (t.seconds > 0 ? Num(static_cast<double>(t.campaigns) / t.seconds, 3) : std::string("–")) + " |\n";
  }
  return out;
}

nlohmann::json NoiseToJson(const Noise& n) {
  return {{"period_rel", n.period_rel},     {"diffusion", n.diffusion},     {"ma_theta", n.ma_theta},
          {"bed_common", n.bed_common},     {"bed_point", n.bed_point},     {"bed_offset", n.bed_offset},
          {"jitter_sd", n.jitter_sd},       {"jitter_phi", n.jitter_phi},   {"transient_v0", n.transient_v0},
          {"transient_tau", n.transient_tau}, {"x_walk", n.x_walk}};
}

nlohmann::json CalibrationJson(const std::vector<LawTally>& tallies, const Calibrator& cal, const Noise& noise) {
  const Design& design = cal.design();
  nlohmann::json laws = nlohmann::json::array();
  for (const LawTally& t : tallies) {
    const Law* law = FindLaw(t.law);
    nlohmann::json cells = nlohmann::json::array();
    for (const auto& key : t.order) {
      const Counts& c = t.cells.at(key);
      std::optional<bool> truth = law ? TruthOf(*law, key.first, key.second) : std::nullopt;
      auto rate = [&](int64_t k) {
        auto [lo, hi] = WilsonInterval(k, c.n());
        return nlohmann::json{{"count", k},
                              {"rate", c.n() ? static_cast<double>(k) / static_cast<double>(c.n()) : 0.0},
                              {"lo", lo},
                              {"hi", hi}};
      };
      cells.push_back({{"claim", key.first},
                       {"part", key.second},
                       {"true", truth ? nlohmann::json(*truth) : nlohmann::json(nullptr)},
                       {"n", c.n()},
                       {"holds", rate(c.holds)},
                       {"differs", rate(c.differs)},
                       {"inconclusive", rate(c.inconclusive)}});
    }
    auto cov = [](const Coverage& c) { return nlohmann::json{{"n", c.n}, {"covered", c.covered}}; };
    laws.push_back({{"law", t.law},
                    {"breaks", law ? law->breaks : ""},
                    {"campaigns", t.campaigns},
                    {"runs", t.runs},
                    {"conclusive", t.conclusive},
                    {"mean_rel_error", t.conclusive ? t.sum_rel_error / static_cast<double>(t.conclusive) : 0.0},
                    {"coverage", {{"runs_all", cov(t.runs_all)},
                                  {"runs_stopped_at_target", cov(t.runs_stopped_early)},
                                  {"runs_not_stopped_at_target", cov(t.runs_full)},
                                  {"points_vs_law", cov(t.points_vs_law)},
                                  {"points_with_a_run_stopped_at_target", cov(t.points_stopped_early)}}},
                    {"simulated_s_per_campaign", t.campaigns ? t.simulated_s / static_cast<double>(t.campaigns) : 0.0},
                    {"wall_s", t.seconds},
                    {"cells", cells}});
  }
  return {{"design",
           {{"campaign", design.campaign},
            {"scale", design.scale},
            {"beds", design.beds},
            {"duration_multiplier", design.duration_multiplier},
            {"precision", design.precision},
            {"follow", design.follow},
            {"follow_every_s", design.follow_every_s},
            {"follow_lag_s", design.follow_lag_s},
            {"planned_simulated_s", cal.PlannedSimSeconds()},
            {"noise", NoiseToJson(noise)},
            {"key", DesignKeyToJson(cal.Key())}}},
          {"laws", laws}};
}

namespace {
DriftReport NightReport(const SimCampaign& c, int64_t id, const Design& design) {
  DriftReport r;
  r.campaign_run_id = id;
  r.campaign = design.campaign;
  r.scale = design.scale;
  for (size_t i = 0; i < c.runs.size(); ++i) {
    const SimRun& run = c.runs[i];
    DriftPoint p;
    p.point = PointToJson(run.point);
    p.replicate = run.replicate;
    p.bed_id = run.replicate + 1;  // the same beds both nights
    p.run_id = static_cast<int64_t>(i) + 1;
    p.state = run.result ? JobState::kDone : JobState::kFailed;
    if (run.result) {
      p.analysis = run.result->analysis;
      p.inconclusive = !run.result->conclusive;
      if (run.result->conclusive) {
        p.uz = run.result->uz;
        p.uz_stderr = run.result->uz_stderr;
        p.uz_ci95 = run.result->uz_ci95;
      }
    }
    r.rows.push_back(std::move(p));
  }
  return r;
}
}  // namespace

DriftAlarms MeasureDriftAlarms(const Calibrator& cal, const Law& law, const Noise& noise, int64_t campaigns,
                               uint64_t first_world, int threads, double change) {
  Law changed = law;
  changed.uz_factor *= change;
  std::atomic<int64_t> next{0};
  std::mutex mu;
  DriftAlarms total;
  auto work = [&] {
    DriftAlarms mine;
    for (int64_t i; (i = next++) < campaigns;) {
      const uint64_t world = first_world + static_cast<uint64_t>(i);
      DriftReport before = NightReport(cal.Simulate(law, noise, world, 1), 1, cal.design());
      DriftReport now = NightReport(cal.Simulate(changed, noise, world, 2), 2, cal.design());
      CompareWithPrevious(before, nullptr, CronZone::kUtc);
      CompareWithPrevious(now, &before, CronZone::kUtc);
      ++mine.campaigns;
      mine.runs_compared += now.compared;
      mine.runs_drifted += now.drifted;
      mine.points_compared += now.points_compared;
      mine.points_drifted += now.points_drifted;
      if (now.points_drifted > 0) ++mine.campaigns_any_point;
      if (now.campaign_drifted) ++mine.campaigns_drifted;
      // Rule 1 on the same pairs of runs.
      int64_t rule1 = 0;
      for (const DriftPoint& p : now.rows) {
        if (!p.tolerance || !p.uz_stderr || !p.uz_stderr_previous) continue;
        DriftTest test;
        test.rule = 1;
        test.beds.push_back({*p.uz, *p.uz_stderr, kNormalDof, *p.uz_previous, *p.uz_stderr_previous, kNormalDof, true});
        if (DecideDrift(test).drifted) ++rule1;
      }
      mine.runs_drifted_rule1 += rule1;
      if (rule1 > 0) ++mine.campaigns_any_run_rule1;
    }
    std::lock_guard<std::mutex> lock(mu);
    total.campaigns += mine.campaigns;
    total.runs_compared += mine.runs_compared;
    total.runs_drifted += mine.runs_drifted;
    total.points_compared += mine.points_compared;
    total.points_drifted += mine.points_drifted;
    total.campaigns_any_point += mine.campaigns_any_point;
    total.campaigns_drifted += mine.campaigns_drifted;
    total.runs_drifted_rule1 += mine.runs_drifted_rule1;
    total.campaigns_any_run_rule1 += mine.campaigns_any_run_rule1;
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, threads); ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  return total;
}

}  // namespace sandswim::truth
