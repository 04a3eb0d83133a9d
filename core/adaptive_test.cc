// Claim-driven rounds (core/adaptive.h) on paper-58 at smoke with synthetic results: what a round
// may order (declared points, or new f strictly inside the declared range), what it may spend
// (never more than the budget left), what it refuses (a budget below the first round), and when
// it stops.
#include "core/adaptive.h"

#include <cmath>
#include <random>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/sweep.h"
#include "core/trajectory.h"

namespace sandswim {
namespace {

using ::testing::HasSubstr;

struct Fixture {
  Campaign campaign;
  std::vector<AdaptiveSweep> sweeps;
  AdaptiveCost cost;
};

Fixture Paper58AtSmoke() {
  Fixture f;
  Result<Campaign> c = BuiltinCampaign("paper-58");
  EXPECT_TRUE(c.ok());
  f.campaign = *c;
  f.cost.scale = FindScale("smoke");
  for (SweepSpec& s : f.campaign.sweeps) {
    s.scale = "smoke";
    Result<std::vector<Point>> points = ExpandSweep(s);
    EXPECT_TRUE(points.ok());
    f.sweeps.push_back({s.name, *points});
  }
  return f;
}

// A result measured over `blocks` periods with relative error `rel` (exact value, no noise).
api::RunResult Measured(double uz, double rel, int blocks = 5) {
  api::RunResult r;
  r.uz = uz;
  r.uz_stderr = std::max(rel * std::abs(uz), 1e-4);
  r.uz_ci95 = StudentT95(blocks - 1) * *r.uz_stderr;
  r.uz_blocks = blocks;
  r.conclusive = true;
  r.stop_reason = "duration";
  r.sim_time_s = 2;
  r.dz = uz * 2;
  r.z_osc_amplitude = 0.002;
  r.x_osc_amplitude = 0.002;
  return r;
}

// Every declared point done once on bed 0: U_z of a peaked law in f (at 5 Hz), growing in |Omega|,
// proportional in A, rising for Omega < 0 and the modes rising; errors `rel` of |U_z|, wide enough
// that the rate claims stay open.
AdaptiveState FirstRoundDone(const Fixture& f, double rel) {
  AdaptiveState s;
  s.claims = f.campaign.claims;
  s.sweeps = f.sweeps;
  s.input.scale = "smoke";
  ClaimBed bed;
  bed.id = 1;
  bed.state = JobState::kDone;
  bed.grains = 6682;
  bed.bed_height = 0.68;
  s.input.beds.push_back(bed);
  int64_t id = 0;
  for (const AdaptiveSweep& sw : f.sweeps) {
    ClaimSweep cs;
    cs.name = sw.name;
    for (const Point& p : sw.points) {
      double uz = 0.03;
      if (p.mode == Mode::kOscillatory) {
        const double g = (p.f / 5) * std::exp(1 - p.f / 5);
        uz = (p.Omega < 0 ? 1 : -1) * 0.04 * g * (p.A / 0.03) * std::log2(1 + std::abs(p.Omega) / 10);
      }
      ClaimRun r;
      r.run_id = ++id;
      r.point = p;
      r.state = JobState::kDone;
      r.result = Measured(uz, rel);
      cs.runs.push_back(r);
    }
    s.input.sweeps.push_back(cs);
  }
  s.rounds_done = 1;
  return s;
}

TEST(AdaptiveBudgetTest, ABudgetBelowTheFirstRoundIsRefusedWithTheNumberItNeeds) {
  Fixture f = Paper58AtSmoke();
  AdaptiveRound first = FirstRound(f.sweeps, f.cost);
  ASSERT_EQ(first.actions.size(), 1u);
  EXPECT_GT(first.actions[0].runs.size(), 40u);  // paper-58's points, each once
  EXPECT_EQ(first.actions[0].new_beds, 1);
  EXPECT_GT(first.core_h, 1.0);
  for (double bad : {0.0, -1.0, std::nan(""), first.core_h * 0.99}) {
    Status s = ValidateAdaptiveBudget(bad, first);
    ASSERT_FALSE(s.ok()) << bad;
    EXPECT_EQ(s.field(), "budget_core_h");
    char need[32];
    std::snprintf(need, sizeof need, "%.2f", first.core_h);
    EXPECT_THAT(s.reason(), HasSubstr("needs at least"));
  }
  EXPECT_TRUE(ValidateAdaptiveBudget(first.core_h, first).ok());
  EXPECT_TRUE(ValidateAdaptiveBudget(first.core_h * 3, first).ok());
}

// The campaign field that makes a campaign adaptive (core/sweep.h AdaptiveSettings), and its
// budget priced against the first round at a scale and the cost model's rates.
TEST(AdaptiveBudgetTest, TheCampaignFieldIsParsedAndItsBudgetPricedAtTheScale) {
  nlohmann::json j = *BuiltinCampaignDefinition("paper-58");
  j["name"] = "mine";
  EXPECT_FALSE(ParseCampaign(j)->adaptive.has_value());  // absent: the fixed design
  j["adaptive"] = {{"budget_core_h", 20}, {"max_rounds", 3}};
  Result<Campaign> c = ParseCampaign(j);
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  ASSERT_TRUE(c->adaptive.has_value());
  EXPECT_EQ(c->adaptive->budget_core_h, 20);
  EXPECT_EQ(c->adaptive->max_rounds, 3);
  j["adaptive"] = {{"budget_core_h", 20}};
  EXPECT_EQ(ParseCampaign(j)->adaptive->max_rounds, 4);

  struct Bad {
    nlohmann::json adaptive;
    std::string field;
  };
  for (const Bad& bad : std::vector<Bad>{{{{"budget_core_h", 0}}, "adaptive.budget_core_h"},
                                         {{{"budget_core_h", -3}}, "adaptive.budget_core_h"},
                                         {{{"budget_core_h", "a lot"}}, "adaptive.budget_core_h"},
                                         {{{"max_rounds", 3}}, "adaptive.budget_core_h"},
                                         {{{"budget_core_h", 5}, {"max_rounds", 0}}, "adaptive.max_rounds"},
                                         {{{"budget_core_h", 5}, {"max_rounds", 2.5}}, "adaptive.max_rounds"},
                                         {{{"budget_core_h", 5}, {"rounds", 2}}, "adaptive.rounds"},
                                         {5, "adaptive"}}) {
    j["adaptive"] = bad.adaptive;
    Result<Campaign> r = ParseCampaign(j);
    ASSERT_FALSE(r.ok()) << bad.adaptive.dump();
    EXPECT_EQ(r.status().field(), bad.field) << r.status().ToString();
  }
  j["adaptive"] = {{"budget_core_h", 20}};
  nlohmann::json no_claims = j;
  no_claims.erase("claims");
  EXPECT_EQ(ParseCampaign(no_claims).status().field(), "adaptive");
  nlohmann::json two_beds = j;
  two_beds["replicates"] = 2;
  EXPECT_EQ(ParseCampaign(two_beds).status().field(), "replicates");

  // The budget against round 1 at smoke and at mini (about 8x the particle-steps), at the rates given.
  Fixture f = Paper58AtSmoke();
  const double smoke_first = FirstRound(f.sweeps, f.cost).core_h;
  AdaptiveCost cost;  // the default rates; the scale is the one asked
  Campaign campaign = *ParseCampaign(j);
  campaign.adaptive->budget_core_h = smoke_first * 1.01;
  EXPECT_TRUE(CheckAdaptiveBudget(campaign, "smoke", cost).ok());
  Status at_mini = CheckAdaptiveBudget(campaign, "mini", cost);
  ASSERT_FALSE(at_mini.ok());
  EXPECT_EQ(at_mini.field(), "adaptive.budget_core_h");
  EXPECT_THAT(at_mini.reason(), HasSubstr("needs at least"));
  EXPECT_THAT(at_mini.reason(), HasSubstr("at mini, at the cost model's rates now"));
  // Twice as slow an engine: the same budget no longer pays for round 1 at smoke.
  cost.run_rate.s_per_unit *= 2;
  cost.bed_rate.s_per_unit *= 2;
  EXPECT_EQ(CheckAdaptiveBudget(campaign, "smoke", cost).field(), "adaptive.budget_core_h");
  campaign.adaptive.reset();
  EXPECT_TRUE(CheckAdaptiveBudget(campaign, "mini", cost).ok());  // not adaptive: nothing to price
}

TEST(AdaptiveRoundTest, NeverSpendsMoreThanTheBudgetLeft) {
  Fixture f = Paper58AtSmoke();
  AdaptiveState s = FirstRoundDone(f, 0.6);
  s.spent_core_h = 10;
  for (double budget : {10.2, 10.6, 11.0, 12.0, 15.0, 20.0, 40.0}) {
    AdaptiveRound r = PlanNextRound(s, budget, f.cost);
    double sum = 0;
    for (const AdaptiveAction& a : r.actions) sum += a.core_h;
    EXPECT_NEAR(sum, r.core_h, 1e-9);
    EXPECT_LE(r.core_h, budget - s.spent_core_h + 1e-9) << budget;
    if (r.stop) {
      EXPECT_FALSE(r.stop_reason.empty());
    }
    // An action's price covers its runs at their longest and its new beds.
    for (const AdaptiveAction& a : r.actions) {
      double runs = 0;
      for (const RunOrder& o : a.runs) runs += f.cost.RunCoreHours(o.point, o.max_duration_s);
      EXPECT_GE(a.core_h + 1e-12, runs);
      EXPECT_FALSE(a.reason.empty());
      EXPECT_THAT(a.reason, HasSubstr("core-h"));
    }
  }
  // Nothing left: it stops and says the budget is spent.
  AdaptiveRound none = PlanNextRound(s, 10.01, f.cost);
  EXPECT_TRUE(none.stop);
  EXPECT_TRUE(none.actions.empty());
}

TEST(AdaptiveRoundTest, NeverOrdersAPointOutsideTheDeclaredRanges) {
  Fixture f = Paper58AtSmoke();
  AdaptiveState s = FirstRoundDone(f, 0.6);
  AdaptiveRound r = PlanNextRound(s, 1000, f.cost);
  ASSERT_FALSE(r.considered.empty());
  std::set<DriveId> declared;
  for (const AdaptiveSweep& sw : f.sweeps)
    for (const Point& p : sw.points) declared.insert(DriveIdOf(p));
  double longest_base = 0;
  for (const AdaptiveSweep& sw : f.sweeps)
    for (const Point& p : sw.points) longest_base = std::max(longest_base, RunDuration(p, f.cost.scale->default_precision));
  bool new_point = false;
  for (const std::vector<AdaptiveAction>* list : {&r.considered, &r.actions}) {
    for (const AdaptiveAction& a : *list) {
      for (const RunOrder& o : a.runs) {
        EXPECT_TRUE(Validate(o.point).ok());
        EXPECT_TRUE(FitsScale(o.point, *f.cost.scale).ok());
        EXPECT_GE(o.replicate, 0);
        EXPECT_LT(o.replicate, AdaptiveOptions{}.max_beds);
        EXPECT_LE(o.max_duration_s, AdaptiveOptions{}.max_duration_factor * longest_base + 1e-9);
        if (declared.count(DriveIdOf(o.point))) continue;
        // A new point: a declared point of its sweep with another f, strictly inside the sweep's f.
        ASSERT_EQ(a.kind, ActionKind::kNewPoint) << a.reason;
        new_point = true;
        double lo = 1e9, hi = -1e9;
        bool sibling = false;
        for (const AdaptiveSweep& sw : f.sweeps) {
          if (sw.name != o.sweep) continue;
          for (const Point& p : sw.points) {
            lo = std::min(lo, p.f), hi = std::max(hi, p.f);
            Point q = p;
            q.f = o.point.f;
            sibling = sibling || SameDrive(q, o.point);
          }
        }
        EXPECT_TRUE(sibling) << a.reason;
        EXPECT_GT(o.point.f, lo);
        EXPECT_LT(o.point.f, hi);
      }
    }
  }
  EXPECT_TRUE(new_point) << "the f sweep's peak gets new points between its neighbours";
}

TEST(AdaptiveRoundTest, AClaimFrozenAtALookStaysAsItWasDecided) {
  Fixture f = Paper58AtSmoke();
  std::map<std::string, Verdict> frozen;
  ClaimVerdict v;
  v.claim.id = "F1";
  v.verdict = Verdict::kHolds;
  EXPECT_EQ(FreezeDecisions({v}, frozen), std::vector<std::string>{"F1"});
  v.verdict = Verdict::kDiffers;
  EXPECT_TRUE(FreezeDecisions({v}, frozen).empty());
  EXPECT_EQ(frozen.at("F1"), Verdict::kHolds);
  v.claim.id = "F2";
  v.verdict = Verdict::kInconclusive;
  EXPECT_TRUE(FreezeDecisions({v}, frozen).empty());
  EXPECT_FALSE(frozen.count("F2"));
}

TEST(AdaptiveRoundTest, StopsWhenEveryClaimIsDecidedOrTheLooksAreUsed) {
  Fixture f = Paper58AtSmoke();
  AdaptiveState s = FirstRoundDone(f, 0.6);
  // F6 (grain_count) names no sweep: runs cannot decide it, so it is never open.
  for (const std::string& id : OpenClaims(s)) EXPECT_NE(id, "F6");
  for (const Claim& c : s.claims) s.frozen[c.id] = Verdict::kHolds;
  AdaptiveRound done = PlanNextRound(s, 1000, f.cost);
  EXPECT_TRUE(done.stop);
  EXPECT_THAT(done.stop_reason, HasSubstr("every claim"));
  s.frozen.clear();
  s.rounds_done = AdaptiveOptions{}.max_rounds;
  AdaptiveRound last = PlanNextRound(s, 1000, f.cost);
  EXPECT_TRUE(last.stop);
  EXPECT_THAT(last.stop_reason, HasSubstr("look schedule"));
}

TEST(AdaptiveRoundTest, ThePlanIsTheSameEachTime) {
  Fixture f = Paper58AtSmoke();
  AdaptiveState s = FirstRoundDone(f, 0.6);
  AdaptiveRound a = PlanNextRound(s, 100, f.cost), b = PlanNextRound(s, 100, f.cost);
  ASSERT_EQ(a.actions.size(), b.actions.size());
  for (size_t i = 0; i < a.actions.size(); ++i) EXPECT_EQ(a.actions[i].reason, b.actions[i].reason);
}

}  // namespace
}  // namespace sandswim
