// The early stop at the surface, with the real engine: a bed too shallow for the run, of its own
// (not the shared smoke bed, so this test needs no fixture and runs while the smoke bed is
// prepared).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/deck.h"
#include "tests/engine_fixture.h"

namespace sandswim {
namespace {

using testing::Drive;
using testing::EngineRun;
using ::testing::HasSubstr;
using testing::ReadTrajectory;
using testing::SoFrame;

// A bed too shallow for the run: the SO's top is near the surface, and a rising drive stops the
// run early at the surface and says so.
TEST(ShallowBedTest, EarlyStopAtTheSurfaceOfAShallowBed) {
  Scale shallow = *FindScale("smoke");
  shallow.name = "shallow-test";
  shallow.z_bed_top = 0.09;  // 0.03 m of grains above the SO's top
  // A smaller box than smoke's, for a cheaper bed: this test needs no room below, and L_y holds
  // exactly its A (2 A + d_SO + 3 d_grain).
  shallow.z_floor = -0.15;
  shallow.y_len = 0.24;
  const Point p = OscillatoryPoint(0.03, 3, -80, 2.0);  // rises (Omega < 0), for up to 2 s
  EngineRun r = Drive("shallow", p, shallow);
  EXPECT_THAT(r.log, HasSubstr("SANDSWIM drive stop surface"));
  std::vector<SoFrame> tr = ReadTrajectory(r.dir);
  ASSERT_FALSE(tr.empty());
  EXPECT_LT(tr.back().t, 2.0);
}

}  // namespace
}  // namespace sandswim
