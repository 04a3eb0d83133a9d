#include "core/sweep.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <set>

#include "core/deck.h"
#include "core/keys.h"

namespace sandswim {
namespace {

using nlohmann::json;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Not;

json IssueExample() {
  return json::parse(R"({"name": "omega-sign", "scale": "smoke",
     "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
     "axes": [{"param": "Omega", "values": [-80, 80]}],
     "combine": "product"})");
}

// The status of parsing, then expanding, `j`.
Status ParseAndExpand(const json& j) {
  auto s = ParseSweep(j);
  if (!s.ok()) return s.status();
  auto points = ExpandSweep(*s);
  return points.status();
}

TEST(SweepTest, IssueExampleExpandsToTwoPoints) {
  auto s = ParseSweep(IssueExample());
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->name, "omega-sign");
  EXPECT_EQ(s->scale, "smoke");
  EXPECT_EQ(s->combine, Combine::kProduct);
  auto points = ExpandSweep(*s);
  ASSERT_TRUE(points.ok()) << points.status().ToString();
  ASSERT_EQ(points->size(), 2u);
  EXPECT_EQ((*points)[0].Omega, -80);
  EXPECT_EQ((*points)[1].Omega, 80);
  for (const Point& p : *points) {
    EXPECT_EQ(p.mode, Mode::kOscillatory);
    EXPECT_EQ(p.A, 0.03);
    EXPECT_EQ(p.f, 3);
    EXPECT_EQ(p.duration_s, 0.3);
  }
}

TEST(SweepTest, NoAxesIsTheBaseAlone) {
  json j = IssueExample();
  j.erase("axes");
  j.erase("combine");
  auto s = ParseSweep(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  auto points = ExpandSweep(*s);
  ASSERT_TRUE(points.ok());
  ASSERT_EQ(points->size(), 1u);
  EXPECT_EQ((*points)[0].Omega, -80);
}

TEST(SweepTest, ForceAndDescriptionAreAccepted) {
  json j = IssueExample();
  j["force"] = true;
  j["description"] = "sign of Omega";
  EXPECT_TRUE(ParseSweep(j).ok());
  j["force"] = "yes";
  EXPECT_EQ(ParseSweep(j).status().field(), "force");
}

TEST(SweepTest, EveryModeParsesWithItsFields) {
  for (const char* text : {
           R"({"mode": "vibration", "A": 0.03, "f": 3, "duration_s": 1})",
           R"({"mode": "rotation", "omega": 80, "axis": "xz", "duration_s": 1})",
           R"({"mode": "vibration+rotation", "A": 0.03, "f": 3, "omega": -80, "axis": "y", "duration_s": 1})",
           R"({"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": 80, "duration_s": 1})",
       }) {
    json j = {{"name", "m"}, {"scale", "smoke"}, {"base", json::parse(text)}};
    auto s = ParseSweep(j);
    ASSERT_TRUE(s.ok()) << text << ": " << s.status().ToString();
    EXPECT_EQ(PointToJson(s->base), json::parse(text)) << text;
  }
}

struct BadCase {
  const char* what;
  std::function<void(json&)> edit;
  std::string field;
  StatusCode code = StatusCode::kInvalidArgument;
};

TEST(SweepTest, BadInputNamesTheField) {
  const std::vector<BadCase> cases = {
      // Malformed structure.
      {"not an object",
       [](json& j) {
         j = json::array({1, 2});
       },
       ""},
      {"base not an object", [](json& j) { j["base"] = json::array(); }, "base"},
      {"axes not an array", [](json& j) { j["axes"] = json::object(); }, "axes"},
      {"axis not an object", [](json& j) { j["axes"][0] = 5; }, "axes[0]"},
      {"axis with two sources",
       [](json& j) {
         j["axes"][0]["range"] = {{"from", 1}, {"to", 2}, {"step", 1}};
       },
       "axes[0]"},
      {"axis with no source", [](json& j) { j["axes"][0].erase("values"); }, "axes[0]"},
      {"empty values", [](json& j) { j["axes"][0]["values"] = json::array(); }, "axes[0].values"},
      {"missing base", [](json& j) { j.erase("base"); }, "base"},
      {"missing name", [](json& j) { j.erase("name"); }, "name"},
      {"missing required base field", [](json& j) { j["base"].erase("f"); }, "base.f"},
      {"missing mode", [](json& j) { j["base"].erase("mode"); }, "base.mode"},
      // Unknown fields, at every level.
      {"unknown top-level field", [](json& j) { j["foo"] = 1; }, "foo"},
      {"unknown base field", [](json& j) { j["base"]["foo"] = 1; }, "base.foo"},
      {"unknown axis field", [](json& j) { j["axes"][0]["foo"] = 1; }, "axes[0].foo"},
      {"unknown range field",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"}, {"range", {{"from", 1}, {"to", 2}, {"step", 1}, {"by", 1}}}};
       },
       "axes[0].range.by"},
      {"base field the mode does not use", [](json& j) { j["base"]["omega"] = 3; }, "base.omega"},
      {"axis param the mode does not use", [](json& j) { j["axes"][0]["param"] = "omega"; }, "axes[0].param"},
      {"unknown axis param", [](json& j) { j["axes"][0]["param"] = "g"; }, "axes[0].param"},
      {"two axes on one param", [](json& j) { j["axes"][1] = j["axes"][0]; }, "axes[1].param"},
      // Wrong types and bad enumerations.
      {"name not a string", [](json& j) { j["name"] = 5; }, "name"},
      {"name with a space", [](json& j) { j["name"] = "a b"; }, "name"},
      {"name a URL normalises (.)", [](json& j) { j["name"] = "."; }, "name"},
      {"name a URL normalises (..)", [](json& j) { j["name"] = ".."; }, "name"},
      {"name too long", [](json& j) { j["name"] = std::string(101, 'a'); }, "name"},
      {"unknown scale", [](json& j) { j["scale"] = "huge"; }, "scale"},
      {"unknown mode", [](json& j) { j["base"]["mode"] = "swim"; }, "base.mode"},
      {"combine not a string", [](json& j) { j["combine"] = 1; }, "combine"},
      {"unknown combine", [](json& j) { j["combine"] = "cross"; }, "combine"},
      {"bool for a number", [](json& j) { j["base"]["A"] = true; }, "base.A"},
      {"null for a number", [](json& j) { j["base"]["A"] = nullptr; }, "base.A"},
      // Deck injection: a string where a number belongs, with or without a newline.
      {"string for a number", [](json& j) { j["base"]["A"] = "0.03"; }, "base.A"},
      {"newline in a number's place", [](json& j) { j["base"]["f"] = "3\nshell rm -rf /"; }, "base.f"},
      {"string in values", [](json& j) { j["axes"][0]["values"][1] = "80"; }, "axes[0].values[1]"},
      {"string in range",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"}, {"range", {{"from", "1"}, {"to", 2}, {"step", 1}}}};
       },
       "axes[0].range.from"},
      // Values out of bounds.
      {"A = 0", [](json& j) { j["base"]["A"] = 0; }, "base.A"},
      {"A < 0", [](json& j) { j["base"]["A"] = -0.01; }, "base.A"},
      {"f = 0", [](json& j) { j["base"]["f"] = 0; }, "base.f"},
      {"f < 0", [](json& j) { j["base"]["f"] = -3; }, "base.f"},
      {"|Omega| over the cap in an axis", [](json& j) { j["axes"][0]["values"][1] = 5001; }, "axes[0].values[1]"},
      {"|Omega| over the cap in base", [](json& j) { j["base"]["Omega"] = -5001; }, "base.Omega"},
      {"duration over a day", [](json& j) { j["base"]["duration_s"] = 86401; }, "base.duration_s"},
      {"duration zero", [](json& j) { j["base"]["duration_s"] = 0; }, "base.duration_s"},
      // JSON text cannot carry NaN or Infinity (nlohmann refuses 1e400 as malformed), but a json
      // value built in code can.
      {"infinity", [](json& j) { j["base"]["A"] = std::numeric_limits<double>::infinity(); }, "base.A"},
      {"NaN in values", [](json& j) { j["axes"][0]["values"][0] = std::nan(""); }, "axes[0].values[0]"},
      {"A <= 0 in a range",
       [](json& j) {
         j["axes"][0] = {{"param", "A"}, {"range", {{"from", -0.01}, {"to", 0.02}, {"step", 0.01}}}};
       },
       "axes[0].range"},
      {"zero step",
       [](json& j) {
         j["axes"][0] = {{"param", "A"}, {"range", {{"from", 0.01}, {"to", 0.02}, {"step", 0}}}};
       },
       "axes[0].range.step"},
      {"geometric sign 2",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"},
                         {"geometric", {{"start", 10}, {"ratio", 2}, {"count", 3}, {"signs", {1, 2}}}}};
       },
       "axes[0].geometric.signs[1]"},
      {"geometric count 2.5",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"}, {"geometric", {{"start", 10}, {"ratio", 2}, {"count", 2.5}}}};
       },
       "axes[0].geometric.count"},
      {"geometric over the cap",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"}, {"geometric", {{"start", 10}, {"ratio", 2}, {"count", 10}}}};
       },
       "axes[0].geometric"},
      // The box: A = 0.2 m needs the paper's box, A = 0.105 m the mini one.
      {"A too large for smoke", [](json& j) { j["base"]["A"] = 0.2; }, "base.A", StatusCode::kFailedPrecondition},
      {"A too large for smoke in an axis",
       [](json& j) {
         j["axes"][0] = {{"param", "A"}, {"values", {0.03, 0.105}}};
       },
       "axes[0].values[1]", StatusCode::kFailedPrecondition},
      // Size.
      {"product past the run limit",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"}, {"range", {{"from", -1000}, {"to", 999}, {"step", 1}}}};
         j["axes"][1] = {{"param", "f"}, {"range", {{"from", 0.01}, {"to", 1}, {"step", 0.01}}}};
       },
       "axes", StatusCode::kResourceExhausted},
      {"range past the run limit",
       [](json& j) {
         j["axes"][0] = {{"param", "Omega"}, {"range", {{"from", 0}, {"to", 1}, {"step", 1e-9}}}};
       },
       "axes[0].range", StatusCode::kResourceExhausted},
      {"zip length mismatch",
       [](json& j) {
         j["combine"] = "zip";
         j["axes"][1] = {{"param", "A"}, {"values", {0.01, 0.02, 0.03}}};
       },
       "axes[1]"},
  };
  for (const auto& c : cases) {
    json j = IssueExample();
    c.edit(j);
    Status s = ParseAndExpand(j);
    EXPECT_FALSE(s.ok()) << c.what;
    EXPECT_EQ(s.field(), c.field) << c.what << ": " << s.ToString();
    EXPECT_EQ(s.code(), c.code) << c.what << ": " << s.ToString();
    EXPECT_THAT(s.reason(), Not(HasSubstr("\n"))) << c.what;
    EXPECT_THAT(s.reason(), Not(HasSubstr("rm -rf"))) << c.what;
  }
}

TEST(SweepTest, AmplitudeRefusalNamesAScaleThatTakesIt) {
  json j = IssueExample();
  j["base"]["A"] = 0.2;
  Status s = ParseSweep(j).status();
  EXPECT_EQ(s.field(), "base.A");
  EXPECT_THAT(s.reason(), HasSubstr("scale 'paper' takes it"));
  EXPECT_THAT(s.reason(), HasSubstr("'smoke'"));
  j["base"]["A"] = 0.105;
  s = ParseSweep(j).status();
  EXPECT_EQ(s.field(), "base.A");
  EXPECT_THAT(s.reason(), HasSubstr("scale 'mini' takes it"));
  // The same sweep at the paper's scale is fine.
  j["scale"] = "paper";
  EXPECT_TRUE(ParseSweep(j).ok());
}

TEST(SweepTest, UnknownFieldNameIsEscapedInThePath) {
  json j = IssueExample();
  j["base"]["A\nshell"] = 1;
  Status s = ParseSweep(j).status();
  EXPECT_EQ(s.field(), "base.A\\u000ashell");
}

TEST(SweepTest, ExpandSweepChecksHandBuiltSpecs) {
  auto spec = ParseSweep(IssueExample());
  ASSERT_TRUE(spec.ok());
  // Past max_points, before materializing.
  auto r = ExpandSweep(*spec, 1);
  EXPECT_EQ(r.status().code(), StatusCode::kResourceExhausted);
  EXPECT_EQ(r.status().field(), "axes");
  // NaN cannot come from JSON, but a hand-built spec may carry it.
  SweepSpec bad = *spec;
  bad.base.A = std::nan("");
  EXPECT_EQ(ExpandSweep(bad).status().field(), "base.A");
  bad = *spec;
  bad.axes[0].values[1] = 9000;
  EXPECT_EQ(ExpandSweep(bad).status().field(), "axes[0].values[1]");
  bad = *spec;
  bad.axes.push_back({"A", {0.01, 0.2}, "range"});
  Status s = ExpandSweep(bad).status();
  EXPECT_EQ(s.field(), "axes[1].range");
  EXPECT_THAT(s.reason(), HasSubstr("value [1]"));
  // Product size overflowing size_t is refused, not wrapped.
  SweepSpec huge = *spec;
  huge.axes.clear();
  std::vector<double> many(100000, 1.0);
  for (const char* p : {"A", "f", "Omega", "duration_s"}) huge.axes.push_back({p, many, "values"});
  EXPECT_EQ(ExpandSweep(huge).status().code(), StatusCode::kResourceExhausted);
}

// Golden: these exact doubles (not 0.30000000000000004) and this order.
TEST(SweepTest, RangeGivesExactDecimals) {
  json j = IssueExample();
  j["scale"] = "paper";
  j["axes"] = json::array({{{"param", "A"}, {"range", {{"from", 0.01}, {"to", 0.10}, {"step", 0.01}}}}});
  auto s = ParseSweep(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_THAT(s->axes[0].values, ElementsAre(0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1));
  auto points = ExpandSweep(*s);
  ASSERT_TRUE(points.ok());
  std::vector<double> as;
  for (const Point& p : *points) as.push_back(p.A);
  EXPECT_THAT(as, ElementsAre(0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1));
}

TEST(SweepTest, GeometricWithSignsGivesEachSignInTurn) {
  json j = IssueExample();
  j["axes"] = json::array(
      {{{"param", "Omega"}, {"geometric", {{"start", 10}, {"ratio", 2}, {"count", 8}, {"signs", {-1, 1}}}}}});
  auto s = ParseSweep(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  auto points = ExpandSweep(*s);
  ASSERT_TRUE(points.ok());
  std::vector<double> omegas;
  for (const Point& p : *points) omegas.push_back(p.Omega);
  EXPECT_THAT(omegas, ElementsAre(-10, -20, -40, -80, -160, -320, -640, -1280, 10, 20, 40, 80, 160, 320, 640, 1280));
  // Without signs: the positive series alone.
  j["axes"][0]["geometric"].erase("signs");
  j["axes"][0]["geometric"]["ratio"] = 0.5;
  j["axes"][0]["geometric"]["count"] = 3;
  s = ParseSweep(j);
  ASSERT_TRUE(s.ok());
  EXPECT_THAT(s->axes[0].values, ElementsAre(10, 5, 2.5));
}

TEST(SweepTest, ProductVariesTheLastAxisFastestAndZipPairs) {
  json j = IssueExample();
  j["axes"] = json::parse(R"([{"param": "A", "values": [0.01, 0.02]}, {"param": "Omega", "values": [-80, 80]}])");
  auto s = ParseSweep(j);
  ASSERT_TRUE(s.ok());
  auto points = ExpandSweep(*s);
  ASSERT_TRUE(points.ok());
  std::vector<std::pair<double, double>> got;
  for (const Point& p : *points) got.emplace_back(p.A, p.Omega);
  EXPECT_THAT(
      got, ElementsAre(std::pair(0.01, -80.0), std::pair(0.01, 80.0), std::pair(0.02, -80.0), std::pair(0.02, 80.0)));
  j["combine"] = "zip";
  s = ParseSweep(j);
  ASSERT_TRUE(s.ok());
  points = ExpandSweep(*s);
  ASSERT_TRUE(points.ok());
  got.clear();
  for (const Point& p : *points) got.emplace_back(p.A, p.Omega);
  EXPECT_THAT(got, ElementsAre(std::pair(0.01, -80.0), std::pair(0.02, 80.0)));
}

// ---------------------------------------------------------------------------------------------
// Campaigns.

TEST(CampaignTest, Paper58IsBuiltIn) {
  EXPECT_THAT(BuiltinCampaignNames(), ElementsAre("paper-58", "density-ratio", "dt-convergence"));
  auto c = BuiltinCampaign("paper-58");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->name, "paper-58");
  EXPECT_EQ(c->scale, "paper");
  EXPECT_TRUE(c->schedule.has_value());
  EXPECT_EQ(c->drift_tolerance_mps, 0);  // drift is judged by the results' own errors (drift_report.h)
  EXPECT_THAT(c->description, HasSubstr("rotation only"));
  for (const auto& s : c->sweeps) EXPECT_EQ(s.scale, "paper");
  EXPECT_EQ(BuiltinCampaign("paper-59").status().code(), StatusCode::kNotFound);
}

const PlannedRun* FindRun(const Plan& plan, Mode mode, double A, double f, double Omega) {
  for (const auto& r : plan.runs)
    if (r.point.mode == mode && r.point.A == A && r.point.f == f && r.point.Omega == Omega) return &r;
  return nullptr;
}

TEST(CampaignTest, Paper58PlansFiftyEightRuns) {
  auto c = BuiltinCampaign("paper-58");
  ASSERT_TRUE(c.ok());
  auto plan = PlanSweeps(c->sweeps, *FindScale("paper"), "LIGGGHTS-PUBLIC 3.8.0");
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->scale, "paper");
  ASSERT_EQ(plan->runs.size(), 58u);
  int four = 0, five = 0;
  std::set<std::string> keys;
  for (const auto& r : plan->runs) {
    if (r.point.duration_s == 4) ++four;
    if (r.point.duration_s == 5) ++five;
    EXPECT_EQ(r.run_duration_s, r.point.duration_s);  // the paper scale never cuts
    EXPECT_EQ(r.steps, DriveSteps(r.point, std::nullopt));
    EXPECT_FALSE(r.precision.has_value());  // neither the campaign nor the paper scale sets one
    EXPECT_FALSE(r.deck.empty());
    keys.insert(r.key);
  }
  EXPECT_EQ(four, 56);
  EXPECT_EQ(five, 2);
  EXPECT_EQ(keys.size(), 58u);
  EXPECT_FALSE(plan->beds.at(0).deck.empty());
  EXPECT_EQ(plan->beds.at(0).key.size(), 64u);

  for (double omega : {-80.0, 80.0}) {
    const PlannedRun* r = FindRun(*plan, Mode::kOscillatory, 0.03, 3, omega);
    ASSERT_NE(r, nullptr) << omega;
    EXPECT_EQ(r->point.duration_s, 5);
    EXPECT_THAT(r->sweeps, ElementsAre("baseline", "Omega-sweep", "A-sweep", "f-sweep"));
  }
  // A point only one sweep names belongs to that sweep alone.
  const PlannedRun* r = FindRun(*plan, Mode::kOscillatory, 0.1, 3, -80);
  ASSERT_NE(r, nullptr);
  EXPECT_THAT(r->sweeps, ElementsAre("A-sweep"));
  EXPECT_EQ(r->point.duration_s, 4);
  // Six mode runs, one each.
  int modes = 0;
  for (const auto& run : plan->runs)
    if (run.point.mode != Mode::kOscillatory) {
      ++modes;
      EXPECT_EQ(run.sweeps.size(), 1u);
      EXPECT_EQ(run.sweeps[0].rfind("modes.", 0), 0u);
    }
  EXPECT_EQ(modes, 6);
}

TEST(CampaignTest, Paper58AtSmokeScaleStillHasFiftyEightRuns) {
  auto c = BuiltinCampaign("paper-58");
  ASSERT_TRUE(c.ok());
  const Scale& smoke = *FindScale("smoke");
  auto plan = PlanSweeps(c->sweeps, smoke, "e");
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->runs.size(), 58u);
  for (const auto& r : plan->runs) {
    ASSERT_TRUE(r.precision.has_value());  // the smoke scale's default
    EXPECT_EQ(*r.precision, *smoke.default_precision);
    EXPECT_EQ(r.run_duration_s, RunDuration(r.point, smoke.default_precision));
  }
}

TEST(SweepTest, PrecisionTargetsParseAndMerge) {
  auto s = ParseSweep(json::parse(R"({"name": "p", "scale": "smoke",
      "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 4},
      "precision": {"uz_rel": 0.1, "uz_abs": 0.002, "min_periods": 4, "max_duration_s": 3}})"));
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  ASSERT_TRUE(s->precision.has_value());
  EXPECT_EQ(*s->precision, (PrecisionTarget{0.1, 0.002, 4, 3}));

  // Bad targets name the field under "precision".
  for (const auto& [bad, field] : std::vector<std::pair<std::string, std::string>>{
           {R"({"uz_rel": 0.1})", "precision.max_duration_s"},
           {R"({"uz_rel": -1, "max_duration_s": 2})", "precision.uz_rel"},
           {R"({"uz_rel": 0, "uz_abs": 0, "max_duration_s": 2})", "precision.uz_rel"},
           {R"({"uz_rel": 0.1, "min_periods": 2, "max_duration_s": 2})", "precision.min_periods"},
           {R"({"uz_rel": 0.1, "min_periods": 3.5, "max_duration_s": 2})", "precision.min_periods"},
           {R"({"uz_rel": "0.1", "max_duration_s": 2})", "precision.uz_rel"},
           {R"({"uz_rel": 0.1, "max_duration_s": 0})", "precision.max_duration_s"},
           {R"({"uz_rel": 0.1, "max_duration_s": 2, "tolerance": 1})", "precision.tolerance"},
           {R"([1])", "precision"}}) {
    SCOPED_TRACE(bad);
    json j = json::parse(R"({"name": "p", "scale": "smoke",
        "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 4}})");
    j["precision"] = json::parse(bad);
    auto r = ParseSweep(j);
    ASSERT_FALSE(r.ok());
    EXPECT_EQ(r.status().field(), field);
  }

  // A point two sweeps share runs once, to the tighter target; with a sweep that sets none at a
  // scale without a default, it runs its whole duration.
  SweepSpec loose = *s, tight = *s, none = *s;
  loose.name = "loose";
  tight.name = "tight";
  none.name = "none";
  tight.precision = PrecisionTarget{0.05, 0.004, 5, 2};
  auto plan = PlanSweeps({loose, tight}, *FindScale("smoke"), "e");
  ASSERT_TRUE(plan.ok());
  ASSERT_EQ(plan->runs.size(), 1u);
  EXPECT_EQ(*plan->runs[0].precision, (PrecisionTarget{0.05, 0.002, 5, 3}));
  none.precision.reset();
  auto paper = PlanSweeps({loose, none}, *FindScale("paper"), "e");
  ASSERT_TRUE(paper.ok());
  ASSERT_EQ(paper->runs.size(), 1u);
  EXPECT_FALSE(paper->runs[0].precision.has_value());
  EXPECT_EQ(paper->runs[0].run_duration_s, 4);
}

// Replicate beds: K beds poured from K seeds, each point once on each, keys apart.
TEST(SweepTest, ReplicatesRunEachPointOnEachOfKBeds) {
  json j = IssueExample();
  j["replicates"] = 3;
  auto s = ParseSweep(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->Replicates(), 3);
  const Scale& smoke = *FindScale("smoke");
  auto plan = PlanSweeps({*s}, smoke, "e");
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ASSERT_EQ(plan->beds.size(), 3u);
  std::set<std::string> bed_keys;
  std::set<long long> seeds;
  for (int r = 0; r < 3; ++r) {
    const PlannedBed& bed = plan->beds[r];
    EXPECT_EQ(bed.replicate, r);
    EXPECT_EQ(bed.deck, RenderBedDeck(smoke, r));
    EXPECT_THAT(bed.deck, HasSubstr("insert/pack seed " + std::to_string(bed.seeds.pour1) + " "));
    EXPECT_THAT(bed.deck, HasSubstr("insert/pack seed " + std::to_string(bed.seeds.pour2) + " "));
    bed_keys.insert(bed.key);
    seeds.insert(bed.seeds.pour1);
    seeds.insert(bed.seeds.pour2);
  }
  EXPECT_EQ(bed_keys.size(), 3u);
  EXPECT_EQ(seeds.size(), 6u);
  EXPECT_EQ(plan->beds[0].deck, RenderBedDeck(smoke));  // replicate 0 is the bed without replicates
  // Two points, three beds each: six runs, six keys; a point's deck is the same on every bed.
  ASSERT_EQ(plan->runs.size(), 6u);
  std::set<std::string> run_keys;
  std::map<int, int> per_replicate;
  for (const PlannedRun& r : plan->runs) {
    run_keys.insert(r.key);
    ++per_replicate[r.replicate];
    EXPECT_EQ(r.key, RunKey(r.deck, plan->beds[r.replicate].key, "e"));
    EXPECT_EQ(PlannedRunToJson(r)["replicate"], r.replicate);
  }
  EXPECT_EQ(run_keys.size(), 6u);
  EXPECT_EQ(per_replicate, (std::map<int, int>{{0, 2}, {1, 2}, {2, 2}}));
  EXPECT_EQ(plan->runs[0].deck, plan->runs[1].deck);

  // A sweep without replicates, planned beside it, shares replicate 0's runs.
  SweepSpec single = *s;
  single.name = "single";
  single.replicates.reset();
  auto both = PlanSweeps({single, *s}, smoke, "e");
  ASSERT_TRUE(both.ok());
  EXPECT_EQ(both->runs.size(), 6u);
  for (const PlannedRun& r : both->runs) EXPECT_EQ(r.sweeps.size(), r.replicate == 0 ? 2u : 1u) << r.replicate;

  // K times the points counts against the run limit, and the refusal names "replicates".
  auto capped = PlanSweeps({*s}, smoke, "e", 5);
  ASSERT_FALSE(capped.ok());
  EXPECT_EQ(capped.status().field(), "replicates") << capped.status().ToString();
}

TEST(SweepTest, BadReplicatesNameTheField) {
  for (const json& bad : {json(0), json(21), json(2.5), json("2"), json(-1), json(nullptr)}) {
    json j = IssueExample();
    j["replicates"] = bad;
    auto s = ParseSweep(j);
    ASSERT_FALSE(s.ok()) << bad.dump();
    EXPECT_EQ(s.status().field(), "replicates") << bad.dump();
  }
  // A campaign's replicates hold for its sweeps that set none.
  json c = json::parse(R"({"name": "c", "description": "d", "scale": "smoke", "replicates": 2,
      "sweeps": [{"name": "a", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": 80, "duration_s": 1}},
                 {"name": "b", "replicates": 4,
                  "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 1}}]})");
  auto campaign = ParseCampaign(c);
  ASSERT_TRUE(campaign.ok()) << campaign.status().ToString();
  EXPECT_EQ(campaign->sweeps[0].Replicates(), 2);
  EXPECT_EQ(campaign->sweeps[1].Replicates(), 4);
  c["replicates"] = 30;
  EXPECT_EQ(ParseCampaign(c).status().field(), "replicates");
}

TEST(CampaignTest, KeysAreStableAndFollowTheEngine) {
  auto c = BuiltinCampaign("paper-58");
  ASSERT_TRUE(c.ok());
  const Scale& smoke = *FindScale("smoke");
  auto a = PlanSweeps(c->sweeps, smoke, "LIGGGHTS 3.8.0");
  auto b = PlanSweeps(c->sweeps, smoke, "LIGGGHTS 3.8.0");
  auto other = PlanSweeps(c->sweeps, smoke, "LIGGGHTS 3.8.1");
  ASSERT_TRUE(a.ok() && b.ok() && other.ok());
  EXPECT_EQ(a->beds.at(0).key, b->beds.at(0).key);
  EXPECT_NE(a->beds.at(0).key, other->beds.at(0).key);
  ASSERT_EQ(a->runs.size(), other->runs.size());
  for (size_t i = 0; i < a->runs.size(); ++i) {
    EXPECT_EQ(a->runs[i].key, b->runs[i].key);
    EXPECT_EQ(a->runs[i].deck, b->runs[i].deck);
    EXPECT_NE(a->runs[i].key, other->runs[i].key);
  }
}

TEST(CampaignTest, PlanMergesSameDriveWithinAndAcrossSweeps) {
  auto s = ParseSweep(IssueExample());
  ASSERT_TRUE(s.ok());
  SweepSpec twice = *s;
  twice.name = "twice";
  twice.axes[0].values = {-80, 80, -80};  // a repeated point in one sweep runs once
  twice.base.duration_s = 0.2;
  auto plan = PlanSweeps({*s, twice}, *FindScale("smoke"), "e");
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ASSERT_EQ(plan->runs.size(), 2u);
  for (const auto& r : plan->runs) {
    EXPECT_EQ(r.point.duration_s, 0.3);
    EXPECT_THAT(r.sweeps, ElementsAre("omega-sign", "twice"));
  }
  // The run limit counts every expanded point.
  EXPECT_EQ(PlanSweeps({*s, twice}, *FindScale("smoke"), "e", 4).status().code(), StatusCode::kResourceExhausted);
  // A point the plan's scale cannot hold is refused naming the sweep.
  SweepSpec wide = *s;
  wide.scale = "paper";
  wide.base.A = 0.2;
  Status st = PlanSweeps({*s, wide}, *FindScale("smoke"), "e").status();
  EXPECT_EQ(st.code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(st.field(), "sweeps[1].base.A");
}

TEST(CampaignTest, PlanOptionsGiveTheSamePlan) {
  json j = IssueExample();
  j["axes"] = json::parse(R"([{"param": "Omega", "range": {"from": -100, "to": 100, "step": 0.1}}])");
  auto s = ParseSweep(j);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  const Scale& smoke = *FindScale("smoke");
  auto one = PlanSweeps({*s}, smoke, "e");
  PlanOptions options;
  options.threads = 2;
  options.keep_decks = false;
  auto two = PlanSweeps({*s}, smoke, "e", options);
  ASSERT_TRUE(one.ok() && two.ok());
  ASSERT_EQ(one->runs.size(), 2001u);
  ASSERT_EQ(two->runs.size(), one->runs.size());
  for (size_t i = 0; i < one->runs.size(); ++i) {
    EXPECT_EQ(two->runs[i].key, one->runs[i].key);
    EXPECT_EQ(two->runs[i].steps, one->runs[i].steps);
    EXPECT_TRUE(two->runs[i].deck.empty());
  }
  // The deck a lease renders later is the one the key was made from.
  EXPECT_EQ(RenderDriveDeck(two->runs[7].point, smoke, two->runs[7].precision), one->runs[7].deck);
  options.max_runs = 2000;
  EXPECT_EQ(PlanSweeps({*s}, smoke, "e", options).status().code(), StatusCode::kResourceExhausted);
}

// Golden run key. A change here means the decks or the key recipe changed: if that was on
// purpose (a template edit should also bump kTemplateVersion), paste the new key.
TEST(CampaignTest, GoldenRunKey) {
  auto s = ParseSweep(IssueExample());
  ASSERT_TRUE(s.ok());
  s->axes.clear();
  auto plan = PlanSweeps({*s}, *FindScale("smoke"), "LIGGGHTS-PUBLIC 3.8.0");
  ASSERT_TRUE(plan.ok());
  ASSERT_EQ(plan->runs.size(), 1u);
  EXPECT_EQ(plan->runs[0].key, "536c66133897e94239740f6a6d036a7df6cdf830bafc8172054245e085bb34bb");
}

TEST(CampaignTest, PlannedRunJsonHasTheModeFieldsOnly) {
  auto c = BuiltinCampaign("paper-58");
  ASSERT_TRUE(c.ok());
  auto plan = PlanSweeps(c->sweeps, *FindScale("smoke"), "e");
  ASSERT_TRUE(plan.ok());
  for (const auto& r : plan->runs) {
    json j = PlannedRunToJson(r);
    EXPECT_EQ(j["key"], r.key);
    EXPECT_EQ(j["mode"], std::string(ModeName(r.point.mode)));
    EXPECT_EQ(j["duration_s"], r.point.duration_s);
    EXPECT_EQ(j["run_duration_s"], r.run_duration_s);
    EXPECT_EQ(j["steps"], r.steps);
    EXPECT_EQ(j["sweeps"], json(r.sweeps));
    EXPECT_EQ(j.contains("Omega"), r.point.mode == Mode::kOscillatory);
    EXPECT_EQ(j.contains("omega"), r.point.has_constant_rotation());
    EXPECT_EQ(j.contains("axis"), r.point.has_constant_rotation());
    EXPECT_EQ(j.contains("A"), r.point.has_vibration());
  }
  json rot = PlannedRunToJson(plan->runs[1]);
  EXPECT_EQ(rot["mode"], "rotation");
  EXPECT_EQ(rot["omega"], 80.0);
  EXPECT_EQ(rot["axis"], "x");
}

json SmallCampaign() {
  return json::parse(R"({"name": "c", "description": "d", "scale": "smoke", "schedule": "0 2 * * *",
      "drift_tolerance_mps": 0.01,
      "sweeps": [{"name": "s", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": 80, "duration_s": 1}}]})");
}

TEST(CampaignTest, BadCampaignsNameTheField) {
  EXPECT_TRUE(ParseCampaign(SmallCampaign()).ok());
  const std::vector<BadCase> cases = {
      {"sweep with its own scale", [](json& j) { j["sweeps"][0]["scale"] = "paper"; }, "sweeps[0].scale"},
      {"sweep with force", [](json& j) { j["sweeps"][0]["force"] = true; }, "sweeps[0].force"},
      {"repeated sweep name", [](json& j) { j["sweeps"][1] = j["sweeps"][0]; }, "sweeps[1].name"},
      {"bad schedule", [](json& j) { j["schedule"] = "nightly; rm"; }, "schedule"},
      {"four-field schedule", [](json& j) { j["schedule"] = "0 2 * *"; }, "schedule"},
      {"negative tolerance", [](json& j) { j["drift_tolerance_mps"] = -1; }, "drift_tolerance_mps"},
      {"string tolerance", [](json& j) { j["drift_tolerance_mps"] = "0.1"; }, "drift_tolerance_mps"},
      {"no sweeps", [](json& j) { j["sweeps"] = json::array(); }, "sweeps"},
      {"unknown field", [](json& j) { j["every"] = "night"; }, "every"},
      {"bad point", [](json& j) { j["sweeps"][0]["base"]["A"] = 0.5; }, "sweeps[0].base.A",
       StatusCode::kFailedPrecondition},
      {"missing description", [](json& j) { j.erase("description"); }, "description"},
  };
  for (const auto& c : cases) {
    json j = SmallCampaign();
    c.edit(j);
    Status s = ParseCampaign(j).status();
    EXPECT_FALSE(s.ok()) << c.what;
    EXPECT_EQ(s.field(), c.field) << c.what << ": " << s.ToString();
    EXPECT_EQ(s.code(), c.code) << c.what << ": " << s.ToString();
  }
}

// A submission of several sweeps past the cap names the sweep that passes it and says what the
// sweeps before it took (it once said "more than 0 points (at most 0 runs)").
TEST(SweepTest, ASweepPastWhatIsLeftOfTheCapSaysWhatTheSweepsBeforeItTook) {
  auto sweep = [](const std::string& name, double sign, int fs) {
    json values = json::array();
    for (int i = 0; i < fs; ++i) values.push_back(1 + 0.01 * i);
    json omegas = json::array();
    for (int i = 0; i < 10; ++i) omegas.push_back(sign * (10 + i));
    auto s = ParseSweep(json{{"name", name},
                             {"scale", "smoke"},
                             {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -80}, {"duration_s", 0.3}}},
                             {"axes", {{{"param", "Omega"}, {"values", omegas}}, {{"param", "f"}, {"values", values}}}}});
    EXPECT_TRUE(s.ok()) << s.status().ToString();
    return *s;
  };
  auto plan = PlanSweeps({sweep("a", 1, 6), sweep("b", -1, 5)}, *FindScale("smoke"), "e", 100);  // 60 + 50 runs
  ASSERT_FALSE(plan.ok());
  EXPECT_EQ(plan.status().field(), "sweeps[1].axes");
  EXPECT_EQ(plan.status().reason(), "with the 60 runs of the sweeps before it, the submission comes to more than 100 "
                                    "runs, the most one submission may hold");
  auto alone = PlanSweeps({sweep("c", 1, 11)}, *FindScale("smoke"), "e", 100);  // 110 runs
  ASSERT_FALSE(alone.ok());
  EXPECT_EQ(alone.status().reason(), "the sweep expands to more than 100 points (at most 100 runs per submission)");
}

}  // namespace

// A sweep may ask for snapshots; a point two sweeps share takes every fraction either asks for, and
// is a run of its own (another key) against the same point without snapshots.
TEST(SweepTest, SnapshotsParseMergeAndEnterTheKey) {
  json a = {{"name", "a"},
            {"scale", "smoke"},
            {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -80}, {"duration_s", 1}}},
            {"snapshots", {1, 0}}};
  auto sa = ParseSweep(a);
  ASSERT_TRUE(sa.ok()) << sa.status().ToString();
  EXPECT_EQ(*sa->snapshots, (SnapshotFractions{0, 1}));
  json b = a;
  b["name"] = "b";
  b["snapshots"] = {0.5, 1};
  json plain = a;
  plain["name"] = "plain";
  plain.erase("snapshots");
  auto sb = ParseSweep(b);
  auto sp = ParseSweep(plain);
  const Scale& smoke = *FindScale("smoke");
  auto both = PlanSweeps({*sa, *sb}, smoke, "engine");
  ASSERT_TRUE(both.ok());
  ASSERT_EQ(both->runs.size(), 1u);
  EXPECT_EQ(both->runs[0].snapshots, (SnapshotFractions{0, 0.5, 1}));
  EXPECT_THAT(both->runs[0].deck, HasSubstr("at 0, 0.5, 1 of the run's actual length"));
  auto alone = PlanSweeps({*sp}, smoke, "engine");
  ASSERT_TRUE(alone.ok());
  EXPECT_TRUE(alone->runs[0].snapshots.empty());
  EXPECT_NE(alone->runs[0].key, both->runs[0].key);
  for (json bad : {json(0.5), json({"start"}), json({0, 2}), json({0.5, 0.5})}) {
    json s = a;
    s["snapshots"] = bad;
    EXPECT_THAT(ParseSweep(s).status().field(), ::testing::StartsWith("snapshots")) << bad.dump();
  }
}

}  // namespace sandswim
