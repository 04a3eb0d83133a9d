#include "server/analysis/claim_check.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

// What an adaptive campaign run's verdicts show (the pure part of CheckClaims): a frozen claim as
// its deciding look froze it, an open one inconclusive until a look decides it, and the procedure's
// rates, never a single-look table's. The store-backed path is in report_test.cc.
namespace sandswim {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

ClaimVerdict Evaluated(const std::string& id, Verdict verdict, const std::string& reason) {
  ClaimVerdict v;
  v.claim.id = id;
  v.verdict = verdict;
  v.reason = reason;
  v.scale = "smoke";
  ClaimPart part;
  part.name = "sign";
  part.verdict = verdict;
  part.reason = "the numbers";
  v.parts.push_back(part);
  return v;
}

rounds::RoundRow Row(int round, bool finished, const char* stop = nullptr) {
  rounds::RoundRow r;
  r.round = round;
  if (finished) r.finished_at = 100.0 * round;
  if (stop) r.stop_reason = stop;
  return r;
}

TEST(RoundsSoFarTest, SaysWhichLookComesNextOrThatNoneDoes) {
  RoundsSoFar none = RoundsSoFarOf({});  // round 1 runs; its row is written at the first look
  EXPECT_EQ(none.rounds, 1);
  EXPECT_EQ(none.next_look, 1);
  RoundsSoFar running = RoundsSoFarOf({Row(1, true), Row(2, false)});
  EXPECT_EQ(running.rounds, 2);
  EXPECT_EQ(running.next_look, 2);
  RoundsSoFar stopped = RoundsSoFarOf({Row(1, true), Row(2, true, "every claim is decided")});
  EXPECT_EQ(stopped.rounds, 2);
  EXPECT_FALSE(stopped.next_look.has_value());
  EXPECT_EQ(stopped.stopped_after, 2);
}

TEST(ShowFrozenVerdictsTest, AnOpenClaimIsInconclusiveUntilALookDecidesIt) {
  std::vector<ClaimVerdict> verdicts = {Evaluated("F1", Verdict::kHolds, "every sign as expected"),
                                        Evaluated("F2", Verdict::kDiffers, "the peak is at the edge"),
                                        Evaluated("F3", Verdict::kInconclusive, "needs 5 points")};
  const RoundsSoFar so_far = RoundsSoFarOf({Row(1, true), Row(2, false)});
  const std::map<std::string, Verdict> current = ShowFrozenVerdicts(verdicts, {}, so_far);
  EXPECT_EQ(current.at("F1"), Verdict::kHolds);
  EXPECT_EQ(current.at("F2"), Verdict::kDiffers);
  EXPECT_EQ(current.at("F3"), Verdict::kInconclusive);
  for (const ClaimVerdict& v : verdicts) EXPECT_EQ(v.verdict, Verdict::kInconclusive) << v.claim.id;
  EXPECT_EQ(verdicts[0].reason,
            "reads holds with the runs so far; only the look after a round decides (the next look: after round 2): "
            "every sign as expected");
  EXPECT_THAT(verdicts[1].reason, HasSubstr("reads differs with the runs so far"));
  EXPECT_EQ(verdicts[2].reason, "needs 5 points");  // inconclusive as read: as it was
  const VerdictCounts n = CountVerdicts(verdicts);
  EXPECT_EQ(n.holds, 0);
  EXPECT_EQ(n.differs, 0);
  EXPECT_EQ(n.inconclusive, 3);

  // After the rounds stopped, no look is to come: it stays undecided, and says why.
  std::vector<ClaimVerdict> late = {Evaluated("F1", Verdict::kHolds, "every sign as expected")};
  ShowFrozenVerdicts(late, {}, RoundsSoFarOf({Row(1, true, "the budget is spent")}));
  EXPECT_EQ(late[0].verdict, Verdict::kInconclusive);
  EXPECT_THAT(late[0].reason, HasSubstr("none is to come (the rounds stopped after round 1)"));
}

TEST(ShowFrozenVerdictsTest, AFrozenClaimSaysWhoseNumbersItShows) {
  std::vector<ClaimVerdict> verdicts = {Evaluated("F1", Verdict::kHolds, "every sign as expected"),
                                        Evaluated("F2", Verdict::kInconclusive, "a point failed")};
  std::map<std::string, rounds::FrozenVerdict> frozen;
  frozen["F1"] = rounds::FrozenVerdict{Verdict::kHolds, 1, 100};
  frozen["F2"] = rounds::FrozenVerdict{Verdict::kDiffers, 1, 100};
  const RoundsSoFar so_far = RoundsSoFarOf({Row(1, true), Row(2, true), Row(3, false)});
  const std::map<std::string, Verdict> current = ShowFrozenVerdicts(verdicts, frozen, so_far);
  // Agreeing: the current evaluation's numbers stay, labelled as such.
  EXPECT_EQ(verdicts[0].verdict, Verdict::kHolds);
  EXPECT_EQ(verdicts[0].reason,
            "holds since the look after round 1 (frozen there); what follows is the current evaluation with all 3 "
            "rounds' runs, not the numbers of that look: every sign as expected");
  EXPECT_EQ(verdicts[0].parts.size(), 1u);
  // Disagreeing: the frozen verdict, what the runs now read and that it does not count.
  EXPECT_EQ(current.at("F2"), Verdict::kInconclusive);
  EXPECT_EQ(verdicts[1].verdict, Verdict::kDiffers);
  EXPECT_THAT(verdicts[1].reason, HasSubstr("decided (differs) at the look after round 1 and frozen there; with all 3 "
                                            "rounds' runs it now reads inconclusive, which does not count (frozen)"));
  EXPECT_THAT(verdicts[1].reason, Not(HasSubstr("a point failed")));
  EXPECT_TRUE(verdicts[1].parts.empty());
}

TEST(AdaptiveRatesTest, EveryVerdictAndPartIsQuotedTheProceduresRatesNotATable) {
  std::vector<ClaimVerdict> verdicts = {Evaluated("F1", Verdict::kHolds, "x"), Evaluated("F2", Verdict::kDiffers, "y")};
  ClaimInput input;
  input.scale = "smoke";
  ClaimSweep sweep;
  sweep.name = "omega";
  for (auto [omega, replicate] : std::vector<std::pair<double, int>>{{-80, 0}, {-80, 1}, {80, 0}}) {
    ClaimRun r;
    r.point.Omega = omega;
    r.replicate = replicate;
    sweep.runs.push_back(r);
  }
  input.sweeps.push_back(sweep);
  DesignKey key;
  key.campaign = "tiny-rounds";
  key.scale = "smoke";
  key.beds = 2;
  const std::string text = DescribeAdaptiveDesign(key, input, RoundsSoFarOf({Row(1, true), Row(2, false)}));
  EXPECT_THAT(text, HasSubstr("tiny-rounds at smoke, adaptive: in rounds (2 rounds so far), beds vary by point "
                              "(1 to 2 beds a point)"));
  EXPECT_THAT(text, Not(HasSubstr("K =")));
  AttachAdaptiveRates(verdicts, text);
  for (const ClaimVerdict& v : verdicts) {
    ASSERT_TRUE(v.rates.has_value());
    EXPECT_FALSE(v.rates->calibrated);
    EXPECT_EQ(v.rates->text, kAdaptiveRatesText);
    EXPECT_EQ(v.rates->design, text);
    EXPECT_FALSE(v.rates->false_holds.has_value());
    for (const ClaimPart& p : v.parts) {
      ASSERT_TRUE(p.rates.has_value());
      EXPECT_EQ(p.rates->text, kAdaptiveRatesText);
    }
  }
}

}  // namespace
}  // namespace sandswim
