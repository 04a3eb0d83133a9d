#include "core/claim_rates.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/sweep.h"

namespace sandswim {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

// A table of two laws: "paper" makes part P of F9 true, "null" makes it false.
CalibrationTable Table(const DesignKey& key, int64_t paper_holds, int64_t paper_differs, int64_t null_holds,
                       int64_t n = 300) {
  auto cell = [&](bool truth, int64_t holds, int64_t differs) {
    return nlohmann::json{{"claim", "F9"},
                          {"part", "P"},
                          {"true", truth},
                          {"n", n},
                          {"holds", {{"count", holds}}},
                          {"differs", {{"count", differs}}},
                          {"inconclusive", {{"count", n - holds - differs}}}};
  };
  nlohmann::json j = {
      {"design", {{"key", DesignKeyToJson(key)}}},
      {"laws",
       {{{"law", "paper"}, {"campaigns", n}, {"cells", {cell(true, paper_holds, paper_differs)}}},
        {{"law", "null"}, {"campaigns", n}, {"cells", {cell(false, null_holds, 0)}}}}}};
  Result<CalibrationTable> t = ParseCalibrationTable("test.json", j);
  EXPECT_TRUE(t.ok()) << t.status().ToString();
  return *t;
}

DesignKey Key(int beds = 1) {
  DesignKey k;
  k.campaign = "c";
  k.definition_hash = "abc";
  k.scale = "smoke";
  k.beds = beds;
  return k;
}

TEST(ClaimRatesTest, QuotesUpperBoundsAndPowerWithItsInterval) {
  const ClaimRates r = RatesFor("F9", "P", Key(), {Table(Key(), 210, 3, 6)});
  ASSERT_TRUE(r.calibrated);
  ASSERT_TRUE(r.false_holds && r.false_differs && r.power);
  EXPECT_EQ(r.false_holds->law, "null");
  EXPECT_EQ(r.false_holds->count, 6);
  EXPECT_GT(r.false_holds->hi, 6.0 / 300);  // the upper bound, not the estimate
  EXPECT_NEAR(r.power->rate, 0.7, 1e-12);
  EXPECT_LT(r.power->lo, 0.7);
  EXPECT_GT(r.power->hi, 0.7);
  EXPECT_FALSE(r.low_power);
  EXPECT_THAT(r.text, HasSubstr("false holds <= 4.3 %"));  // Wilson upper bound of 6/300
  EXPECT_THAT(r.text, HasSubstr("false differs <= 2.9 %"));
  EXPECT_THAT(r.text, HasSubstr("power 70 % [64.6, 74.9]"));
  EXPECT_THAT(r.text, HasSubstr("at this design"));
  EXPECT_EQ(r.advice, "");
}

TEST(ClaimRatesTest, LowPowerSaysWhatWouldHelp) {
  const ClaimRates r = RatesFor("F9", "P", Key(), {Table(Key(), 36, 0, 0)});
  EXPECT_TRUE(r.low_power);
  EXPECT_THAT(r.advice, HasSubstr("power 12 % at this design: longer runs"));
  EXPECT_THAT(r.advice, HasSubstr("not measured here"));
  // With another K calibrated for the campaign, its measured power is named (higher or lower).
  const ClaimRates with_k3 = RatesFor("F9", "P", Key(), {Table(Key(), 36, 0, 0), Table(Key(3), 150, 0, 0)});
  EXPECT_THAT(with_k3.advice, HasSubstr("measured at K = 3: 50 %"));
}

TEST(ClaimRatesTest, AnotherDesignIsNeverQuoted) {
  const std::vector<CalibrationTable> tables = {Table(Key(1), 210, 3, 6)};
  const ClaimRates k3 = RatesFor("F9", "P", Key(3), tables);
  EXPECT_FALSE(k3.calibrated);
  EXPECT_FALSE(k3.power || k3.false_holds || k3.false_differs);
  EXPECT_THAT(k3.text, HasSubstr("not calibrated at this design"));
  EXPECT_THAT(k3.text, HasSubstr("calibrated at K = 1, not 3"));
  EXPECT_THAT(k3.advice, HasSubstr("bench_claims_calibration --campaign c --scale smoke --beds 3"));
  DesignKey stale = Key();
  stale.rules_version = kClaimRulesVersion + 1;
  EXPECT_THAT(RatesFor("F9", "P", stale, tables).text, HasSubstr("stale"));
  // A K = 1 table made with another bed prior (core/scale.h) is stale, not quoted.
  DesignKey prior = Key();
  prior.bed_sd_rel = 0.17;
  const ClaimRates with_prior = RatesFor("F9", "P", prior, tables);
  EXPECT_FALSE(with_prior.calibrated);
  EXPECT_THAT(with_prior.text, HasSubstr("bed prior"));
  EXPECT_EQ(BedPriorOf("smoke"), 0.17);
  EXPECT_EQ(BedPriorOf("paper"), 0.0);
  EXPECT_EQ(BedPriorOf("no-such-scale"), 0.0);
  DesignKey other = Key();
  other.definition_hash = "def";
  const ClaimRates r = RatesFor("F9", "P", other, tables);
  EXPECT_FALSE(r.calibrated);
  EXPECT_THAT(r.text, Not(HasSubstr("K = 1, not")));
  // A part no law decides has no rate, and says so.
  EXPECT_THAT(RatesFor("F9", "Q", Key(), tables).text, HasSubstr("no law of the truth engine decides"));
}

TEST(ClaimRatesTest, DefinitionHashIgnoresWhatTheAnalysisDoesNotSee) {
  Result<nlohmann::json> def = BuiltinCampaignDefinition("paper-58");
  ASSERT_TRUE(def.ok());
  const std::string h = CampaignDefinitionHash(*def);
  nlohmann::json same = *def;
  same["replicates"] = 3;
  same["description"] = "another text";
  same["schedule"] = "0 3 * * *";
  same["sweeps"][0]["description"] = "changed";
  same["sweeps"][6].erase("snapshots");
  EXPECT_EQ(CampaignDefinitionHash(same), h);
  nlohmann::json other = *def;
  other["sweeps"][7]["base"]["duration_s"] = 5;
  EXPECT_NE(CampaignDefinitionHash(other), h);
  nlohmann::json rule = *def;
  rule["claims"][3]["rule"]["f_c_tolerance_hz"] = 1;
  EXPECT_NE(CampaignDefinitionHash(rule), h);
  nlohmann::json precision = *def;
  precision["precision"] = {{"uz_rel", 0.1}};
  EXPECT_NE(CampaignDefinitionHash(precision), h);
  // The claims a run was judged by, given, stand for the definition's.
  Result<Campaign> c = BuiltinCampaign("paper-58");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(CampaignDefinitionHash(*def, c->claims), h);
}

TEST(ClaimRatesTest, WilsonIntervalHoldsItsEstimate) {
  auto [lo, hi] = WilsonInterval(0, 300);
  EXPECT_EQ(lo, 0);
  EXPECT_NEAR(hi, 0.0126, 1e-3);
  std::tie(lo, hi) = WilsonInterval(150, 300);
  EXPECT_LT(lo, 0.5);
  EXPECT_GT(hi, 0.5);
  std::tie(lo, hi) = WilsonInterval(0, 0);
  EXPECT_EQ(lo, 0);
  EXPECT_EQ(hi, 1);
}

}  // namespace
}  // namespace sandswim
