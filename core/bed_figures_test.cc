#include "core/bed_figures.h"

#include <cmath>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

// A dump of grains of diameter 0.02 m on a simple cubic lattice of spacing 0.02 m (touching:
// packing fraction pi/6) filling a periodic box 0.2 x 0.2 m from z = -0.2 to `top`, with the SO
// (r = 0.06) at (sx, sy, 0). The lattice keeps the sites inside the SO: this is a test of the
// measure, whose known answer is the lattice's own fraction, not a bed.
std::string LatticeDump(double sx, double sy, double top = 0.2) {
  std::ostringstream atoms;
  int n = 0;
  const double a = 0.02;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      for (int k = 0; - 0.19 + k * a <= top; ++k) {
        const double x = -0.09 + i * a, y = -0.09 + j * a, z = -0.19 + k * a;
        atoms << ++n << " 1 " << x << " " << y << " " << z << " 0.01\n";
      }
  atoms << ++n << " 2 " << sx << " " << sy << " 0 0.06\n";
  std::ostringstream out;
  out << "ITEM: TIMESTEP\n100\nITEM: NUMBER OF ATOMS\n"
      << n << "\nITEM: BOX BOUNDS pp pp fm\n-0.1 0.1\n-0.1 0.1\n-0.2 0.6\nITEM: ATOMS id type x y z radius\n"
      << atoms.str();
  return out.str();
}

TEST(BedFiguresTest, ALatticeOfKnownPackingMeasuresAsSuch) {
  auto b = MeasureBed(LatticeDump(0, 0));
  ASSERT_TRUE(b.ok()) << b.status().ToString();
  EXPECT_NEAR(b->packing_fraction, M_PI / 6, 0.01);  // 0.524
  EXPECT_GT(b->shell_grains, 100);
  EXPECT_NEAR(b->grain_top, 0.19, 1e-9);
  EXPECT_NEAR(b->bed_height, 0.39, 1e-9);
  EXPECT_NEAR(b->so_depth, 0.19 - 0.06, 1e-9);
  EXPECT_EQ(b->so_z, 0);
}

// Near the box's edge the shell wraps around: the same lattice, the same fraction.
TEST(BedFiguresTest, TheShellUsesTheNearestPeriodicImage) {
  auto centre = MeasureBed(LatticeDump(0.01, 0.01));
  auto edge = MeasureBed(LatticeDump(0.09, -0.09));
  ASSERT_TRUE(centre.ok() && edge.ok());
  EXPECT_EQ(centre->shell_grains, edge->shell_grains);
  EXPECT_NEAR(centre->packing_fraction, edge->packing_fraction, 1e-12);
}

TEST(BedFiguresTest, BadDumpsAreRefusedWithTheReason) {
  std::string no_so = LatticeDump(0, 0);
  no_so.replace(no_so.rfind(" 2 "), 3, " 1 ");
  EXPECT_THAT(MeasureBed(no_so).status().reason(), ::testing::HasSubstr("none"));
  EXPECT_FALSE(MeasureBed("").ok());
  std::string no_box = LatticeDump(0, 0);
  no_box.replace(no_box.find("BOX BOUNDS"), 10, "BOX LIMITS");
  EXPECT_FALSE(MeasureBed(no_box).ok());
  std::string narrow = LatticeDump(0, 0);
  narrow.replace(narrow.find("-0.1 0.1\n"), 9, "-0.05 0.05\n");
  EXPECT_EQ(MeasureBed(narrow).status().code(), StatusCode::kFailedPrecondition);
}

}  // namespace
}  // namespace sandswim
