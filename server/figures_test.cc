// Figures: each kind is drawn with the right number of series (read back from the SVG by the
// series' colours), PNGs are PNGs, and the cache never serves a figure of older data.
#include "server/figures.h"

#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;

// The series colours an SVG uses (every colour but the black ink and the white background).
std::set<std::string> SeriesColorsIn(const std::string& svg) {
  static const std::regex kColor(R"re((?:stroke|fill)="(#[0-9A-Fa-f]{6})")re");
  std::set<std::string> colors;
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), kColor); it != std::sregex_iterator(); ++it) {
    std::string c = (*it)[1].str();
    for (char& ch : c) ch = static_cast<char>(std::toupper(ch));
    if (c != "#000000" && c != "#FFFFFF") colors.insert(c);
  }
  return colors;
}

std::set<std::string> FirstColors(size_t n) {
  std::set<std::string> colors;
  for (size_t i = 0; i < n; ++i) colors.insert(SeriesColor(i));
  return colors;
}

api::Trajectory Wiggle(double rate, double phase) {
  api::Trajectory t;
  for (int i = 0; i <= 60; ++i) {
    double time = i * 0.01;
    t.t.push_back(time);
    t.x.push_back(0.001 * std::sin(6 * time + phase));
    t.y.push_back(0);
    t.z.push_back(0.02 + rate * time + 0.002 * std::sin(2 * M_PI * 3 * time + phase));
  }
  return t;
}

TEST(FiguresTest, SeriesColoursAreDistinctAndNeverInk) {
  std::set<std::string> colors = FirstColors(64);
  EXPECT_EQ(colors.size(), 64u);
  EXPECT_FALSE(colors.count("#000000"));
  EXPECT_FALSE(colors.count("#FFFFFF"));
}

TEST(FiguresTest, PlplotLiteralDoublesTheEscape) {
  EXPECT_EQ(PlplotLiteral("omega #1 #u"), "omega ##1 ##u");
  EXPECT_EQ(PlplotLiteral("plain"), "plain");
}

TEST(FiguresTest, ARunPlotHasZAndXWithUnits) {
  Plot plot = RunTrajectoryPlot(7, OscillatoryPoint(0.03, 3, -80, 0.6), Wiggle(0.01, 0));
  ASSERT_EQ(plot.series.size(), 2u);
  EXPECT_EQ(plot.x_label, "t (s)");
  EXPECT_THAT(plot.y_label, HasSubstr("(m)"));
  EXPECT_NEAR(plot.series[0].y.front(), 0, 1e-15);  // Δz starts at 0
  auto svg = RenderPlot(plot, ImageFormat::kSvg);
  ASSERT_TRUE(svg.ok()) << svg.status().ToString();
  EXPECT_THAT(*svg, HasSubstr("<svg"));
  EXPECT_EQ(SeriesColorsIn(*svg), FirstColors(2));
  auto png = RenderPlot(plot, ImageFormat::kPng);
  ASSERT_TRUE(png.ok()) << png.status().ToString();
  EXPECT_EQ(png->substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
}

// With its result, a run's plot shows what U_z is made of: Δz at the window's period boundaries and
// the line of slope U_z through the first of them, and says U_z in that line's legend entry.
TEST(FiguresTest, ARunPlotWithItsResultShowsTheBlocksOfUz) {
  api::Trajectory t = Wiggle(0.01, 0);  // 0.6 s at 3 Hz
  api::RunResult r;
  r.uz = 0.01;
  r.uz_blocks = 0;
  EXPECT_EQ(RunTrajectoryPlot(7, OscillatoryPoint(0.03, 3, -80, 0.6), t, &r).series.size(), 2u);
  r.uz_blocks = 1;
  r.block_s = 1.0 / 3;
  r.window_t0 = 0.2;
  r.window_t1 = 0.2 + 1.0 / 3;
  r.conclusive = false;
  Plot plot = RunTrajectoryPlot(7, OscillatoryPoint(0.03, 3, -80, 0.6), t, &r);
  ASSERT_EQ(plot.series.size(), 4u);
  EXPECT_EQ(plot.series[2].x.size(), 2u);  // the window's two period boundaries
  EXPECT_TRUE(plot.series[2].markers);
  EXPECT_NEAR(plot.series[3].y[1] - plot.series[3].y[0], 0.01 / 3, 1e-12);
  EXPECT_THAT(plot.series[3].label, HasSubstr("inconclusive"));
  EXPECT_TRUE(RenderPlot(plot, ImageFormat::kSvg).ok());
}

TEST(FiguresTest, ASweepTrajectoryPlotHasOneSeriesPerRun) {
  std::vector<RunTrajectory> runs;
  for (int n = 0; n < 5; ++n) {
    for (int sign : {-1, 1}) {
      double omega = sign * 10 * std::pow(2.0, n);
      runs.push_back({n * 2 + (sign > 0), OscillatoryPoint(0.03, 3, omega, 0.6), Wiggle(-sign * 0.002 * (n + 1), n)});
    }
  }
  Plot plot = SweepTrajectoriesPlot("omega sweep", runs, "Omega");
  ASSERT_EQ(plot.series.size(), 10u);
  EXPECT_EQ(plot.series[0].label, "Ω = -10 rad/s");
  auto svg = RenderPlot(plot, ImageFormat::kSvg);
  ASSERT_TRUE(svg.ok()) << svg.status().ToString();
  EXPECT_EQ(SeriesColorsIn(*svg), FirstColors(10));
}

TEST(FiguresTest, AUzPlotHasTheBranchesAndTheirFittedCurves) {
  std::vector<SweepSample> samples;
  for (int n = 0; n < 6; ++n) {
    double w = 10 * std::pow(2.0, n);
    samples.push_back({OscillatoryPoint(0.03, 3, -w, 4), 0.02 * (1 - std::exp(-0.02 * w)) + 1e-4 * (n % 2), 2e-4});
    samples.push_back({OscillatoryPoint(0.03, 3, w, 4), -0.01 * (1 - std::exp(-0.03 * w)) - 1e-4 * (n % 3), 2e-4});
  }
  SweepFits fits = FitSweep(samples);
  ASSERT_EQ(fits.branches.size(), 2u);
  ASSERT_TRUE(fits.branches[0].saturation && fits.branches[1].saturation);
  Plot plot = SweepUzPlot("omega sweep: U_z", samples, fits);
  ASSERT_EQ(plot.series.size(), 6u);  // rising, sinking, and a curve and its 95 % band for each
  EXPECT_EQ(plot.x_label, "Ω (rad/s)");
  EXPECT_THAT(plot.y_label, HasSubstr("(m/s)"));
  EXPECT_LT(plot.series[2].x.back(), 0);  // the rising curve lies at Ω < 0
  EXPECT_GT(plot.series[4].x.back(), 0);
  // Each band runs out along its upper edge and back along its lower one, around its curve.
  for (size_t curve : {2u, 4u}) {
    const Series& c = plot.series[curve];
    const Series& band = plot.series[curve + 1];
    EXPECT_THAT(band.label, HasSubstr("95 % band"));
    EXPECT_TRUE(band.dashed);
    const size_t half = band.x.size() / 2;
    ASSERT_EQ(band.x.size(), 2 * half);
    for (size_t i = 1; i < half; ++i) {
      const size_t back = band.x.size() - 1 - i;  // the lower edge at the same x
      ASSERT_DOUBLE_EQ(band.x[i], band.x[back]);
      EXPECT_GT(band.y[i], band.y[back]);
    }
    // The curve at the band's far end lies between its edges.
    EXPECT_DOUBLE_EQ(band.x[half - 1], c.x.back());
    EXPECT_LT(band.y[half], c.y.back());
    EXPECT_GT(band.y[half - 1], c.y.back());
  }
  auto svg = RenderPlot(plot, ImageFormat::kSvg);
  ASSERT_TRUE(svg.ok()) << svg.status().ToString();
  EXPECT_EQ(SeriesColorsIn(*svg), FirstColors(6));

  // A sweep with no fit: just the points. Points with no error (too few periods for one) are a
  // series of their own, never drawn as if they were precise.
  std::vector<SweepSample> two = {{OscillatoryPoint(0.03, 3, -80, 4), 0.01, 2e-3},
                                  {OscillatoryPoint(0.03, 3, 80, 4), -0.01, 0}};
  Plot baseline = SweepUzPlot("baseline", two, FitSweep(two));
  ASSERT_EQ(baseline.series.size(), 2u);
  EXPECT_EQ(baseline.series[0].label, "rising (Ω < 0)");
  EXPECT_EQ(baseline.series[1].label, "conclusive, no error (< 3 periods)");
  EXPECT_EQ(baseline.series[1].x, std::vector<double>{80});
}

TEST(FiguresTest, BadPlotsAreRefused) {
  EXPECT_EQ(RenderPlot(Plot{}, ImageFormat::kSvg).status().field(), "plot");
  Plot bad;
  bad.series.push_back({"nan", {0, 1}, {0, NAN}, {}, false, false});
  EXPECT_EQ(RenderPlot(bad, ImageFormat::kPng).status().field(), "plot");
  Plot ragged;
  ragged.series.push_back({"ragged", {0, 1}, {0}, {}, false, false});
  EXPECT_FALSE(RenderPlot(ragged, ImageFormat::kSvg).ok());
}

// Runs of one point on several replicate beds are told apart in the legend; runs on one bed are not
// labelled by it.
TEST(FiguresTest, TrajectoriesOnSeveralBedsNameTheirBed) {
  const Point p = OscillatoryPoint(0.03, 3, 80, 0.6);
  std::vector<RunTrajectory> runs = {{1, p, Wiggle(-0.05, 0), 0}, {2, p, Wiggle(-0.06, 1), 1}};
  Plot plot = SweepTrajectoriesPlot("replicates", runs, "Omega");
  ASSERT_EQ(plot.series.size(), 2u);
  EXPECT_NE(plot.series[0].label, plot.series[1].label);
  EXPECT_THAT(plot.series[1].label, HasSubstr("replicate bed 1"));
  Plot one = SweepTrajectoriesPlot("one bed", {runs[0]}, "Omega");
  EXPECT_THAT(one.series[0].label, ::testing::Not(HasSubstr("replicate")));
  // Δx(t) on request, from x(0).
  Plot x = SweepTrajectoriesPlot("x", {runs[0]}, "Omega", Coordinate::kX);
  EXPECT_THAT(x.y_label, HasSubstr("Δx"));
  EXPECT_EQ(x.series[0].y.front(), 0);
  EXPECT_NEAR(x.series[0].y.back(), runs[0].trajectory.x.back() - runs[0].trajectory.x.front(), 1e-15);
}

class FigureCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/sandswim-figures-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

TEST_F(FigureCacheTest, NewDataMakesANewFileAndTheOldOneGoes) {
  FigureCache cache(dir_ + "/figures");
  Plot before = RunTrajectoryPlot(3, OscillatoryPoint(0.03, 3, -80, 0.6), Wiggle(0.01, 0));
  auto first = cache.Get("run-3-trajectory", before, ImageFormat::kSvg);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  const std::string old_path = cache.PathFor("run-3-trajectory", before, ImageFormat::kSvg);
  ASSERT_TRUE(std::filesystem::exists(old_path));

  // The same plot is read back from its file (marked here to prove it).
  { std::ofstream(old_path, std::ios::trunc) << "<svg>from the file</svg>"; }
  auto again = cache.Get("run-3-trajectory", before, ImageFormat::kSvg);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, "<svg>from the file</svg>");

  // A new result for the run: a new file, never the old one.
  Plot after = RunTrajectoryPlot(3, OscillatoryPoint(0.03, 3, -80, 0.6), Wiggle(0.02, 0));
  auto fresh = cache.Get("run-3-trajectory", after, ImageFormat::kSvg);
  ASSERT_TRUE(fresh.ok());
  EXPECT_NE(*fresh, "<svg>from the file</svg>");
  EXPECT_NE(cache.PathFor("run-3-trajectory", after, ImageFormat::kSvg), old_path);
  EXPECT_FALSE(std::filesystem::exists(old_path));
  // The PNG of the same plot is a file of its own.
  ASSERT_TRUE(cache.Get("run-3-trajectory", after, ImageFormat::kPng).ok());
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(dir_ + "/figures")) {
    (void)entry;
    ++files;
  }
  EXPECT_EQ(files, 2);
}

}  // namespace
}  // namespace sandswim
