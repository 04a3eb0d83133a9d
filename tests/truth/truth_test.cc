// The truth engine and its calibration harness checked on their own (not the claims' rules, whose
// error rates they measure): the analysis recovers a law's U_z from its trajectories, without bias
// when there is noise; the bed effect is shared by a bed's points and averages out over beds; a
// simulated campaign is reproducible from its seed; and on near-noiseless data the harness hands
// the claims what the law says (the signs of F1 and F5's "vibration alone rises").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include <gtest/gtest.h>

#include "core/api.h"
#include "core/claim_rates.h"
#include "core/drift.h"
#include "core/embedded.h"
#include "core/engine_log.h"
#include "core/trajectory.h"
#include "tests/truth/calibration.h"
#include "tests/truth/truth_law.h"

namespace sandswim::truth {
namespace {

Result<api::RunResult> Analyze(const EngineRun& run, const Point& p, const Scale& scale) {
  EngineLog log;
  log.drive_start = run.start;
  log.drive_stop = run.stop;
  return AnalyzeRun(run.samples, RunInputsFrom(DriveFacts(p, scale), log));
}

// Only the per-period scatter: no bed effect, no transient, no jitter.
Noise PeriodNoiseOnly() {
  Noise n = Noise::None();
  Noise d;
  n.period_rel = d.period_rel;
  n.diffusion = d.diffusion;
  n.ma_theta = d.ma_theta;
  return n;
}

// A slow point that keeps far from the boundaries for 3 s at smoke.
Point SlowPoint() { return OscillatoryPoint(0.03, 3, -10, 3); }

TEST(TruthLawTest, LawsAgreeAtTheBaselineAndBreakWhatTheySay) {
  const Law& paper = *FindLaw("paper");
  const Point rise = OscillatoryPoint(0.03, 3, -80, 4), sink = OscillatoryPoint(0.03, 3, 80, 4);
  for (const Law& law : AllLaws()) {
    EXPECT_NEAR(LawUz(law, rise), LawUz(paper, rise), 1e-12) << law.name;
    EXPECT_NEAR(LawUz(law, sink), LawUz(paper, sink), 1e-12) << law.name;
    if (law.name != "paper") {
      EXPECT_FALSE(law.breaks.empty()) << law.name;
    }
  }
  EXPECT_GT(LawUz(paper, rise), 0);
  EXPECT_LT(LawUz(paper, sink), 0);
  // The paper law peaks at 5 Hz; no_peak_f rises monotonically.
  const Law& nopeak = *FindLaw("no_peak_f");
  EXPECT_GT(LawUz(paper, OscillatoryPoint(0.03, 5, -80, 4)), LawUz(paper, OscillatoryPoint(0.03, 4, -80, 4)));
  EXPECT_GT(LawUz(paper, OscillatoryPoint(0.03, 5, -80, 4)), LawUz(paper, OscillatoryPoint(0.03, 6, -80, 4)));
  EXPECT_GT(LawUz(nopeak, OscillatoryPoint(0.03, 30, -80, 4)), LawUz(nopeak, OscillatoryPoint(0.03, 20, -80, 4)));
  // sign_wrong: the slowest |Omega| moves the other way.
  EXPECT_LT(LawUz(*FindLaw("sign_wrong"), OscillatoryPoint(0.03, 3, -10, 4)), 0);
  EXPECT_GT(LawUz(paper, OscillatoryPoint(0.03, 3, -10, 4)), 0);
}

TEST(TruthLawTest, NoiselessTrajectoryGivesTheLawsRate) {
  const Scale& smoke = *FindScale("smoke");
  const Law& paper = *FindLaw("paper");
  const Noise none = Noise::None();
  const Bed bed = MakeBed(7, 0, none);
  for (const Point& p : {SlowPoint(), OscillatoryPoint(0.03, 5, -20, 3), OscillatoryPoint(0.05, 2, 20, 3),
                         OscillatoryPoint(0.03, 10, 10, 3)}) {
    RunSpec spec;
    spec.point = p;
    spec.duration_s = p.duration_s;
    spec.z_floor = smoke.z_floor;
    const EngineRun run = GenerateRun(paper, none, bed, spec, 1);
    EXPECT_DOUBLE_EQ(run.true_uz, LawUz(paper, p));
    Result<api::RunResult> r = Analyze(run, p, smoke);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_TRUE(r->uz.has_value());
    EXPECT_NEAR(*r->uz, LawUz(paper, p), 1e-4 * std::fabs(LawUz(paper, p))) << PointToJson(p).dump();
    EXPECT_EQ(r->stop_reason, "duration");
  }
}

TEST(TruthLawTest, NoisyRatesAreUnbiasedAndTheirScatterIsTheStatedOne) {
  const Scale& smoke = *FindScale("smoke");
  const Law& paper = *FindLaw("paper");
  const Noise noise = PeriodNoiseOnly();
  const Point p = SlowPoint();
  const Bed bed = MakeBed(3, 0, noise);
  double sum = 0, sum2 = 0;
  int n = 0;
  for (uint64_t seed = 1; seed <= 400; ++seed) {
    RunSpec spec;
    spec.point = p;
    spec.duration_s = p.duration_s;
    spec.z_floor = smoke.z_floor;
    const EngineRun run = GenerateRun(paper, noise, bed, spec, seed);
    Result<api::RunResult> r = Analyze(run, p, smoke);
    ASSERT_TRUE(r.ok() && r->uz && r->conclusive);
    const double e = *r->uz - run.true_uz;
    sum += e;
    sum2 += e * e;
    ++n;
  }
  const double mean = sum / n, sd = std::sqrt((sum2 - n * mean * mean) / (n - 1));
  EXPECT_LT(std::fabs(mean), 4 * sd / std::sqrt(n)) << "bias " << mean << " m/s";
  // The scatter of a run's U_z is the per-period scatter over its blocks: 8 blocks in 3 s at 3 Hz
  // after one transient period, each with sd sqrt(D T + (rel U T)^2) / T, MA(1)-correlated: the
  // mean's variance is (1 + 2 rho (n - 1) / n) sd^2 / n.
  const double u = LawUz(paper, p), T = 1.0 / 3;
  const double block_sd = std::sqrt(noise.diffusion * T + std::pow(noise.period_rel * u * T, 2)) / T;
  const double rho = noise.ma_theta / (1 + noise.ma_theta * noise.ma_theta);
  const double expected = block_sd * std::sqrt((1 + 2 * rho * 7 / 8) / 8);
  EXPECT_NEAR(sd, expected, 0.15 * expected);
}

TEST(TruthLawTest, BedEffectIsSharedOnABedAndAveragesOutOverBeds) {
  const Law& paper = *FindLaw("paper");
  const Noise noise;
  const Point a = OscillatoryPoint(0.03, 3, -80, 4), b = OscillatoryPoint(0.03, 3, -160, 4);
  double sum = 0, sab = 0, sa = 0, sb = 0, saa = 0, sbb = 0;
  const int beds = 2000;
  for (int w = 0; w < beds; ++w) {
    const Bed bed = MakeBed(static_cast<uint64_t>(w), 0, noise);
    const double ua = BedUz(paper, noise, bed, a) / LawUz(paper, a), ub = BedUz(paper, noise, bed, b) / LawUz(paper, b);
    sum += ua;
    sa += ua, sb += ub, sab += ua * ub, saa += ua * ua, sbb += ub * ub;
    // The same bed gives the same effect again.
    EXPECT_DOUBLE_EQ(BedUz(paper, noise, MakeBed(static_cast<uint64_t>(w), 0, noise), a), ua * LawUz(paper, a));
  }
  const double mean = sum / beds;
  const double cov = sab / beds - (sa / beds) * (sb / beds);
  const double corr = cov / std::sqrt((saa / beds - std::pow(sa / beds, 2)) * (sbb / beds - std::pow(sb / beds, 2)));
  const double sd = std::sqrt(saa / beds - mean * mean);
  EXPECT_NEAR(mean, 1, 4 * sd / std::sqrt(beds));
  // Shared: two points on one bed are correlated by the common part of the effect.
  const double common = noise.bed_common * noise.bed_common;
  const double expected = common / (common + noise.bed_point * noise.bed_point);
  EXPECT_NEAR(corr, expected, 0.1);
  // Another replicate of the same world is another bed.
  EXPECT_NE(MakeBed(1, 0, noise).seed, MakeBed(1, 1, noise).seed);
}

TEST(TruthLawTest, EngineStopsAtTheSurfaceAndObeysTheStopHookAfterItsLag) {
  const Scale& smoke = *FindScale("smoke");
  const Law& paper = *FindLaw("paper");
  const Noise none = Noise::None();
  const Bed bed = MakeBed(1, 0, none);
  RunSpec spec;
  spec.point = OscillatoryPoint(0.03, 3, -1280, 4);
  spec.duration_s = 4;
  spec.z_floor = smoke.z_floor;
  const EngineRun up = GenerateRun(paper, none, bed, spec, 1);
  EXPECT_EQ(up.stop.reason, "surface");
  EXPECT_GE(up.samples.back().z + kMaterials.d_so / 2, bed.surface);
  EXPECT_LT(up.samples.back().t, 4);
  spec.point = OscillatoryPoint(0.03, 3, 1280, 4);
  EXPECT_EQ(GenerateRun(paper, none, bed, spec, 1).stop.reason, "floor");
  // The worker asks at t >= 0.5 s; the run ends lag_s later.
  spec.point = SlowPoint();
  spec.lag_s = 0.05;
  spec.stop_hook = [](const std::vector<SoSample>& s, std::string* reason) {
    *reason = "target";
    return s.back().t >= 0.5;
  };
  const EngineRun asked = GenerateRun(paper, none, bed, spec, 1);
  EXPECT_EQ(asked.stop.reason, "target");
  EXPECT_NEAR(asked.samples.back().t, 0.55, 1.5e-3);
}

TEST(CalibrationTest, CampaignIsReproducibleAndFollowsThePlan) {
  Design design;
  Result<Calibrator> cal = Calibrator::Make(design);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  EXPECT_EQ(cal->plan().runs.size(), 58u);  // paper-58's distinct runs on its one bed
  const Law& paper = *FindLaw("paper");
  const SimCampaign a = cal->Simulate(paper, Noise(), 11), b = cal->Simulate(paper, Noise(), 11);
  ASSERT_EQ(a.runs.size(), cal->plan().runs.size());
  ASSERT_EQ(a.verdicts.size(), cal->claims().size());
  for (size_t i = 0; i < a.runs.size(); ++i) {
    ASSERT_EQ(a.runs[i].result.has_value(), b.runs[i].result.has_value());
    if (a.runs[i].result) {
      EXPECT_EQ(a.runs[i].result->uz, b.runs[i].result->uz);
    }
    // No run outlasts its plan (plus the worker's lag).
    EXPECT_LE(a.runs[i].simulated_s, a.runs[i].planned_s + 1e-9);
  }
  for (size_t i = 0; i < a.verdicts.size(); ++i) EXPECT_EQ(a.verdicts[i].verdict, b.verdicts[i].verdict);
  // Another world is another draw.
  const SimCampaign c = cal->Simulate(paper, Noise(), 12);
  bool differ = false;
  for (size_t i = 0; i < a.runs.size(); ++i)
    differ = differ || (a.runs[i].result && c.runs[i].result && a.runs[i].result->uz != c.runs[i].result->uz);
  EXPECT_TRUE(differ);
}

TEST(CalibrationTest, NearNoiselessSignsReachTheClaims) {
  // The paper's box and durations: room for every point's periods, so no point is missing.
  Design design;
  design.scale = "paper";
  Result<Calibrator> cal = Calibrator::Make(design);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  Noise tiny = PeriodNoiseOnly();
  tiny.period_rel = 1e-3;
  tiny.diffusion = 1e-12;
  auto verdict = [&](const std::string& law, const std::string& claim, const std::string& part) {
    const SimCampaign c = cal->Simulate(*FindLaw(law), tiny, 5);
    for (const ClaimVerdict& v : c.verdicts) {
      if (v.claim.id != claim) continue;
      if (part.empty()) return v.verdict;
      for (const ClaimPart& p : v.parts)
        if (p.name == part) return p.verdict;
    }
    ADD_FAILURE() << "no " << claim << " " << part;
    return Verdict::kInconclusive;
  };
  EXPECT_EQ(verdict("paper", "F1", ""), Verdict::kHolds);
  EXPECT_EQ(verdict("sign_wrong", "F1", ""), Verdict::kDiffers);
  EXPECT_EQ(verdict("paper", "F5", "vibration alone rises"), Verdict::kHolds);
}

TEST(CalibrationTest, TruthTableNamesTheBrokenParts) {
  const Law& paper = *FindLaw("paper");
  EXPECT_EQ(TruthOf(paper, "F1", ""), std::optional<bool>(true));
  EXPECT_EQ(TruthOf(*FindLaw("sign_wrong"), "F1", ""), std::optional<bool>(false));
  EXPECT_EQ(TruthOf(*FindLaw("flat_Omega"), "F2", "rising: |U_z| grows with |Omega| (C1 > 0)"),
            std::optional<bool>(false));
  EXPECT_EQ(TruthOf(*FindLaw("no_saturation"), "F2", "sinking: saturates within the swept |Omega|"),
            std::optional<bool>(false));
  EXPECT_EQ(TruthOf(*FindLaw("affine_A"), "F3", "rising: U_z = C3 A over the swept A"), std::optional<bool>(false));
  EXPECT_EQ(TruthOf(*FindLaw("affine_A"), "F4", ""), std::optional<bool>(true));
  EXPECT_EQ(TruthOf(*FindLaw("no_peak_f"), "F4", ""), std::optional<bool>(false));
  EXPECT_EQ(TruthOf(*FindLaw("modes_equal"), "F5", "vibration alone rises"), std::optional<bool>(true));
  EXPECT_EQ(TruthOf(paper, "F6", ""), std::nullopt);
  auto [lo, hi] = WilsonInterval(50, 100);
  EXPECT_LT(lo, 0.5);
  EXPECT_GT(hi, 0.5);
}

// The trend test (core/trajectory.h) on the truth engine: its false alarms on a stationary law
// (the engine's own per-period scatter, MA(1) -0.2, jitter and x motion; no transient, no bed
// effect) and its power on the same law with a drift of the rate (Noise::rate_slope), at the
// baseline's slow rising point (U_z = 0.034 m/s, 3 Hz): runs of 2 s (smoke's longest at 3 Hz,
// 5 periods in the window) and 4 s (11). 1,000 runs a case; the rates are printed for docs/measurements.md.
TEST(TruthTrendTest, FalseAlarmsOnAStationaryLawAndPowerOnADrift) {
  const Scale& smoke = *FindScale("smoke");
  const Law& paper = *FindLaw("paper");
  Noise noise;
  noise.transient_v0 = 0;
  noise.bed_common = noise.bed_point = noise.bed_offset = 0;
  constexpr int kRuns = 1000;
  for (double duration : {2.0, 4.0}) {
    const Point p = OscillatoryPoint(0.03, 3, -10, duration);
    // The drift slows the rising SO (and turns it at 0.02 m/s^2 after 1.7 s), so that it keeps
    // clear of the surface and every case has the same window.
    for (double slope : {0.0, 0.005, 0.01, 0.02}) {
      noise.rate_slope = -slope;
      int tested = 0, flagged = 0, blocks = 0;
      for (int i = 0; i < kRuns; ++i) {
        const Bed bed = MakeBed(1000 + i, 0, noise);
        RunSpec spec;
        spec.point = p;
        spec.duration_s = duration;
        spec.z_floor = smoke.z_floor;
        const EngineRun run = GenerateRun(paper, noise, bed, spec, RunSeed(1000 + i, 0, p));
        Result<api::RunResult> r = Analyze(run, p, smoke);
        ASSERT_TRUE(r.ok()) << r.status().ToString();
        if (!r->trend_p) continue;
        ++tested;
        blocks += r->uz_blocks;
        flagged += r->trending ? 1 : 0;
      }
      ASSERT_EQ(tested, kRuns) << duration << " s";
      const double rate = static_cast<double>(flagged) / tested;
      std::printf("%.0f s runs (%.1f periods), rate slope -%.3f m/s^2: %s %.1f %% (%d of %d)\n", duration,
                  static_cast<double>(blocks) / tested, slope, slope == 0 ? "false alarms" : "power", 100 * rate,
                  flagged, tested);
      if (slope == 0) {
        EXPECT_LE(rate, 0.02) << duration << " s";  // alpha 1 %; the MA(1) makes the test conservative
      } else if (duration == 4.0 && slope >= 0.02) {
        // Measured 100 %; 78 % at 0.01 m/s^2, 15 % at 0.005. Over 5 periods (2 s) it is 1-10 %:
        // a smoke run's window is too short to see a drift of this size.
        EXPECT_GE(rate, 0.9) << duration << " s, slope " << slope;
      }
    }
  }
}

}  // namespace
}  // namespace sandswim::truth

namespace sandswim::truth {
namespace {

// The committed calibration tables (templates/calibration/, what the verdicts quote) are current:
// made for the campaign definition, the claims' rules and the run analysis this build has, with
// the truth engine's noise as it is; and the campaign's default design is among them.
TEST(CommittedCalibrationTest, IsCurrent) {
  const std::string regenerate = "regenerate them: tests/truth/regenerate_calibration.sh (then rebuild and commit)";
  ASSERT_FALSE(CommittedCalibrations().empty()) << "no calibration table is compiled in; " << regenerate;
  for (const CalibrationTable& t : CommittedCalibrations()) {
    const nlohmann::json j = nlohmann::json::parse(*EmbeddedFile(t.file), nullptr, false);
    const nlohmann::json d = j.is_object() ? j.value("design", nlohmann::json::object()) : nlohmann::json::object();
    Design design;
    design.campaign = t.key.campaign;
    design.scale = t.key.scale;
    design.beds = t.key.beds;
    Result<Calibrator> cal = Calibrator::Make(design);
    ASSERT_TRUE(cal.ok()) << t.file << ": " << cal.status().ToString();
    const DesignKey now = cal->Key();
    EXPECT_EQ(t.key.definition_hash, now.definition_hash)
        << t.file << " was made for another definition of " << t.key.campaign << "; " << regenerate;
    EXPECT_EQ(t.key.rules_version, kClaimRulesVersion) << t.file << " was made with other claims rules; " << regenerate;
    EXPECT_EQ(t.key.bed_sd_rel, now.bed_sd_rel) << t.file << " was made with another bed prior; " << regenerate;
    EXPECT_EQ(t.key.analysis_version, api::kAnalysisVersion)
        << t.file << " was made with another run analysis; " << regenerate;
    EXPECT_EQ(d.value("noise", nlohmann::json()), NoiseToJson(Noise{}))
        << t.file << " was made with another truth-engine noise; " << regenerate;
    EXPECT_EQ(d.value("precision", false), true) << t.file;
    EXPECT_EQ(d.value("follow", false), true) << t.file;
    EXPECT_EQ(d.value("duration_multiplier", 0.0), 1.0) << t.file;
  }
  // paper-58's own design at smoke (its default K) is calibrated.
  Result<Calibrator> builtin = Calibrator::Make(Design{});
  ASSERT_TRUE(builtin.ok());
  const DesignKey key = builtin->Key();
  EXPECT_TRUE(std::any_of(CommittedCalibrations().begin(), CommittedCalibrations().end(),
                          [&](const CalibrationTable& t) { return t.key == key; }))
      << DescribeDesign(key) << " has no table; " << regenerate;
}

// A small run of the benchmark (new worlds) agrees with the committed K = 1 table: for every law,
// claim and part, the rates of holds and of differs differ by no more than their binomial errors
// allow (4 standard errors of the difference, pooled, plus half a count: some 350 comparisons, all
// deterministic).
TEST(CommittedCalibrationTest, SmallRunAgreesWithTheTable) {
  Design design;
  design.beds = 1;
  Result<Calibrator> cal = Calibrator::Make(design);
  ASSERT_TRUE(cal.ok());
  const CalibrationTable* table = nullptr;
  for (const CalibrationTable& t : CommittedCalibrations())
    if (t.key == cal->Key()) table = &t;
  ASSERT_NE(table, nullptr) << "no committed table at " << DescribeDesign(cal->Key())
                            << ": tests/truth/regenerate_calibration.sh";
  const int64_t n = 24;
  int compared = 0;
  for (const nlohmann::json& law : table->laws) {
    const Law* l = FindLaw(law.value("law", ""));
    ASSERT_NE(l, nullptr) << law.value("law", "");
    const LawTally small = RunLaw(*cal, *l, Noise{}, n, 5'000'001, 2);
    for (const nlohmann::json& cell : law["cells"]) {
      const auto key = std::make_pair(cell.value("claim", ""), cell.value("part", ""));
      auto it = small.cells.find(key);
      ASSERT_NE(it, small.cells.end()) << l->name << " " << key.first << " [" << key.second << "] not in the small run";
      for (const char* kind : {"holds", "differs"}) {
        const double nc = cell.value("n", 0.0), kc = cell[kind].value("count", 0.0);
        const double ks = static_cast<double>(std::string(kind) == "holds" ? it->second.holds : it->second.differs);
        const double ns = static_cast<double>(it->second.n());
        const double pooled = (kc + ks) / (nc + ns);
        const double se = std::sqrt(pooled * (1 - pooled) * (1 / nc + 1 / ns));
        EXPECT_LE(std::fabs(ks / ns - kc / nc), 4 * se + 0.5 / ns)
            << l->name << " " << key.first << " [" << key.second << "] " << kind << ": " << ks << " of " << ns
            << " now, " << kc << " of " << nc << " in " << table->file
            << ": the table is stale, regenerate it (tests/truth/regenerate_calibration.sh)";
        ++compared;
      }
    }
  }
  EXPECT_GT(compared, 100);
}

// The drift report's false alarms on the truth engine (core/drift.h, bench_drift_alarms is the
// full measurement): two nights of paper-58 at smoke under one law on the same beds, K = 1. Per
// point the rate must be <= 5 % (its estimate at this fixed seed), and so must the campaign's
// Holm verdict's. Rule 1 passed the per-point part (3.8 % [3.4, 4.2], 200 night
// pairs) but said "some point drifted" in most campaigns with nothing changed (it had no
// verdict for the campaign; its any-run rate is checked here to fail the same bound); so does
// rule 2 at 5 % per point, which is why the campaign's verdict is Holm's. And the committed rates
// the reports quote agree with this run (4 pooled standard errors).
TEST(DriftAlarmTest, FalseAlarmsPerPointAndPerCampaignWithinFivePercent) {
  Design design;
  design.beds = 1;
  Result<Calibrator> cal = Calibrator::Make(design);
  ASSERT_TRUE(cal.ok());
  const int64_t n = 40;
  const DriftAlarms d = MeasureDriftAlarms(*cal, *FindLaw("paper"), Noise{}, n, 7'000'001, 2);
  ASSERT_EQ(d.campaigns, n);
  ASSERT_GT(d.points_compared, 20 * n);
  const auto [point_lo, point_hi] = WilsonInterval(d.points_drifted, d.points_compared);
  const auto [campaign_lo, campaign_hi] = WilsonInterval(d.campaigns_drifted, d.campaigns);
  // The rates themselves (a fixed seed: deterministic), not their Wilson lower bounds, which a rule
  // at 6 % would still pass.
  EXPECT_LE(static_cast<double>(d.points_drifted) / d.points_compared, 0.05)
      << d.points_drifted << " of " << d.points_compared << " points drifted";
  EXPECT_LE(static_cast<double>(d.campaigns_drifted) / d.campaigns, 0.05)
      << d.campaigns_drifted << " of " << d.campaigns << " campaigns drifted (Holm)";
  // Without a multiplicity rule a campaign raises some alarm most nights.
  EXPECT_GT(WilsonInterval(d.campaigns_any_run_rule1, d.campaigns).first, 0.05);
  EXPECT_GT(WilsonInterval(d.campaigns_any_point, d.campaigns).first, 0.05);
  std::printf("drift, K = 1, %lld night pairs: points %.1f %% [%.1f, %.1f], campaigns (Holm) %.1f %% [%.1f, %.1f], "
              "some run (rule 1) %.1f %%\n",
              static_cast<long long>(n), 100.0 * d.points_drifted / d.points_compared, 100 * point_lo, 100 * point_hi,
              100.0 * d.campaigns_drifted / n, 100 * campaign_lo, 100 * campaign_hi,
              100.0 * d.campaigns_any_run_rule1 / n);
  const DriftAlarmRates* committed = FindDriftAlarmRates("paper-58", "smoke", 1);
  ASSERT_NE(committed, nullptr) << "no committed drift rates for rule " << kDriftRuleVersion << ", analysis "
                                << api::kAnalysisVersion << ": run bench_drift_alarms, update core/drift.cc kMeasured";
  const double kc = static_cast<double>(committed->points_drifted), nc = static_cast<double>(committed->points);
  const double ks = static_cast<double>(d.points_drifted), ns = static_cast<double>(d.points_compared);
  const double pooled = (kc + ks) / (nc + ns);
  EXPECT_LE(std::fabs(ks / ns - kc / nc), 4 * std::sqrt(pooled * (1 - pooled) * (1 / nc + 1 / ns)))
      << "core/drift.cc kMeasured is stale: run bench_drift_alarms";
}

}  // namespace
}  // namespace sandswim::truth
