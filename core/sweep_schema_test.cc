// Keeps schema/sweep.schema.json and schema/campaign.schema.json in step with core/sweep.cc:
// every mode, field, parameter, axis key, enumeration and cap the schema states is checked
// against what ParseSweep / ParseCampaign actually accept, so neither can
// change without the other.
#include <gtest/gtest.h>

#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>

#include "core/point.h"
#include "core/scale.h"
#include "core/sweep.h"

namespace sandswim {
namespace {

using nlohmann::json;

json LoadSchema(const std::string& name) {
  std::ifstream in(std::string(SANDSWIM_SOURCE_DIR) + "/schema/" + name);
  if (!in) {
    ADD_FAILURE() << "cannot read schema/" << name;
    return json::object();
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return json::parse(ss.str());
}

class SweepSchemaTest : public ::testing::Test {
 protected:
  void SetUp() override {
    schema_ = LoadSchema("sweep.schema.json");
    defs_ = schema_.at("$defs");
  }
  // The names of an object schema's properties.
  static std::set<std::string> Keys(const json& object_schema) {
    std::set<std::string> keys;
    for (const auto& [k, v] : object_schema.at("properties").items()) {
      (void)v;
      keys.insert(k);
    }
    return keys;
  }
  static std::set<std::string> Strings(const json& array) { return array.get<std::set<std::string>>(); }

  json schema_;
  json defs_;
};

// A valid value for every base field.
json ValidValue(const std::string& field) {
  if (field == "A") return 0.03;
  if (field == "f") return 3;
  if (field == "Omega" || field == "omega") return 80;
  if (field == "axis") return "x";
  if (field == "duration_s") return 1;
  if (const MaterialField* m = FindMaterialField(field)) return kTable1.*m->member;
  ADD_FAILURE() << "no sample value for " << field;
  return nullptr;
}

const std::set<std::string> kMaterialParams = [] {
  std::set<std::string> names;
  for (const MaterialField& m : MaterialFields()) names.emplace(m.name);
  return names;
}();
const std::set<std::string> kAllParams = [] {
  std::set<std::string> all = {"A", "f", "Omega", "omega", "duration_s"};
  all.insert(kMaterialParams.begin(), kMaterialParams.end());
  return all;
}();

// The point schemas, by mode, as the schema lists them.
std::map<std::string, json> PointSchemas(const json& defs) {
  std::map<std::string, json> out;
  for (const auto& ref : defs.at("point").at("oneOf")) {
    std::string name = ref.at("$ref").get<std::string>().substr(std::string("#/$defs/").size());
    const json& p = defs.at(name);
    out[p.at("properties").at("mode").at("const").get<std::string>()] = p;
  }
  return out;
}

TEST_F(SweepSchemaTest, ModesAreTheOnesCxxKnows) {
  auto points = PointSchemas(defs_);
  std::set<std::string> schema_modes;
  for (const auto& [mode, p] : points) schema_modes.insert(mode);
  std::set<std::string> cxx_modes;
  for (Mode m : {Mode::kVibration, Mode::kRotation, Mode::kVibrationRotation, Mode::kOscillatory})
    cxx_modes.insert(std::string(ModeName(m)));
  EXPECT_EQ(schema_modes, cxx_modes);
}

TEST_F(SweepSchemaTest, EachModeRequiresAndAllowsTheSameFields) {
  for (const auto& [mode, p] : PointSchemas(defs_)) {
    EXPECT_FALSE(p.at("additionalProperties").get<bool>()) << mode;
    std::set<std::string> required = Strings(p.at("required"));
    std::set<std::string> drive_fields;
    for (const auto& k : Keys(p))
      if (!kMaterialParams.count(k)) drive_fields.insert(k);
    EXPECT_EQ(required, drive_fields) << mode << ": every listed drive field is required";
    for (const auto& m : kMaterialParams) EXPECT_TRUE(Keys(p).count(m)) << mode << " takes " << m;
    json base = {{"mode", mode}};
    for (const auto& f : required)
      if (f != "mode") base[f] = ValidValue(f);
    json sweep = {{"name", "s"}, {"scale", "smoke"}, {"base", base}};
    auto ok = ParseSweep(sweep);
    ASSERT_TRUE(ok.ok()) << mode << ": " << ok.status().ToString();
    for (const auto& f : required) {
      json missing = sweep;
      missing["base"].erase(f);
      EXPECT_EQ(ParseSweep(missing).status().field(), "base." + f) << mode << " without " << f;
    }
    std::set<std::string> others = kAllParams;
    others.insert("axis");
    for (const auto& f : others) {
      if (required.count(f) || kMaterialParams.count(f)) continue;
      json extra = sweep;
      extra["base"][f] = ValidValue(f);
      EXPECT_EQ(ParseSweep(extra).status().field(), "base." + f) << mode << " with " << f;
    }
  }
}

TEST_F(SweepSchemaTest, AxisParamsFollowTheMode) {
  const json& axis = defs_.at("axis_spec");
  EXPECT_EQ(Strings(axis.at("properties").at("param").at("enum")), kAllParams);
  auto points = PointSchemas(defs_);
  int rules = 0;
  for (const auto& rule : defs_.at("sweep").at("allOf")) {
    std::string mode = rule.at("if").at("properties").at("base").at("properties").at("mode").at("const");
    std::set<std::string> allowed =
        Strings(rule.at("then").at("properties").at("axes").at("items").at("properties").at("param").at("enum"));
    ++rules;
    json base = {{"mode", mode}};
    for (const auto& f : Strings(points.at(mode).at("required")))
      if (f != "mode") base[f] = ValidValue(f);
    for (const auto& param : kAllParams) {
      json sweep = {{"name", "s"}, {"scale", "smoke"}, {"base", base}};
      sweep["axes"] = json::array({{{"param", param}, {"values", {ValidValue(param)}}}});
      Status s = ParseSweep(sweep).status();
      if (allowed.count(param)) {
        EXPECT_TRUE(s.ok()) << mode << " axis " << param << ": " << s.ToString();
      } else {
        EXPECT_EQ(s.field(), "axes[0].param") << mode << " axis " << param;
      }
    }
  }
  EXPECT_EQ(rules, 4);
  EXPECT_EQ(defs_.at("campaign_sweep").at("allOf"), defs_.at("sweep").at("allOf"));
}

TEST_F(SweepSchemaTest, AxisKeysAndCaps) {
  const json& axis = defs_.at("axis_spec");
  EXPECT_EQ(Keys(axis), (std::set<std::string>{"param", "values", "range", "geometric"}));
  const json& range = axis.at("properties").at("range");
  EXPECT_EQ(Keys(range), (std::set<std::string>{"from", "to", "step"}));
  EXPECT_EQ(Strings(range.at("required")), Keys(range));
  const json& geo = axis.at("properties").at("geometric");
  EXPECT_EQ(Keys(geo), (std::set<std::string>{"start", "ratio", "count", "signs"}));
  EXPECT_EQ(Strings(geo.at("required")), (std::set<std::string>{"start", "ratio", "count"}));
  EXPECT_EQ(axis.at("properties").at("values").at("maxItems"), kMaxRunsPerSubmission);
  EXPECT_EQ(geo.at("properties").at("count").at("maximum"), kMaxRunsPerSubmission);
  EXPECT_EQ(defs_.at("sweep").at("x-max-points"), kMaxRunsPerSubmission);
  EXPECT_EQ(defs_.at("campaign").at("x-max-points"), kMaxRunsPerSubmission);
  EXPECT_EQ(defs_.at("sweep").at("properties").at("axes").at("maxItems"), kAllParams.size());

  // Each key the schema lists is one the parser takes, and one more is refused.
  json sweep = {{"name", "s"},
                {"scale", "smoke"},
                {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", 80}, {"duration_s", 1}}}};
  for (const json& a :
       {json{{"param", "Omega"}, {"values", {80}}},
        json{{"param", "Omega"}, {"range", {{"from", 10}, {"to", 20}, {"step", 10}}}},
        json{{"param", "Omega"}, {"geometric", {{"start", 10}, {"ratio", 2}, {"count", 2}, {"signs", {-1, 1}}}}}}) {
    json s = sweep;
    s["axes"] = json::array({a});
    EXPECT_TRUE(ParseSweep(s).ok()) << a.dump();
    s["axes"][0]["extra"] = 1;
    EXPECT_EQ(ParseSweep(s).status().field(), "axes[0].extra") << a.dump();
  }
  // Values past the per-axis cap are refused.
  json s = sweep;
  s["axes"] = json::array({{{"param", "Omega"}, {"values", std::vector<double>(kMaxRunsPerSubmission + 1, 80)}}});
  EXPECT_EQ(ParseSweep(s).status().code(), StatusCode::kResourceExhausted);
  s["axes"] = json::array({{{"param", "Omega"}, {"values", std::vector<double>(kMaxRunsPerSubmission, 80)}}});
  EXPECT_TRUE(ParseSweep(s).ok());
}

TEST_F(SweepSchemaTest, MaterialBoundsAreTheParsersBounds) {
  for (const MaterialField& m : MaterialFields()) {
    const std::string name(m.name);
    ASSERT_TRUE(defs_.contains(name)) << name;
    const json& d = defs_.at(name);
    EXPECT_EQ(d.at("x-role"), m.role == MaterialRole::kBed ? "bed" : "drive") << name;
    EXPECT_EQ(LoadSchema("campaign.schema.json").at("$defs").at(name), d) << name;
    switch (m.bound) {
      case MaterialField::Bound::kPositive:
        EXPECT_EQ(d.at("exclusiveMinimum").get<double>(), 0) << name;
        EXPECT_EQ(d.at("maximum").get<double>(), m.cap) << name;
        break;
      case MaterialField::Bound::kFriction:
        EXPECT_EQ(d.at("minimum").get<double>(), 0) << name;
        EXPECT_EQ(d.at("maximum").get<double>(), m.cap) << name;
        break;
      case MaterialField::Bound::kRestitution:
        EXPECT_EQ(d.at("exclusiveMinimum").get<double>(), 0) << name;
        EXPECT_EQ(d.at("maximum").get<double>(), 1) << name;
        break;
      case MaterialField::Bound::kPoisson:
        EXPECT_EQ(d.at("exclusiveMinimum").get<double>(), 0) << name;
        EXPECT_EQ(d.at("exclusiveMaximum").get<double>(), 0.5) << name;
        break;
    }
  }
}

TEST_F(SweepSchemaTest, PointCapsAreThePointCaps) {
  EXPECT_EQ(defs_.at("A").at("maximum").get<double>(), kMaxAmplitudeM);
  EXPECT_EQ(defs_.at("A").at("exclusiveMinimum").get<double>(), 0);
  EXPECT_EQ(defs_.at("f").at("maximum").get<double>(), kMaxFrequencyHz);
  EXPECT_EQ(defs_.at("f").at("minimum").get<double>(), kMinFrequencyHz);
  for (const char* w : {"Omega", "omega"}) {
    EXPECT_EQ(defs_.at(w).at("maximum").get<double>(), kMaxAngularVelocity) << w;
    EXPECT_EQ(defs_.at(w).at("minimum").get<double>(), -kMaxAngularVelocity) << w;
  }
  EXPECT_EQ(defs_.at("duration_s").at("maximum").get<double>(), kMaxDurationS);
  EXPECT_EQ(defs_.at("duration_s").at("minimum").get<double>(), kMinDurationS);
  EXPECT_EQ(defs_.at("name").at("maxLength"), kMaxNameLength);
  EXPECT_EQ(defs_.at("name").at("pattern"), "^(?!\\.\\.?$)[A-Za-z0-9._-]+$") << "CheckName refuses . and ..";
  EXPECT_EQ(defs_.at("description").at("maxLength"), kMaxDescriptionLength);

  std::set<std::string> scales;
  for (const auto& sc : AllScales()) scales.insert(std::string(sc.name));
  EXPECT_EQ(Strings(defs_.at("scale").at("enum")), scales);
  std::set<std::string> axes;
  for (RotationAxis a : {RotationAxis::kX, RotationAxis::kY, RotationAxis::kZ, RotationAxis::kXZ})
    axes.insert(std::string(AxisName(a)));
  EXPECT_EQ(Strings(defs_.at("axis").at("enum")), axes);
  EXPECT_EQ(Strings(defs_.at("sweep").at("properties").at("combine").at("enum")),
            (std::set<std::string>{"product", "zip"}));

  // The caps bite exactly where the schema says.
  json sweep = {{"name", std::string(kMaxNameLength, 'n')},
                {"scale", "paper"},
                {"description", std::string(kMaxDescriptionLength, 'd')},
                {"base",
                 {{"mode", "oscillatory"},
                  {"A", kMaxAmplitudeM * 0.41},
                  {"f", kMaxFrequencyHz},
                  {"Omega", -kMaxAngularVelocity},
                  {"duration_s", kMaxDurationS}}}};
  EXPECT_TRUE(ParseSweep(sweep).ok()) << ParseSweep(sweep).status().ToString();
  json over = sweep;
  over["name"] = std::string(kMaxNameLength + 1, 'n');
  EXPECT_EQ(ParseSweep(over).status().field(), "name");
  over = sweep;
  over["description"] = std::string(kMaxDescriptionLength + 1, 'd');
  EXPECT_EQ(ParseSweep(over).status().field(), "description");
  for (const char* f : {"f", "duration_s"}) {
    over = sweep;
    over["base"][f] = over["base"][f].get<double>() * 1.000001;
    EXPECT_EQ(ParseSweep(over).status().field(), std::string("base.") + f);
  }
  over = sweep;
  over["base"]["Omega"] = -kMaxAngularVelocity * 1.000001;
  EXPECT_EQ(ParseSweep(over).status().field(), "base.Omega");
}

// The precision target's keys, bounds and required key are the ones core/precision.cc takes.
TEST_F(SweepSchemaTest, PrecisionTargetIsTheOneCxxTakes) {
  const json& p = defs_.at("precision");
  EXPECT_EQ(Keys(p), (std::set<std::string>{"uz_rel", "uz_abs", "min_periods", "max_duration_s"}));
  EXPECT_EQ(Strings(p.at("required")), (std::set<std::string>{"max_duration_s"}));
  EXPECT_EQ(p.at("properties").at("min_periods").at("minimum"), kMinPrecisionPeriods);
  EXPECT_EQ(p.at("properties").at("min_periods").at("maximum"), kMaxPrecisionPeriods);
  EXPECT_EQ(p.at("properties").at("uz_rel").at("maximum").get<double>(), kMaxPrecisionRel);
  EXPECT_EQ(p.at("properties").at("uz_abs").at("maximum").get<double>(), kMaxPrecisionAbs);
  EXPECT_EQ(p.at("properties").at("max_duration_s").at("maximum").get<double>(), kMaxDurationS);
  EXPECT_EQ(LoadSchema("campaign.schema.json").at("$defs").at("precision"), p);
}

// replicates: an integer from 1 to kMaxReplicates, as core/sweep.cc takes it.
TEST_F(SweepSchemaTest, ReplicatesAreTheOnesCxxTakes) {
  const json& r = defs_.at("replicates");
  EXPECT_EQ(r.at("type"), "integer");
  EXPECT_EQ(r.at("minimum"), 1);
  EXPECT_EQ(r.at("maximum"), kMaxReplicates);
  json sweep = {{"name", "r"},
                {"scale", "smoke"},
                {"base", {{"mode", "vibration"}, {"A", 0.03}, {"f", 3}, {"duration_s", 1}}},
                {"replicates", kMaxReplicates}};
  EXPECT_TRUE(ParseSweep(sweep).ok());
  sweep["replicates"] = kMaxReplicates + 1;
  EXPECT_EQ(ParseSweep(sweep).status().field(), "replicates");
}

TEST_F(SweepSchemaTest, SweepAndCampaignFieldsAreTheOnesCxxTakes) {
  const json& sweep_schema = defs_.at("sweep");
  EXPECT_EQ(Keys(sweep_schema), (std::set<std::string>{"name", "scale", "description", "base", "axes", "combine",
                                                       "force", "precision", "replicates", "snapshots", "numerics"}));
  EXPECT_EQ(Strings(sweep_schema.at("required")), (std::set<std::string>{"name", "scale", "base"}));
  json full = {{"name", "s"},           {"scale", "smoke"},
               {"description", "d"},    {"base", {{"mode", "vibration"}, {"A", 0.03}, {"f", 3}, {"duration_s", 1}}},
               {"axes", json::array()}, {"combine", "zip"},
               {"force", false},        {"precision", {{"uz_rel", 0.1}, {"max_duration_s", 2}}}};
  EXPECT_TRUE(ParseSweep(full).ok());
  for (const auto& f : Strings(sweep_schema.at("required"))) {
    json missing = full;
    missing.erase(f);
    EXPECT_EQ(ParseSweep(missing).status().field(), f);
  }

  const json& cs = defs_.at("campaign_sweep");
  std::set<std::string> in_campaign = Keys(sweep_schema);
  in_campaign.erase("scale");
  in_campaign.erase("force");
  EXPECT_EQ(Keys(cs), in_campaign);

  const json& campaign = defs_.at("campaign");
  EXPECT_EQ(Keys(campaign), (std::set<std::string>{"name", "description", "scale", "schedule", "drift_tolerance_mps",
                                                   "precision", "replicates", "snapshots", "numerics", "sweeps", "claims", "adaptive"}));
  EXPECT_EQ(Strings(campaign.at("required")), (std::set<std::string>{"name", "description", "scale", "sweeps"}));
  json c = {{"name", "c"},
            {"description", "d"},
            {"scale", "smoke"},
            {"schedule", "30 1 * * 1-5"},
            {"drift_tolerance_mps", 0},
            {"sweeps", json::array({full})}};
  c["sweeps"][0].erase("scale");
  c["sweeps"][0].erase("force");
  auto parsed = ParseCampaign(c);
  EXPECT_TRUE(parsed.ok()) << parsed.status().ToString();
  for (const auto& f : Strings(campaign.at("required"))) {
    json missing = c;
    missing.erase(f);
    EXPECT_EQ(ParseCampaign(missing).status().field(), f);
  }

  // The two other submission forms are parsed by the daemon (server/jobs/submission.cc); here, only
  // that they are built from the same pieces.
  const json& sub = defs_.at("campaign_submission");
  EXPECT_EQ(Keys(sub), (std::set<std::string>{"campaign", "scale", "force"}));
  EXPECT_EQ(sub.at("properties").at("campaign").at("$ref"), "#/$defs/name");
  EXPECT_EQ(sub.at("properties").at("scale").at("$ref"), "#/$defs/scale");
  const json& many = defs_.at("sweeps_submission");
  EXPECT_EQ(Keys(many), (std::set<std::string>{"sweeps", "force"}));
  EXPECT_EQ(many.at("properties").at("sweeps").at("items").at("$ref"), "#/$defs/sweep");
  EXPECT_EQ(many.at("x-max-points"), kMaxRunsPerSubmission);
}

// Claims (core/claims.h): the fields, the rule kinds and each kind's parameters are the ones the
// parser takes.
TEST_F(SweepSchemaTest, ClaimRulesAreTheOnesCxxTakes) {
  const json& claim = defs_.at("claim");
  EXPECT_EQ(Keys(claim), (std::set<std::string>{"id", "title", "source", "paper", "rule"}));
  EXPECT_EQ(Strings(claim.at("required")), Keys(claim));
  std::set<std::string> kinds;
  for (const json& rule : defs_.at("claim_rule").at("oneOf")) {
    const std::string kind = rule.at("properties").at("kind").at("const").get<std::string>();
    kinds.insert(kind);
    std::set<std::string> params = Keys(rule);
    params.erase("kind");
    const std::vector<std::string> cxx = ClaimRuleParams(kind);
    EXPECT_EQ(params, std::set<std::string>(cxx.begin(), cxx.end())) << kind;
    std::set<std::string> required = Strings(rule.at("required"));
    required.erase("kind");
    const std::vector<std::string> cxx_required = ClaimRuleParams(kind, /*required_only=*/true);
    EXPECT_EQ(required, std::set<std::string>(cxx_required.begin(), cxx_required.end())) << kind;
  }
  const std::vector<std::string> cxx_kinds = ClaimKinds();
  EXPECT_EQ(kinds, std::set<std::string>(cxx_kinds.begin(), cxx_kinds.end()));
}

TEST_F(SweepSchemaTest, CampaignSchemaSharesTheDefinitions) {
  json campaign_schema = LoadSchema("campaign.schema.json");
  EXPECT_EQ(campaign_schema.at("$schema"), schema_.at("$schema"));
  EXPECT_EQ(campaign_schema.at("$ref"), "#/$defs/campaign");
  for (const auto& [name, def] : campaign_schema.at("$defs").items()) EXPECT_EQ(def, defs_.at(name)) << name;
}

}  // namespace
}  // namespace sandswim
