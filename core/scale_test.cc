#include "core/scale.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;

Point Vib(double A, double f = 3) {
  Point p;
  p.mode = Mode::kVibration;
  p.A = A;
  p.f = f;
  p.duration_s = 4;
  return p;
}

TEST(ScaleTest, BoxesHoldTheSoAndItsSwing) {
  for (const Scale& s : AllScales()) {
    SCOPED_TRACE(std::string(s.name));
    EXPECT_GE(s.x_len, kMaterials.d_so + 3 * kMaterials.d_grain);
    // At least 0.12 m of grains above and below the SO at (0, 0, 0) (SPEC.md).
    EXPECT_GE(s.z_bed_top - kMaterials.d_so / 2, 0.12 - 1e-12);
    EXPECT_GE(-s.z_floor - kMaterials.d_so / 2, 0.12 - 1e-12);
  }
  // The paper-58 A sweep reaches 0.10 m: every scale takes it.
  for (const Scale& s : AllScales()) EXPECT_TRUE(FitsScale(Vib(0.10), s).ok()) << s.name;
}

TEST(ScaleTest, RefusesAnAmplitudeTheBoxCannotHoldAndNamesAScaleThatCan) {
  Status st = FitsScale(Vib(0.2), *FindScale("smoke"));
  ASSERT_FALSE(st.ok());
  EXPECT_EQ(st.field(), "A");
  EXPECT_THAT(st.reason(), HasSubstr("scale 'paper' takes it"));
  EXPECT_THAT(st.reason(), HasSubstr("L_y >= 0.58"));
  st = FitsScale(Vib(0.5), *FindScale("paper"));
  ASSERT_FALSE(st.ok());
  EXPECT_THAT(st.reason(), ::testing::Not(HasSubstr("takes it")));
}

// Every box keeps about the same room above and below the SO placed at z = 0 (each side loses
// its 0.12 m clearance and the SO's radius), and at least 0.12 m of it.
TEST(ScaleTest, RoomAboveAndBelowTheSoIsAlike) {
  for (const Scale& s : AllScales()) {
    SCOPED_TRACE(std::string(s.name));
    const double up = s.z_bed_top - kMaterials.d_so / 2 - 0.12;
    const double down = -s.z_floor - kMaterials.d_so / 2 - 0.12;
    EXPECT_GE(up, 0.12);
    EXPECT_GE(down, 0.12);
    EXPECT_NEAR(up, down, 0.02);
  }
}

TEST(ScaleTest, SmokeRunsToAPrecisionTarget) {
  const Scale& smoke = *FindScale("smoke");
  ASSERT_TRUE(smoke.default_precision.has_value());
  EXPECT_TRUE(Validate(*smoke.default_precision).ok());
  EXPECT_GE(smoke.default_precision->min_periods, 3);
  // The maximum still holds the transient and min_periods whole periods at f = 1 Hz.
  EXPECT_DOUBLE_EQ(RunDuration(Vib(0.03, 1), smoke.default_precision), 4.0);
  EXPECT_DOUBLE_EQ(RunDuration(Vib(0.03, 30), smoke.default_precision), smoke.default_precision->max_duration_s);
  EXPECT_FALSE(FindScale("paper")->default_precision.has_value());
  EXPECT_DOUBLE_EQ(RunDuration(Vib(0.03, 3), std::nullopt), 4.0);
}

TEST(PointTest, ValidationNamesTheField) {
  Point p = Vib(-0.01);
  EXPECT_EQ(Validate(p).field(), "A");
  p = Vib(0.03, 0);
  EXPECT_EQ(Validate(p).field(), "f");
  p = Vib(0.03);
  p.duration_s = 86401;
  EXPECT_EQ(Validate(p).field(), "duration_s");
  p = Vib(std::nan(""));
  EXPECT_EQ(Validate(p).field(), "A");
  p = Vib(0.03);
  p.Omega = 80;  // not a vibration-mode field
  EXPECT_EQ(Validate(p).field(), "Omega");
  p.mode = Mode::kOscillatory;
  p.Omega = 1e6;
  EXPECT_EQ(Validate(p).field(), "Omega");
  p.Omega = -80;
  EXPECT_TRUE(Validate(p).ok());
}

}  // namespace
}  // namespace sandswim
