#include "core/point.h"

#include <gtest/gtest.h>

namespace sandswim {
namespace {

// One decoding of a stored point, shared by the daemon's reads and its lease queue: every mode
// and axis reads back, and a name that is not ours is corruption, never a default.
TEST(StoredPointTest, EveryModeAndAxisReadsBackAndAStrangerIsCorruption) {
  for (Mode mode : {Mode::kVibration, Mode::kRotation, Mode::kVibrationRotation, Mode::kOscillatory}) {
    for (RotationAxis axis : {RotationAxis::kX, RotationAxis::kY, RotationAxis::kZ, RotationAxis::kXZ}) {
      auto p = StoredPoint(ModeName(mode), AxisName(axis), 0.03, 3, -80, 5, 2, std::nullopt);
      ASSERT_TRUE(p.ok()) << p.status().ToString();
      EXPECT_EQ(p->mode, mode);
      EXPECT_EQ(p->axis, axis);
      EXPECT_EQ(p->A, 0.03);
      EXPECT_EQ(p->f, 3);
      EXPECT_EQ(p->Omega, -80);
      EXPECT_EQ(p->omega, 5);
      EXPECT_EQ(p->duration_s, 2);
    }
  }
  auto bad_mode = StoredPoint("wobble", "x", 0, 0, 0, 0, 1, std::nullopt);
  EXPECT_EQ(bad_mode.status().code(), StatusCode::kCorruption);
  EXPECT_EQ(bad_mode.status().field(), "mode");
  auto bad_axis = StoredPoint("oscillatory", "w", 0, 0, 0, 0, 1, std::nullopt);
  EXPECT_EQ(bad_axis.status().code(), StatusCode::kCorruption);
  EXPECT_EQ(bad_axis.status().field(), "axis");
}

}  // namespace
}  // namespace sandswim
