#include "core/deck.h"

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

std::string GoldenPath(const std::string& name) { return std::string(SANDSWIM_SOURCE_DIR) + "/tests/golden/" + name; }

// Compares with tests/golden/<name>; SANDSWIM_UPDATE_GOLDEN=1 rewrites the file instead and fails,
// so a run with it set never passes (review the diff, then run again without it: a changed deck
// changes every content key, so bump kTemplateVersion).
void ExpectGolden(const std::string& name, const std::string& text) {
  if (std::getenv("SANDSWIM_UPDATE_GOLDEN")) {
    std::ofstream(GoldenPath(name), std::ios::binary) << text;
    ADD_FAILURE() << "rewrote " << GoldenPath(name)
                  << ": review the diff, then run again without SANDSWIM_UPDATE_GOLDEN";
    return;
  }
  std::ifstream in(GoldenPath(name), std::ios::binary);
  ASSERT_TRUE(in) << "missing golden file " << GoldenPath(name);
  std::stringstream ss;
  ss << in.rdbuf();
  EXPECT_EQ(ss.str(), text) << "deck differs from " << GoldenPath(name);
}

const Scale& Smoke() { return *FindScale("smoke"); }

TEST(FormatNumberTest, ShortestRoundTrip) {
  EXPECT_EQ(FormatNumber(0.03), "0.03");
  EXPECT_EQ(FormatNumber(-80), "-80");
  EXPECT_EQ(FormatNumber(1e-5), "1e-05");
  EXPECT_EQ(FormatNumber(1e7), "1e+07");
  EXPECT_EQ(FormatNumber(2500), "2500");
  EXPECT_EQ(FormatNumber(-0.0), "0");
  EXPECT_EQ(FormatNumber(0.1 + 0.2), "0.30000000000000004");  // exact, never rounded away
}

TEST(DeckTest, BedDeckMatchesGolden) { ExpectGolden("bed_smoke.in", RenderBedDeck(Smoke())); }

TEST(DeckTest, DriveDeckMatchesGolden) {
  ExpectGolden("drive_oscillatory_smoke.in",
               RenderDriveDeck(OscillatoryPoint(0.03, 3, -80, 4), Smoke(), Smoke().default_precision));
}

TEST(DeckTest, VibrationRotationDeckMatchesGolden) {
  Point p;
  p.mode = Mode::kVibrationRotation;
  p.A = 0.03;
  p.f = 3;
  p.omega = 80;
  p.axis = RotationAxis::kXZ;
  p.duration_s = 4;
  ExpectGolden("drive_vibration_rotation_xz_paper.in", RenderDriveDeck(p, *FindScale("paper"), std::nullopt));
}

// A point of other materials, of each kind (core/materials.h): one that pours a bed of its own
// (larger, stiffer grains and a larger SO: a grown box, a shorter step, the header saying both),
// and one that only changes the drive (a denser, slicker SO on Table 1's bed).
Point BedChangingPoint() {
  Point p = OscillatoryPoint(0.03, 3, -80, 4);
  p.materials.d_grain = 0.025;
  p.materials.youngs = 3e7;
  p.materials.d_so = 0.15;
  return p;
}
Point DriveOnlyPoint() {
  Point p = OscillatoryPoint(0.03, 3, -80, 4);
  p.materials.rho_so = 5000;
  p.materials.mu_so_grain = 0.3;
  p.materials.e_so_grain = 0.7;
  return p;
}

TEST(DeckTest, BedChangingMaterialsMatchGolden) {
  const Point p = BedChangingPoint();
  ASSERT_TRUE(Validate(p).ok());
  ASSERT_TRUE(FitsScale(p, Smoke()).ok());
  ExpectGolden("bed_smoke_materials.in", RenderBedDeck(Smoke(), 0, p.materials));
  ExpectGolden("drive_oscillatory_smoke_materials.in", RenderDriveDeck(p, Smoke(), Smoke().default_precision));
}

TEST(DeckTest, DriveOnlyMaterialsMatchGoldenOnTable1sBed) {
  const Point p = DriveOnlyPoint();
  ASSERT_TRUE(Validate(p).ok());
  EXPECT_EQ(RenderBedDeck(Smoke(), 0, p.materials), RenderBedDeck(Smoke()));
  ExpectGolden("drive_oscillatory_smoke_so_density.in", RenderDriveDeck(p, Smoke(), Smoke().default_precision));
}

// Table 1 of the paper, as the decks must state it, whatever the scale.
TEST(DeckTest, EveryDeckHoldsTableOne) {
  for (const Scale& s : AllScales()) {
    for (const std::string& deck :
         {RenderBedDeck(s), RenderDriveDeck(OscillatoryPoint(0.03, 3, 80, 4), s, s.default_precision)}) {
      SCOPED_TRACE(std::string(s.name));
      EXPECT_THAT(deck, HasSubstr("youngsModulus peratomtype 1e+07 1e+07"));
      EXPECT_THAT(deck, HasSubstr("poissonsRatio peratomtype 0.25 0.25"));
      EXPECT_THAT(deck, HasSubstr("coefficientRestitution peratomtypepair 2 0.9 0.5 0.5 0.5"));
      EXPECT_THAT(deck, HasSubstr("coefficientFriction peratomtypepair 2 0.45 0.5 0.5 0.5"));
      EXPECT_THAT(deck, HasSubstr("pair_style      gran model hertz tangential history"));
      EXPECT_THAT(deck, HasSubstr("timestep        1e-05"));
      EXPECT_THAT(deck, HasSubstr("gravity 9.81 vector 0.0 0.0 -1.0"));
      EXPECT_THAT(deck, HasSubstr("boundary        p p f"));
      EXPECT_THAT(deck, HasSubstr("primitive type 1 zplane " + FormatNumber(s.z_floor)));
      EXPECT_THAT(deck, Not(HasSubstr("{{")));
      EXPECT_THAT(deck, Not(HasSubstr("shell")));
    }
    std::string bed = RenderBedDeck(s);
    EXPECT_THAT(bed, HasSubstr("density constant 2500 radius constant 0.01"));
    EXPECT_THAT(bed, HasSubstr("set group so diameter 0.12"));
    EXPECT_THAT(bed, HasSubstr("set group so density 2500"));
  }
}

TEST(DeckTest, ModesBecomeNumbers) {
  Point p;
  p.mode = Mode::kRotation;
  p.omega = 80;
  p.axis = RotationAxis::kY;
  p.duration_s = 4;
  std::string d = RenderDriveDeck(p, *FindScale("paper"), std::nullopt);
  EXPECT_THAT(d, HasSubstr("variable A equal 0\n"));
  EXPECT_THAT(d, HasSubstr("variable wy equal 80+0*cos"));
  EXPECT_THAT(d, HasSubstr("variable wx equal 0+0*cos"));

  p.mode = Mode::kVibrationRotation;
  p.A = 0.03;
  p.f = 3;
  p.axis = RotationAxis::kXZ;
  d = RenderDriveDeck(p, *FindScale("paper"), std::nullopt);
  const std::string c = FormatNumber(80 * M_SQRT1_2);
  EXPECT_THAT(d, HasSubstr("variable wx equal " + c + "+0*cos"));
  EXPECT_THAT(d, HasSubstr("variable wz equal " + c + "+0*cos"));
  EXPECT_THAT(d, HasSubstr("variable A equal 0.03\n"));

  d = RenderDriveDeck(OscillatoryPoint(0.05, 4, -160, 4), *FindScale("paper"), std::nullopt);
  EXPECT_THAT(d, HasSubstr("variable wx equal 0+-160*cos(2.0*PI*v_f*v_t)"));
  EXPECT_THAT(d, HasSubstr("variable f equal 4\n"));
}

TEST(DeckTest, RenderingIsDeterministic) {
  const PrecisionTarget kTarget{0.2, 0.005, 3, 2.0};
  Point p = OscillatoryPoint(0.07, 20, 640, 4);
  EXPECT_EQ(RenderDriveDeck(p, Smoke(), kTarget), RenderDriveDeck(p, Smoke(), kTarget));
  EXPECT_EQ(RenderBedDeck(Smoke()), RenderBedDeck(Smoke()));
  EXPECT_NE(RenderDriveDeck(p, Smoke(), kTarget),
            RenderDriveDeck(OscillatoryPoint(0.07, 20, -640, 4), Smoke(), kTarget));
}

TEST(DeckTest, StepsCoverTheRunOrItsTargetsMaximum) {
  // 4 s without a target is 400000 steps.
  EXPECT_EQ(DriveSteps(OscillatoryPoint(0.03, 3, 80, 4), std::nullopt), 400000);
  // A target's maximum (2 s here) caps it...
  const PrecisionTarget t{0.1, 0.002, 3, 2.0};
  EXPECT_EQ(DriveSteps(OscillatoryPoint(0.03, 3, 80, 4), t), 200000);
  // ...but never below the transient and min_periods whole periods: 4 periods at 1 Hz.
  EXPECT_EQ(DriveSteps(OscillatoryPoint(0.03, 1, 80, 10), t), 400000);
  // Never longer than asked.
  EXPECT_EQ(DriveSteps(OscillatoryPoint(0.03, 1, 80, 0.1), t), 10000);
  std::string d = RenderDriveDeck(OscillatoryPoint(0.03, 3, 80, 4), Smoke(), t);
  EXPECT_THAT(d, HasSubstr("variable c loop 2000\n"));
  EXPECT_THAT(d, HasSubstr("# Precision target: 95 % interval of U_z within max(0.1 |U_z|, 0.002 m/s)"));
  // The target is part of the deck, hence of the run's key.
  EXPECT_NE(d, RenderDriveDeck(OscillatoryPoint(0.03, 3, 80, 4), Smoke(), PrecisionTarget{0.2, 0.002, 3, 2.0}));
  EXPECT_NE(d, RenderDriveDeck(OscillatoryPoint(0.03, 3, 80, 4), Smoke(), std::nullopt));
}

// At least 20 omega updates in every drive period, at every accepted f.
TEST(DeckTest, OmegaUpdatesKeepUpWithTheFrequency) {
  for (double f : {0.5, 1.0, 3.0, 30.0, 50.0, 51.0, 200.0, 999.0, kMaxFrequencyHz}) {
    SCOPED_TRACE(f);
    const Point p = OscillatoryPoint(0.03, f, 80, 4);
    const int chunk = OmegaUpdateSteps(p);
    EXPECT_GE(chunk, 1);
    EXPECT_LE(chunk, kOmegaUpdateSteps);
    const double period_steps = 1.0 / (f * kMaterials.dt);
    EXPECT_GE(period_steps / chunk, kMinOmegaUpdatesPerPeriod - 1e-9);
    EXPECT_EQ(DriveSteps(p, std::nullopt) % chunk, 0);
    EXPECT_THAT(RenderDriveDeck(p, Smoke(), std::nullopt),
                HasSubstr("run " + std::to_string(chunk) + " pre no post no"));
  }
  EXPECT_EQ(OmegaUpdateSteps(OscillatoryPoint(0.03, 50, 80, 4)), 100);
  EXPECT_EQ(OmegaUpdateSteps(OscillatoryPoint(0.03, 51, 80, 4)), 98);
}

TEST(DeckTest, DriveDeckEndsAtTheBoundaryOrWhenAsked) {
  const std::string d = RenderDriveDeck(OscillatoryPoint(0.03, 3, 80, 4), Smoke(), std::nullopt);
  // The floor stop: the SO's bottom one grain diameter above the floor (-0.35 + 0.06 + 0.02).
  ASSERT_EQ(Smoke().z_floor, -0.35);
  EXPECT_THAT(d, HasSubstr("variable z_floor_stop equal -0.27\n"));
  EXPECT_THAT(d, HasSubstr("print \"variable sandswim_stop equal 0\" file control.in screen no"));
  EXPECT_THAT(d, HasSubstr("  include control.in\n"));
  EXPECT_THAT(d, HasSubstr("SANDSWIM drive stop target"));
  EXPECT_THAT(d, HasSubstr("SANDSWIM drive stop window"));
  EXPECT_EQ(ControlFileText(StopVerdict::kContinue), "variable sandswim_stop equal 0\n");
  EXPECT_EQ(ControlFileText(StopVerdict::kTargetMet), "variable sandswim_stop equal 1\n");
  EXPECT_EQ(ControlFileText(StopVerdict::kWindowClosed), "variable sandswim_stop equal 2\n");
}

}  // namespace

// Snapshots (Fig. 5): a deck without them is the one it always was (the golden files above); with
// them it dumps every atom periodically, right after the trajectory's dump is set up and before the
// first run, and once more where every way of ending meets; the fractions are in the deck, hence
// in the key.
TEST(DeckTest, SnapshotsAddTheirDumpsAndChangeTheKeyOnly) {
  const Point p = OscillatoryPoint(0.03, 3, 80, 4);
  const PrecisionTarget t{0.2, 0.005, 3, 2.0};
  const std::string plain = RenderDriveDeck(p, Smoke(), t);
  EXPECT_EQ(RenderDriveDeck(p, Smoke(), t, {}), plain);
  const std::string with = RenderDriveDeck(p, Smoke(), t, {0, 0.5, 1});
  EXPECT_NE(with, plain);
  EXPECT_NE(with, RenderDriveDeck(p, Smoke(), t, {0, 1}));
  // 2 s at most = 2000 chunks of 100 steps: a frame every 100 chunks.
  EXPECT_EQ(SnapshotEverySteps(p, t), 10000);
  const std::string periodic = "dump snap all custom 10000 frame.*.dump id type x y z vx vy vz radius\n";
  const size_t at = with.find(periodic);
  ASSERT_NE(at, std::string::npos) << with;
  EXPECT_GT(at, with.find("dump_modify traj sort id"));
  EXPECT_LT(at, with.find("label chunk"));
  EXPECT_THAT(with, HasSubstr("# Full-bed snapshots (paper Fig. 5) at 0, 0.5, 1 of the run's actual length"));
  const std::string last = "write_dump all custom frame.last.dump id type x y z vx vy vz radius modify sort id\n";
  ASSERT_GE(with.size(), last.size());
  EXPECT_EQ(with.substr(with.size() - last.size()), last);
  EXPECT_GT(with.find(last), with.find("label finish"));
  // Nothing else changed: taking the snapshot lines out gives the plain deck back.
  std::string stripped = with.substr(0, with.find("label finish\n") + 13);
  const size_t block = stripped.find("# Full-bed snapshots");
  stripped.erase(block, stripped.find("dump_modify snap sort id\n") + 25 - block);
  EXPECT_EQ(stripped, plain);
}

TEST(DeckTest, SnapshotFractionsAreCheckedAndSorted) {
  auto ok = CheckSnapshotFractions({1, 0, 0.5});
  ASSERT_TRUE(ok.ok());
  EXPECT_EQ(*ok, (SnapshotFractions{0, 0.5, 1}));
  EXPECT_EQ(CheckSnapshotFractions({0, 1.5}).status().field(), "snapshots[1]");
  EXPECT_EQ(CheckSnapshotFractions({-0.1}).status().field(), "snapshots[0]");
  EXPECT_EQ(CheckSnapshotFractions({std::nan("")}).status().field(), "snapshots[0]");
  EXPECT_EQ(CheckSnapshotFractions({0.5, 0.5}).status().field(), "snapshots");
  EXPECT_EQ(CheckSnapshotFractions(std::vector<double>(kMaxSnapshots + 1, 0.1)).status().field(), "snapshots");
  // The database's form, and back.
  EXPECT_FALSE(SnapshotFractionsText({}).has_value());
  auto back = StoredSnapshotFractions(SnapshotFractionsText({0, 0.5, 1}));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, (SnapshotFractions{0, 0.5, 1}));
  EXPECT_TRUE(StoredSnapshotFractions(std::nullopt)->empty());
  EXPECT_EQ(StoredSnapshotFractions(std::string("[1, 0]")).status().code(), StatusCode::kCorruption);
  EXPECT_EQ(StoredSnapshotFractions(std::string("{")).status().code(), StatusCode::kCorruption);
}

}  // namespace sandswim
