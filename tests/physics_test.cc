// Physics of the decks with the real engine at smoke scale: the SO follows its
// prescription, its x and z are free, and runs from one bed start alike. Each test runs LIGGGHTS
// under mpirun on the shared smoke bed (engine_fixture.h; ctest's smoke_bed fixture prepares it).
// The early stop at the surface needs a bed of its own: shallow_bed_test.cc.
#include <cmath>
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/deck.h"
#include "core/dump_reader.h"
#include "tests/engine_fixture.h"

namespace sandswim {
namespace {

using testing::Drive;
using testing::EngineRun;
using ::testing::HasSubstr;
using testing::ReadTrajectory;
using testing::SoFrame;

const Scale& Smoke() { return *FindScale("smoke"); }

// y = y0 + A sin(2 pi f t) at every frame; omega_x = Omega cos(2 pi f t') where t' is the start of
// the 1 ms chunk the frame closes (omega is set between chunks and holds within one); x, z free.
TEST(PhysicsTest, SoFollowsThePrescribedDriveAndZIsFree) {
  const Point p = OscillatoryPoint(0.03, 10, -80, 0.2);  // two periods at 10 Hz
  EngineRun r = Drive("oscillatory", p, Smoke());
  EXPECT_THAT(r.log, HasSubstr("SANDSWIM drive stop duration step 20000"));
  std::vector<SoFrame> tr = ReadTrajectory(r.dir);
  ASSERT_EQ(tr.size(), 201u);  // t = 0, 1 ms, ..., 200 ms
  const double y0 = tr[0].y;
  const double chunk = kOmegaUpdateSteps * kMaterials.dt;
  for (size_t i = 0; i < tr.size(); ++i) {
    const SoFrame& f = tr[i];
    SCOPED_TRACE("t = " + std::to_string(f.t));
    const double w = 2 * M_PI * p.f;
    // The dump prints 6 significant digits: 1e-5 m and 1e-3 of the amplitudes are the resolution.
    EXPECT_NEAR(f.y, y0 + p.A * std::sin(w * f.t), 1e-5);
    // fix move prescribes v_y from the first step on; the t = 0 frame still shows the bed's rest.
    if (i > 0) {
      EXPECT_NEAR(f.vy, p.A * w * std::cos(w * f.t), 1e-3 * p.A * w);
    }
    const double t_set = i == 0 ? 0.0 : f.t - chunk;
    EXPECT_NEAR(f.wx, p.Omega * std::cos(w * t_set), 1e-3 * std::fabs(p.Omega));
    EXPECT_EQ(f.wy, 0.0);
    EXPECT_EQ(f.wz, 0.0);
  }
  // Driven, the SO moves in z by more than a quarter of a grain diameter in 0.2 s.
  EXPECT_GT(std::fabs(tr.back().z - tr.front().z), 0.005) << "z0 " << tr.front().z << " z1 " << tr.back().z;
}

// With no drive at all the SO rests in the equilibrated bed: x and z free but still.
TEST(PhysicsTest, UndrivenSoStaysPut) {
  Point p;
  p.mode = Mode::kRotation;
  p.omega = 0;
  p.duration_s = 0.05;
  EngineRun r = Drive("undriven", p, Smoke());
  std::vector<SoFrame> tr = ReadTrajectory(r.dir);
  ASSERT_EQ(tr.size(), 51u);  // t = 0, 1 ms, ..., 50 ms
  for (const SoFrame& f : tr) {
    EXPECT_NEAR(f.z, tr[0].z, 0.002);  // a tenth of a grain diameter
    EXPECT_NEAR(f.x, tr[0].x, 0.002);
    EXPECT_NEAR(f.y, tr[0].y, 1e-9);
    EXPECT_EQ(f.wx, 0.0);
  }
}

// Constant rotation about the xz diagonal: omega = 80 (1, 0, 1)/sqrt(2) in every frame.
TEST(PhysicsTest, ConstantRotationAboutTheDiagonal) {
  Point p;
  p.mode = Mode::kVibrationRotation;
  p.A = 0.03;
  p.f = 20;
  p.omega = 80;
  p.axis = RotationAxis::kXZ;
  p.duration_s = 0.02;  // 21 frames: omega is checked in each
  EngineRun r = Drive("diagonal", p, Smoke());
  const std::vector<SoFrame> tr = ReadTrajectory(r.dir);
  ASSERT_EQ(tr.size(), 21u);  // t = 0, 1 ms, ..., 20 ms
  for (const SoFrame& f : tr) {
    EXPECT_NEAR(f.wx, 80 * M_SQRT1_2, 1e-3);
    EXPECT_EQ(f.wy, 0.0);
    EXPECT_NEAR(f.wz, 80 * M_SQRT1_2, 1e-3);
  }
}

// Every run starts from the same bed: identical grain positions at t = 0.
TEST(PhysicsTest, RunsFromOneBedStartIdentically) {
  // Short runs: the t = 0 frames must match, and the drives differ from the first step on.
  Point a = OscillatoryPoint(0.03, 20, 80, 0.02);
  Point b = OscillatoryPoint(0.05, 20, -160, 0.02);
  EngineRun ra = Drive("same-bed-a", a, Smoke());
  EngineRun rb = Drive("same-bed-b", b, Smoke());
  std::string ia = testing::ReadFile(ra.dir + "/" + kInitialDumpFile);
  std::string ib = testing::ReadFile(rb.dir + "/" + kInitialDumpFile);
  ASSERT_GT(ia.size(), 1000u);
  EXPECT_EQ(ia, ib);
  EXPECT_NE(testing::ReadFile(ra.dir + "/" + kTrajectoryDumpFile),
            testing::ReadFile(rb.dir + "/" + kTrajectoryDumpFile));
}

}  // namespace
}  // namespace sandswim
