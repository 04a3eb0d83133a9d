// Claim-driven rounds (core/adaptive.h) on the truth engine at a small n (the full table is
// tests/bench/bench_adaptive.cc): whole adaptive campaigns of paper-58 at smoke under every law,
// each round planned by PlanNextRound and run on the truth engine. Asserted: no campaign spends more
// than its budget, no round orders a point outside the declared ranges, and the procedure's false
// holds and false differs (a claim's verdict frozen at the look that decided it) stay within the
// targets: over these 4 worlds at most 1 wrong verdict per claim and law (2 in 4 would put
// Wilson's lower 95 % bound at 15 %). Each round is planned within the budget less what the
// rounds before it spent as they ran, so what a campaign spends never passes its budget.
#include <set>

#include <gtest/gtest.h>

#include "tests/truth/adaptive_campaign.h"

namespace sandswim::truth {
namespace {

constexpr int kWorlds = 4;
constexpr double kBudget = 30;  // core-h: about what the fixed three-bed design spends

TEST(AdaptiveCampaignTest, StaysInBudgetAndRangesAndItsErrorRatesWithinTheTargets) {
  Design d;
  d.beds = 1;
  Result<Calibrator> cal = Calibrator::Make(d);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  std::set<DriveId> declared;
  std::map<std::string, std::pair<double, double>> f_range;  // sweep -> declared f range
  for (const AdaptiveSweep& s : DeclaredSweeps(*cal)) {
    for (const Point& p : s.points) {
      declared.insert(DriveIdOf(p));
      auto [it, fresh] = f_range.emplace(s.name, std::make_pair(p.f, p.f));
      it->second.first = std::min(it->second.first, p.f);
      it->second.second = std::max(it->second.second, p.f);
    }
  }
  AdaptiveOptions options;
  int rounds_after_the_first = 0;
  for (const Law& law : AllLaws()) {
    std::map<std::string, int> false_holds, false_differs;
    for (int w = 1; w <= kWorlds; ++w) {
      AdaptiveOutcome o = SimulateAdaptive(*cal, law, Noise{}, static_cast<uint64_t>(1000 + w), kBudget, options);
      EXPECT_LE(o.core_h, kBudget + 1e-9) << law.name << " world " << w;
      ASSERT_FALSE(o.rounds.empty());
      EXPECT_TRUE(o.rounds.back().stop);
      EXPECT_FALSE(o.rounds.back().stop_reason.empty());
      for (size_t r = 1; r < o.rounds.size(); ++r) {
        if (!o.rounds[r].stop) ++rounds_after_the_first;
        for (const AdaptiveAction& a : o.rounds[r].actions) {
          EXPECT_FALSE(a.reason.empty());
          for (const RunOrder& ord : a.runs) {
            if (declared.count(DriveIdOf(ord.point))) continue;
            EXPECT_EQ(a.kind, ActionKind::kNewPoint) << a.reason;
            EXPECT_GT(ord.point.f, f_range[ord.sweep].first) << a.reason;
            EXPECT_LT(ord.point.f, f_range[ord.sweep].second) << a.reason;
          }
        }
      }
      for (const std::string id : {"F1", "F2", "F3", "F4", "F5"}) {
        std::optional<bool> truth = TruthOf(law, id, "");
        auto it = o.frozen.find(id);
        if (!truth || it == o.frozen.end()) continue;
        if (!*truth && it->second == Verdict::kHolds) ++false_holds[id];
        if (*truth && it->second == Verdict::kDiffers) ++false_differs[id];
      }
    }
    for (const auto& [id, n] : false_holds) EXPECT_LE(n, 1) << id << " false holds under " << law.name;
    for (const auto& [id, n] : false_differs) EXPECT_LE(n, 1) << id << " false differs under " << law.name;
  }
  EXPECT_GT(rounds_after_the_first, 0) << "some campaign runs a round after the first";
}

}  // namespace
}  // namespace sandswim::truth
