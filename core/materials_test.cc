#include "core/materials.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <set>

#include "core/cost.h"
#include "core/deck.h"
#include "core/keys.h"
#include "core/sweep.h"

namespace sandswim {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;
using ::testing::Not;

const Scale& SmokeScale() { return *FindScale("smoke"); }

// The baseline rising drive at smoke with `extra` fields in its base and `axes`.
json Sweep(const json& extra, const json& axes = json::array()) {
  json j = json::parse(R"({"name": "m", "scale": "smoke",
     "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 1}})");
  for (const auto& [k, v] : extra.items()) j["base"][k] = v;
  if (!axes.empty()) j["axes"] = axes;
  return j;
}

Result<Plan> PlanOf(const json& j) {
  auto s = ParseSweep(j);
  if (!s.ok()) return s.status();
  return PlanSweeps({*s}, *FindScale(s->scale), "e");
}

TEST(MaterialsTest, DefaultsAreTable1AndLeaveEverythingAsItWas) {
  const Materials m;
  EXPECT_EQ(m.d_grain, 0.02);
  EXPECT_EQ(m.rho_grain, 2500);
  EXPECT_EQ(m.d_so, 0.12);
  EXPECT_EQ(m.rho_so, 2500);
  EXPECT_EQ(m.youngs, 1e7);
  EXPECT_EQ(m.poisson, 0.25);
  EXPECT_EQ(m.e_grain_grain, 0.9);
  EXPECT_EQ(m.e_so_grain, 0.5);
  EXPECT_EQ(m.mu_grain_grain, 0.45);
  EXPECT_EQ(m.mu_so_grain, 0.5);
  // A base that names Table 1's values is the same point, the same decks and the same key as one
  // that names none.
  json table1 = {{"so_density", 2500},       {"so_diameter", 0.12},     {"so_friction", 0.5},
                 {"so_restitution", 0.5},    {"grain_diameter", 0.02},  {"grain_density", 2500},
                 {"grain_friction", 0.45},   {"grain_restitution", 0.9}, {"grain_youngs", 1e7},
                 {"grain_poisson", 0.25}};
  auto plain = PlanOf(Sweep(json::object()));
  auto named = PlanOf(Sweep(table1));
  ASSERT_TRUE(plain.ok() && named.ok()) << named.status().ToString();
  EXPECT_EQ(plain->runs[0].key, named->runs[0].key);
  EXPECT_EQ(plain->beds[0].key, named->beds[0].key);
  EXPECT_EQ(plain->beds[0].deck, RenderBedDeck(SmokeScale()));
  EXPECT_EQ(PointToJson(named->runs[0].point), PointToJson(plain->runs[0].point));
  EXPECT_FALSE(PlannedRunToJson(plain->runs[0]).contains("dt_s"));
  EXPECT_THAT(plain->runs[0].deck, Not(HasSubstr("Materials not Table 1's")));
}

TEST(MaterialsTest, EveryFieldParsesAndIsAnAxis) {
  for (const MaterialField& f : MaterialFields()) {
    const std::string name(f.name);
    const double v = kTable1.*f.member;
    // A value a little below Table 1's is inside every bound (and keeps the SO larger than a grain).
    const double other = v * 0.9;
    auto s = ParseSweep(Sweep({{name, other}}));
    ASSERT_TRUE(s.ok()) << name << ": " << s.status().ToString();
    EXPECT_EQ(s->base.materials.*f.member, other) << name;
    EXPECT_EQ(PointToJson(s->base)[name], other) << name;
    auto axis = ParseSweep(Sweep(json::object(), {{{"param", name}, {"values", {v, other}}}}));
    ASSERT_TRUE(axis.ok()) << name << ": " << axis.status().ToString();
    auto points = ExpandSweep(*axis);
    ASSERT_TRUE(points.ok()) << name << ": " << points.status().ToString();
    ASSERT_EQ(points->size(), 2u);
    EXPECT_EQ((*points)[1].materials.*f.member, other) << name;
  }
}

TEST(MaterialsTest, RangeGeometricAndZipWorkAsForTheDrive) {
  auto s = ParseSweep(Sweep(json::object(), {{{"param", "so_density"}, {"range", {{"from", 1250}, {"to", 7500}, {"step", 1250}}}},
                                             {{"param", "so_friction"}, {"geometric", {{"start", 0.1}, {"ratio", 2}, {"count", 6}}}}}));
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  auto product = ExpandSweep(*s);
  ASSERT_TRUE(product.ok()) << product.status().ToString();
  EXPECT_EQ(product->size(), 36u);
  EXPECT_EQ(product->back().materials.rho_so, 7500);
  EXPECT_EQ(product->back().materials.mu_so_grain, 3.2);
  s->combine = Combine::kZip;
  auto zip = ExpandSweep(*s);
  ASSERT_TRUE(zip.ok()) << zip.status().ToString();
  ASSERT_EQ(zip->size(), 6u);
  EXPECT_EQ((*zip)[2].materials.rho_so, 3750);
  EXPECT_EQ((*zip)[2].materials.mu_so_grain, 0.4);
}

TEST(MaterialsTest, PhysicalBoundsNameTheField) {
  struct Case {
    const char* field;
    double value;
    const char* says;
  };
  const Case cases[] = {
      {"so_density", 0, "> 0"},           {"so_density", -1, "> 0"},
      {"grain_density", 2e5, "<= 100000"}, {"so_diameter", 0, "> 0"},
      {"grain_diameter", 0.2, "<= 0.1"},   {"grain_youngs", 0, "> 0"},
      {"so_restitution", 0, "(0, 1]"},     {"grain_restitution", 1.01, "(0, 1]"},
      {"so_friction", -0.1, "[0, 10]"},    {"grain_friction", 11, "[0, 10]"},
      {"grain_poisson", 0, "(0, 0.5)"},    {"grain_poisson", 0.5, "(0, 0.5)"},
      {"so_diameter", 0.01, "at least a grain across"},
  };
  for (const Case& c : cases) {
    auto s = ParseSweep(Sweep({{c.field, c.value}}));
    ASSERT_FALSE(s.ok()) << c.field << " = " << c.value;
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument);
    EXPECT_EQ(s.status().field(), std::string("base.") + c.field) << s.status().ToString();
    EXPECT_THAT(s.status().reason(), HasSubstr(c.says)) << s.status().ToString();
    // The same value on an axis names the axis' value.
    auto axis = ParseSweep(Sweep(json::object(), {{{"param", c.field}, {"values", {c.value}}}}));
    ASSERT_FALSE(axis.ok());
    EXPECT_EQ(axis.status().field(), "axes[0].values[0]") << axis.status().ToString();
  }
  // Friction 0 and restitution 1 are allowed.
  EXPECT_TRUE(ParseSweep(Sweep({{"so_friction", 0}, {"grain_restitution", 1}})).ok());
  auto text = ParseSweep(Sweep({{"so_density", "5000"}}));
  ASSERT_FALSE(text.ok());
  EXPECT_EQ(text.status().field(), "base.so_density");
}

TEST(MaterialsTest, ADensitySweepOfTheSoPlansOneBed) {
  auto plan = PlanOf(Sweep(json::object(), {{{"param", "so_density"}, {"values", {1250, 2500, 5000, 7500}}},
                                            {{"param", "so_friction"}, {"values", {0.3, 0.5}}},
                                            {{"param", "so_restitution"}, {"values", {0.3, 0.5}}}}));
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->runs.size(), 16u);
  ASSERT_EQ(plan->beds.size(), 1u);
  EXPECT_EQ(plan->beds[0].deck, RenderBedDeck(SmokeScale()));  // Table 1's bed, shared with the paper's points
  std::set<std::string> keys;
  for (const PlannedRun& r : plan->runs) {
    EXPECT_EQ(r.bed, 0);
    keys.insert(r.key);
  }
  EXPECT_EQ(keys.size(), 16u);
  // The drive deck sets the density after read_restart, and the SO-grain pair's coefficients.
  const PlannedRun& heavy = plan->runs.back();
  ASSERT_EQ(heavy.point.materials.rho_so, 7500);
  EXPECT_THAT(heavy.deck, HasSubstr("group so type 2\nset group so density 7500\n"));
  EXPECT_LT(heavy.deck.find("read_restart"), heavy.deck.find("set group so density"));
  EXPECT_THAT(heavy.deck, HasSubstr("coefficientRestitution peratomtypepair 2 0.9 0.5 0.5 0.5"));
  const PlannedRun& slick = plan->runs[12];  // 7500, 0.3, 0.3
  EXPECT_THAT(slick.deck, HasSubstr("coefficientFriction peratomtypepair 2 0.45 0.3 0.3 0.3"));
  EXPECT_THAT(slick.deck, HasSubstr("coefficientRestitution peratomtypepair 2 0.9 0.3 0.3 0.3"));
  EXPECT_THAT(slick.deck, HasSubstr("# Materials not Table 1's: so_density 7500 kg/m^3 (drive), so_friction 0.3 "
                                    "(drive), so_restitution 0.3 (drive).\n"));
}

TEST(MaterialsTest, BedParametersPourBedsOfTheirOwnAndShareThem) {
  // Two grain sizes x two SO densities x two replicates: two bed materials, four beds; each bed
  // holds the runs of both densities.
  json j = Sweep(json::object(), {{{"param", "grain_diameter"}, {"values", {0.02, 0.025}}},
                                  {{"param", "so_density"}, {"values", {2500, 5000}}}});
  j["replicates"] = 2;
  auto plan = PlanOf(j);
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  ASSERT_EQ(plan->beds.size(), 4u);
  EXPECT_EQ(plan->runs.size(), 8u);
  EXPECT_EQ(plan->beds[0].deck, RenderBedDeck(SmokeScale(), 0));
  EXPECT_EQ(plan->beds[1].deck, RenderBedDeck(SmokeScale(), 1));
  EXPECT_EQ(plan->beds[2].materials.d_grain, 0.025);
  EXPECT_EQ(plan->beds[2].replicate, 0);
  EXPECT_THAT(plan->beds[2].deck, HasSubstr("radius constant 0.0125"));
  EXPECT_THAT(plan->beds[2].deck, HasSubstr("# Materials not Table 1's: grain_diameter 0.025 m (bed).\n"));
  std::set<std::string> bed_keys;
  for (const PlannedBed& b : plan->beds) bed_keys.insert(b.key);
  EXPECT_EQ(bed_keys.size(), 4u);
  std::map<int, int> runs_per_bed;
  for (const PlannedRun& r : plan->runs) {
    ++runs_per_bed[r.bed];
    EXPECT_EQ(plan->beds[r.bed].replicate, r.replicate);
    EXPECT_EQ(plan->beds[r.bed].materials, BedMaterials(r.point.materials));
    EXPECT_EQ(r.key, RunKey(r.deck, plan->beds[r.bed].key, "e"));
  }
  EXPECT_EQ(runs_per_bed, (std::map<int, int>{{0, 2}, {1, 2}, {2, 2}, {3, 2}}));
  // Every bed parameter changes the bed deck; no drive parameter does.
  for (const MaterialField& f : MaterialFields()) {
    Materials m;
    m.*f.member = kTable1.*f.member * 0.9;
    const bool changes = RenderBedDeck(SmokeScale(), 0, m) != RenderBedDeck(SmokeScale());
    EXPECT_EQ(changes, f.role == MaterialRole::kBed) << f.name;
  }
}

TEST(MaterialsTest, TimeStepRule) {
  EXPECT_EQ(TimeStep(kTable1), 1e-5);
  // Rayleigh time of Table 1's grain: 8.56e-4 s; the paper's step is 1.2 % of it.
  EXPECT_NEAR(RayleighTime(0.02, 2500, 1e7, 0.25), 8.56e-4, 0.01e-4);
  Materials stiff;
  stiff.youngs = 1e8;  // T_R / sqrt(10)
  EXPECT_EQ(TimeStep(stiff), 3.1e-6);
  Materials small;
  small.d_grain = 0.015;  // 0.75 T_R, rounded down to two digits
  EXPECT_EQ(TimeStep(small), 7.5e-6);
  Materials light;
  light.rho_grain = 1000;
  EXPECT_EQ(TimeStep(light), 6.3e-6);
  Materials soft;  // softer, larger, heavier: the paper's step is the ceiling
  soft.youngs = 1e6;
  soft.d_grain = 0.03;
  soft.rho_grain = 8000;
  EXPECT_EQ(TimeStep(soft), 1e-5);
  Materials feather_so;  // the SO's own Rayleigh time counts: a very light SO
  feather_so.rho_so = 10;
  EXPECT_LT(TimeStep(feather_so), 1e-5);
  EXPECT_LE(TimeStep(small), 0.75 * 1e-5);
}

TEST(MaterialsTest, TheStepIsInTheDecksAndTheCostModelCountsIt) {
  auto table1 = PlanOf(Sweep(json::object()));
  auto stiff = PlanOf(Sweep({{"grain_youngs", 1e8}}));
  ASSERT_TRUE(table1.ok() && stiff.ok()) << stiff.status().ToString();
  const PlannedRun& r = stiff->runs[0];
  EXPECT_THAT(r.deck, HasSubstr("timestep        3.1e-06\n"));
  EXPECT_THAT(r.deck, HasSubstr("# Time step 3.1e-06 s: " + std::string(kTimeStepRule) + ".\n"));
  EXPECT_THAT(stiff->beds[0].deck, HasSubstr("timestep        3.1e-06\n"));
  EXPECT_EQ(DriveFacts(r.point, SmokeScale()).dt, 3.1e-6);
  EXPECT_EQ(PlannedRunToJson(r)["dt_s"], 3.1e-6);
  // The same physical time in more steps, up to whole chunks of 100 steps.
  const double t = table1->runs[0].run_duration_s;
  EXPECT_EQ(r.run_duration_s, t);
  EXPECT_EQ(table1->runs[0].steps, std::llround(t / 1e-5));
  EXPECT_EQ(r.steps, (std::llround(t / 3.1e-6) + 99) / 100 * 100);
  // The bed's phases keep their physical times.
  EXPECT_THAT(stiff->beds[0].deck, HasSubstr("thermo          3226\n"));
  const PlanCost c1 = CostOfPlan(*table1, {}, DefaultRate(), DefaultBedRate());
  const PlanCost c2 = CostOfPlan(*stiff, {}, DefaultRate(), DefaultBedRate());
  EXPECT_NEAR(c2.particle_steps / c1.particle_steps, 1e-5 / 3.1e-6, 0.001);
  EXPECT_NEAR(c2.bed_core_s / c1.bed_core_s, 1e-5 / 3.1e-6, 1e-9);
}

TEST(MaterialsTest, TheBoxFollowsTheSoAndTheGrains) {
  const Scale& smoke = SmokeScale();
  const Box same = BoxFor(smoke, kTable1);
  EXPECT_EQ(same.x_len, smoke.x_len);
  EXPECT_EQ(same.y_len, smoke.y_len);
  EXPECT_EQ(same.z_floor, smoke.z_floor);
  EXPECT_EQ(same.z_bed_top, smoke.z_bed_top);
  EXPECT_DOUBLE_EQ(same.max_amplitude, smoke.max_amplitude());
  Materials big;
  big.d_so = 0.18;
  big.d_grain = 0.025;
  const Box b = BoxFor(smoke, big);
  // d_SO + 3 d_grain grew by 0.075 m: so did L_x and L_y, and the largest A stays.
  EXPECT_NEAR(b.x_len, 0.255, 1e-12);
  EXPECT_NEAR(b.y_len, 0.455, 1e-12);
  EXPECT_NEAR(b.max_amplitude, smoke.max_amplitude(), 1e-12);
  EXPECT_GE(b.x_len, big.d_so + 3 * big.d_grain - 1e-12);
  // The SO's radius grew by 0.03 m: so did the room above and below it.
  EXPECT_NEAR(b.z_floor, smoke.z_floor - 0.03, 1e-12);
  EXPECT_NEAR(b.z_bed_top, smoke.z_bed_top + 0.03, 1e-12);
  Point p = OscillatoryPoint(0.10, 3, -80, 1);
  p.materials = big;
  EXPECT_TRUE(FitsScale(p, smoke).ok());
  const std::string deck = RenderDriveDeck(p, smoke, std::nullopt);
  EXPECT_THAT(deck, HasSubstr("zplane -0.38\n"));
  EXPECT_THAT(deck, HasSubstr("variable z_floor_stop equal -0.265\n"));  // -0.38 + 0.09 + 0.025
  EXPECT_EQ(DriveFacts(p, smoke).z_floor, -0.38);
  EXPECT_THAT(RenderBedDeck(smoke, 0, big), HasSubstr("region          domain block -0.1275 0.1275 -0.2275 0.2275 -0.38 "));
  // A smaller SO keeps the scale's box.
  Materials small;
  small.d_so = 0.08;
  EXPECT_EQ(BoxFor(smoke, small).x_len, smoke.x_len);
  EXPECT_GT(BoxFor(smoke, small).max_amplitude, smoke.max_amplitude());
}

TEST(MaterialsTest, CapsOnGrainsAndStepNameTheFieldAndAScale) {
  EXPECT_EQ(EstimatedGrains(SmokeScale()), 6682);
  Materials fine;
  fine.d_grain = 0.014;  // (0.02 / 0.014)^3 = 2.9 x the grains
  EXPECT_NEAR(EstimatedGrains(SmokeScale(), fine) / 6682, 2.9, 0.05);
  auto smoke_fine = ParseSweep(Sweep({{"grain_diameter", 0.012}}));
  ASSERT_FALSE(smoke_fine.ok());
  EXPECT_EQ(smoke_fine.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(smoke_fine.status().field(), "base.grain_diameter");
  EXPECT_THAT(smoke_fine.status().reason(), HasSubstr("scale 'smoke' runs at most 20000"));
  EXPECT_THAT(smoke_fine.status().reason(), HasSubstr("scale 'paper' takes it"));
  json at_paper = Sweep({{"grain_diameter", 0.012}});
  at_paper["scale"] = "paper";
  EXPECT_TRUE(ParseSweep(at_paper).ok());
  auto too_fine = ParseSweep(Sweep({{"grain_diameter", 0.005}}));
  ASSERT_FALSE(too_fine.ok());
  EXPECT_THAT(too_fine.status().reason(), HasSubstr("no scale runs it"));
  auto big_so = ParseSweep(Sweep({{"so_diameter", 0.6}}));
  ASSERT_FALSE(big_so.ok());
  EXPECT_EQ(big_so.status().field(), "base.so_diameter") << big_so.status().ToString();
  // A step shorter than any scale runs names the parameter that shortens it most.
  auto stiff = ParseSweep(Sweep({{"grain_youngs", 1e9}, {"grain_density", 2000}}));
  ASSERT_FALSE(stiff.ok());
  EXPECT_EQ(stiff.status().field(), "base.grain_youngs");
  EXPECT_THAT(stiff.status().reason(), HasSubstr("no scale runs steps shorter than 2e-06 s"));
  auto on_axis = ParseSweep(Sweep(json::object(), {{{"param", "grain_youngs"}, {"values", {1e7, 1e10}}}}));
  ASSERT_FALSE(on_axis.ok());
  EXPECT_EQ(on_axis.status().field(), "axes[0].values[1]");
}

}  // namespace
}  // namespace sandswim

namespace sandswim {
namespace {

TEST(MaterialsTest, TheDensityRatioCampaignIsBuiltInAndPoursOneBed) {
  auto c = BuiltinCampaign("density-ratio");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->scale, "smoke");
  ASSERT_EQ(c->sweeps.size(), 2u);
  auto plan = PlanSweeps(c->sweeps, *FindScale(c->scale), "e");
  ASSERT_TRUE(plan.ok()) << plan.status().ToString();
  EXPECT_EQ(plan->runs.size(), 12u);
  ASSERT_EQ(plan->beds.size(), 1u);
  EXPECT_EQ(plan->beds[0].deck, RenderBedDeck(*FindScale("smoke")));
  std::set<double> ratios;
  for (const PlannedRun& r : plan->runs) ratios.insert(r.point.materials.rho_so / r.point.materials.rho_grain);
  EXPECT_EQ(ratios, (std::set<double>{0.5, 0.75, 1, 1.5, 2, 3}));
}

// Labels for people name the fields that are not Table 1's, with units, and the API lists every
// field with its Table 1 value for a client that must show one where a row has none.
TEST(MaterialsTest, LabelsNameWhatIsNotTable1AndTheApiListsEveryField) {
  Materials m;
  EXPECT_EQ(MaterialsLabel(m), "");
  m.rho_so = 5000;
  m.mu_grain_grain = 0.3;
  EXPECT_EQ(MaterialsLabel(m), "so_density = 5000 kg/m^3, grain_friction = 0.3");
  EXPECT_EQ(MaterialsLabel(m, "so_density"), "grain_friction = 0.3");
  const json fields = MaterialFieldsJson();
  ASSERT_EQ(fields.size(), kMaterialFieldCount);
  EXPECT_EQ(fields[0]["name"], "so_density");
  EXPECT_EQ(fields[0]["unit"], "kg/m^3");
  EXPECT_EQ(fields[0]["role"], "drive");
  EXPECT_EQ(fields[0]["table1"].get<double>(), Materials().rho_so);
  for (const json& f : fields) {
    const MaterialField* known = FindMaterialField(f["name"].get<std::string>());
    ASSERT_NE(known, nullptr) << f;
    EXPECT_EQ(f["table1"].get<double>(), Materials().*known->member) << f;
  }
}

}  // namespace
}  // namespace sandswim
