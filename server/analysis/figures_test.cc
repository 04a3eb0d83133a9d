// Figures: each kind is drawn with the right number of series (read back from the SVG by the
// series' colours), a bed slice with every grain and its colour bar, PNGs are PNGs, and the cache
// never serves a figure of older data.
#include "server/analysis/figures.h"

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "server/analysis/figure_cache.h"

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

// ---- Bed slices: discs coloured by a value ----------------------------------------------------

// A slice through a bed 0.18 m wide and 0.7 m tall: `grains` discs of radius 0.01 m on a lattice,
// their speeds running evenly from 0 to 0.5 m/s, and the SO's outline (radius 0.06 m at 0, 0).
Plot BedSlicePlot(int grains, bool equal_aspect) {
  Plot plot;
  plot.title = "y–z slice through the SO, t = 0.67 s";
  plot.x_label = "y (m)";
  plot.y_label = "z (m)";
  Discs discs;
  discs.value_label = "|v| (m/s)";
  for (int i = 0; i < grains; ++i) {
    discs.x.push_back(-0.08 + 0.04 * (i % 5));
    discs.y.push_back(-0.37 + 0.06 * (i / 5));
    discs.r.push_back(0.01);
    discs.value.push_back(grains > 1 ? 0.5 * i / (grains - 1) : 0.2);
  }
  plot.discs = discs;
  Series so{"SO", {}, {}, {}, false, false};
  for (int k = 0; k <= 48; ++k) {
    so.x.push_back(0.06 * std::cos(2 * M_PI * k / 48));
    so.y.push_back(0.06 * std::sin(2 * M_PI * k / 48));
  }
  plot.series.push_back(so);
  plot.equal_aspect = equal_aspect;
  plot.limits = std::array<double, 4>{-0.09, 0.09, -0.4, 0.3};
  return plot;
}

// The SVG's text with its character references ("&#x7c;") decoded: PLplot's svg device writes
// every character of a label as one.
std::string SvgText(const std::string& svg) {
  static const std::regex kRef("&#x([0-9A-Fa-f]+);");
  std::string out;
  auto last = svg.cbegin();
  for (auto it = std::sregex_iterator(svg.begin(), svg.end(), kRef); it != std::sregex_iterator(); ++it) {
    out.append(last, svg.cbegin() + it->position());
    const unsigned long c = std::stoul((*it)[1].str(), nullptr, 16);
    if (c < 0x80) {
      out += static_cast<char>(c);
    } else if (c < 0x800) {
      out += static_cast<char>(0xC0 | (c >> 6));
      out += static_cast<char>(0x80 | (c & 0x3F));
    } else {
      out += static_cast<char>(0xE0 | (c >> 12));
      out += static_cast<char>(0x80 | ((c >> 6) & 0x3F));
      out += static_cast<char>(0x80 | (c & 0x3F));
    }
    last = svg.cbegin() + it->position() + it->length();
  }
  out.append(last, svg.cend());
  return out;
}

// PLplot's svg device writes a filled polygon (plfill) as a <polyline> with a fill-rule; a line
// has none.
int FilledShapesIn(const std::string& svg) {
  int n = 0;
  for (size_t at = svg.find("fill-rule="); at != std::string::npos; at = svg.find("fill-rule=", at + 1)) ++n;
  return n;
}

// Width over height, on the page, of the first filled shape (the first disc: discs are drawn first).
double FirstFilledShapeAspect(const std::string& svg) {
  static const std::regex kPoints(R"re(fill-rule="[a-z]+"\s*points="([^"]*)")re");
  std::smatch m;
  if (!std::regex_search(svg, m, kPoints)) return NAN;
  std::string points = m[1].str();
  std::replace(points.begin(), points.end(), ',', ' ');
  std::istringstream in(points);
  double x = 0, y = 0, x_lo = INFINITY, x_hi = -INFINITY, y_lo = INFINITY, y_hi = -INFINITY;
  while (in >> x >> y) {
    x_lo = std::min(x_lo, x), x_hi = std::max(x_hi, x);
    y_lo = std::min(y_lo, y), y_hi = std::max(y_hi, y);
  }
  return (x_hi - x_lo) / (y_hi - y_lo);
}

TEST(FiguresTest, ASliceRoundTripsThroughJson) {
  const Plot plot = BedSlicePlot(50, true);
  const nlohmann::json j = plot;
  auto back = PlotFromJson(j);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  ASSERT_TRUE(back->discs.has_value());
  EXPECT_EQ(back->discs->x, plot.discs->x);
  EXPECT_EQ(back->discs->y, plot.discs->y);
  EXPECT_EQ(back->discs->r, plot.discs->r);
  EXPECT_EQ(back->discs->value, plot.discs->value);
  EXPECT_EQ(back->discs->value_label, "|v| (m/s)");
  EXPECT_TRUE(back->equal_aspect);
  EXPECT_EQ(back->limits, plot.limits);
  ASSERT_EQ(back->series.size(), 1u);
  EXPECT_EQ(back->series[0].label, "SO");
  EXPECT_EQ(nlohmann::json(*back).dump(), j.dump());
}

// A plot without discs, equal aspect or limits writes none of them: its JSON, and so its figure's
// cache name, is what it was before they existed.
TEST(FiguresTest, APlotWithoutDiscsKeepsItsJson) {
  Plot plot;
  plot.title = "t";
  plot.x_label = "x";
  plot.y_label = "y";
  plot.series.push_back({"a", {0, 1}, {2, 3}, {}, false, true});
  EXPECT_EQ(nlohmann::json(plot).dump(),
            R"({"series":[{"dashed":true,"label":"a","markers":false,"x":[0.0,1.0],"y":[2.0,3.0],"y_err":[]}],)"
            R"("title":"t","x_label":"x","y_label":"y"})");
  auto back = PlotFromJson(nlohmann::json(plot));
  ASSERT_TRUE(back.ok());
  EXPECT_FALSE(back->discs.has_value());
  EXPECT_FALSE(back->equal_aspect);
  EXPECT_FALSE(back->limits.has_value());
}

TEST(FiguresTest, PlotFromJsonRefusesAMistypedSlice) {
  const nlohmann::json good = BedSlicePlot(3, true);
  ASSERT_TRUE(PlotFromJson(good).ok());
  auto refused = [&](auto edit) {
    nlohmann::json j = good;
    edit(j);
    auto plot = PlotFromJson(j);
    return !plot.ok() && plot.status().code() == StatusCode::kInvalidArgument && plot.status().field() == "plot";
  };
  using json = nlohmann::json;
  EXPECT_TRUE(refused([](json& j) { j["discs"] = json::array(); }));
  EXPECT_TRUE(refused([](json& j) { j["discs"].erase("x"); }));
  EXPECT_TRUE(refused([](json& j) { j["discs"]["r"] = 0.01; }));
  EXPECT_TRUE(refused([](json& j) { j["discs"]["value"][1] = "fast"; }));
  EXPECT_TRUE(refused([](json& j) { j["discs"].erase("value_label"); }));
  EXPECT_TRUE(refused([](json& j) { j["discs"]["value_label"] = 3; }));
  EXPECT_TRUE(refused([](json& j) { j["equal_aspect"] = "yes"; }));
  EXPECT_TRUE(refused([](json& j) { j["limits"] = "the box"; }));
  EXPECT_TRUE(refused([](json& j) { j["limits"] = {0, 1, 2}; }));
  EXPECT_TRUE(refused([](json& j) { j["limits"][2] = nullptr; }));
}

TEST(FiguresTest, BadSlicesAreRefused) {
  Plot grains_only = BedSlicePlot(3, true);
  grains_only.series.clear();
  EXPECT_TRUE(CheckPlot(grains_only).ok());  // discs alone are something to draw
  Plot nothing = grains_only;
  nothing.discs.reset();
  EXPECT_EQ(CheckPlot(nothing).field(), "plot");
  auto refused = [](auto edit) {
    Plot plot = BedSlicePlot(3, true);
    edit(plot);
    Status s = CheckPlot(plot);
    return s.code() == StatusCode::kInvalidArgument && s.field() == "plot";
  };
  EXPECT_TRUE(refused([](Plot& p) { p.discs->r.pop_back(); }));
  EXPECT_TRUE(refused([](Plot& p) { p.discs->value.push_back(1); }));
  EXPECT_TRUE(refused([](Plot& p) { p.discs->value[1] = NAN; }));
  EXPECT_TRUE(refused([](Plot& p) { p.discs->x[0] = INFINITY; }));
  EXPECT_TRUE(refused([](Plot& p) { p.discs->r[2] = 0; }));
  EXPECT_TRUE(refused([](Plot& p) { p.discs->r[2] = -0.01; }));
  EXPECT_TRUE(refused([](Plot& p) { (*p.limits)[0] = (*p.limits)[1]; }));
  EXPECT_TRUE(refused([](Plot& p) { (*p.limits)[2] = 1; }));  // above y_hi
  EXPECT_TRUE(refused([](Plot& p) { (*p.limits)[3] = NAN; }));
  Plot ragged = BedSlicePlot(3, true);
  ragged.discs->y.pop_back();
  EXPECT_EQ(RenderPlot(ragged, ImageFormat::kSvg).status().field(), "plot");
}

// Every grain is a filled shape in its speed's colour, the slowest at the colour map's dark end and
// the fastest at its yellow one; the colour bar says what the colour is; the SO is drawn over them.
TEST(FiguresTest, ASliceDrawsEveryDiscAndAColourBar) {
  constexpr int kGrains = 50;
  auto svg = RenderPlot(BedSlicePlot(kGrains, true), ImageFormat::kSvg);
  ASSERT_TRUE(svg.ok()) << svg.status().ToString();
  EXPECT_GE(FilledShapesIn(*svg), kGrains);
  EXPECT_THAT(*svg, HasSubstr("fill=\"#440154\""));  // 0 m/s
  EXPECT_THAT(*svg, HasSubstr("fill=\"#FDE725\""));  // 0.5 m/s
  EXPECT_THAT(*svg, HasSubstr("stroke=\"" + SeriesColor(0) + "\""));
  const std::string text = SvgText(*svg);
  EXPECT_THAT(text, HasSubstr(">|v| (m/s)<"));
  EXPECT_THAT(text, HasSubstr(">0.5<"));  // the colour bar's top tick
  EXPECT_THAT(text, HasSubstr(">SO<"));   // the legend
  // Under a box 0.18 m wide, three short labels that keep apart (PLplot's own "-0.05 0.00 0.05"
  // run into each other there).
  EXPECT_THAT(text, HasSubstr(">-0.05<"));
  EXPECT_THAT(text, HasSubstr(">0<"));
  EXPECT_THAT(text, HasSubstr(">0.05<"));
  EXPECT_THAT(text, ::testing::Not(HasSubstr(">0.00<")));

  // No series: the discs and the colour bar alone, and no legend.
  Plot grains_only = BedSlicePlot(kGrains, true);
  grains_only.series.clear();
  auto bare = RenderPlot(grains_only, ImageFormat::kSvg);
  ASSERT_TRUE(bare.ok()) << bare.status().ToString();
  EXPECT_GE(FilledShapesIn(*bare), kGrains);
  EXPECT_THAT(SvgText(*bare), ::testing::Not(HasSubstr(">SO<")));
}

// With equal_aspect a disc is round on the page; without it, a tall box is stretched across.
TEST(FiguresTest, DiscsAreRoundWithEqualAspect) {
  auto round = RenderPlot(BedSlicePlot(10, true), ImageFormat::kSvg);
  ASSERT_TRUE(round.ok()) << round.status().ToString();
  EXPECT_NEAR(FirstFilledShapeAspect(*round), 1.0, 0.1);
  auto stretched = RenderPlot(BedSlicePlot(10, false), ImageFormat::kSvg);
  ASSERT_TRUE(stretched.ok());
  EXPECT_GT(FirstFilledShapeAspect(*stretched), 2.0);
}

TEST(FiguresTest, AnEqualAspectSliceRendersToPng) {
  auto png = RenderPlot(BedSlicePlot(50, true), ImageFormat::kPng);
  ASSERT_TRUE(png.ok()) << png.status().ToString();
  ASSERT_GT(png->size(), 24u);
  EXPECT_EQ(png->substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  // One speed for every grain: the colour map still has a range to span.
  Plot flat = BedSlicePlot(50, true);
  std::fill(flat.discs->value.begin(), flat.discs->value.end(), 0.0);
  EXPECT_TRUE(RenderPlot(flat, ImageFormat::kPng).ok());
}

// ---- Layout: the plot takes the page's width; the legend hides no data ----

// The issue's figure: U_z of a density-ratio sweep, one branch, bars that reach the top left.
Plot DensitySweepUz() {
  Plot plot;
  plot.title = "sweep 3 density.rising (smoke): U#dz#u";
  plot.x_label = "so_density (kg/m^3)";
  plot.y_label = "U#dz#u (m/s), bars: 95 % interval";
  plot.series.push_back({"rising (Ω < 0)",
                         {1250, 1900, 2500, 3750, 5000, 7500},
                         {0.1225, 0.108, 0.1015, 0.0815, 0.076, 0.047},
                         {0.065, 0.05, 0.0375, 0.0295, 0.030, 0.0175},
                         true,
                         false});
  return plot;
}

// The plot's data on the page (fractions), as the test sees them: markers with their bars and
// every line, each segment sampled finely; and whether any comes within `clear_px` of `r`.
bool DataWithin(const Plot& plot, const FigureLayout& at, const PageRect& r, double clear_px) {
  const PageRect near{r.x0 - clear_px / 1200, r.x1 + clear_px / 1200, r.y0 - clear_px / 600, r.y1 + clear_px / 600};
  const auto page_x = [&](double x) { return at.box.x0 + (x - at.axes[0]) / (at.axes[1] - at.axes[0]) * at.box.width(); };
  const auto page_y = [&](double y) { return at.box.y0 + (y - at.axes[2]) / (at.axes[3] - at.axes[2]) * at.box.height(); };
  const auto inside = [&](double x, double y) { return x >= near.x0 && x <= near.x1 && y >= near.y0 && y <= near.y1; };
  for (const Series& s : plot.series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      const double e = s.y_err.empty() ? 0 : s.y_err[i];
      const double x0 = s.x[i], y0 = s.markers ? s.y[i] - e : s.y[i];
      const double x1 = s.markers || i + 1 == s.x.size() ? s.x[i] : s.x[i + 1];
      const double y1 = s.markers ? s.y[i] + e : i + 1 == s.x.size() ? s.y[i] : s.y[i + 1];
      for (int k = 0; k <= 50; ++k) {
        if (inside(page_x(x0 + (x1 - x0) * k / 50), page_y(y0 + (y1 - y0) * k / 50))) return true;
      }
    }
  }
  return false;
}

std::string Describe(const PageRect& r) {
  std::ostringstream out;
  out << "x " << r.x0 << ".." << r.x1 << ", y " << r.y0 << ".." << r.y1;
  return out.str();
}

::testing::AssertionResult Contains(const PageRect& outer, const PageRect& inner) {
  constexpr double kSlack = 1e-6;
  if (inner.x0 >= outer.x0 - kSlack && inner.x1 <= outer.x1 + kSlack && inner.y0 >= outer.y0 - kSlack &&
      inner.y1 <= outer.y1 + kSlack) {
    return ::testing::AssertionSuccess();
  }
  return ::testing::AssertionFailure() << Describe(inner) << " is not inside " << Describe(outer);
}

// Draws `plot` in `format` and returns the layout as drawn.
FigureLayout Drawn(const Plot& plot, ImageFormat format) {
  // A name of this process's own: ctest runs each test in a process of its own, several at once.
  const std::string path =
      std::filesystem::temp_directory_path() / ("sandswim-layout-test-" + std::to_string(getpid()));
  FigureLayout drawn;
  const Status status = DrawPlotToFile(plot, format, path, &drawn);
  EXPECT_TRUE(status.ok()) << status.ToString();
  std::filesystem::remove(path);
  return drawn;
}

// The density-ratio figure drew its box over the left 47 % of the page and its one-entry legend
// in the rest. Now the box spans the page and the legend sits inside it, clear of every bar.
TEST(FigureLayoutTest, AUzFigureUsesThePageWidthAndItsLegendHidesNoData) {
  const Plot plot = DensitySweepUz();
  for (ImageFormat format : {ImageFormat::kPng, ImageFormat::kSvg}) {
    SCOPED_TRACE(ImageExtension(format));
    const FigureLayout layout = LayOutFigure(plot, format);
    EXPECT_EQ(layout.legend, LegendPlace::kInside);
    EXPECT_FALSE(layout.headroom);
    const FigureLayout drawn = Drawn(plot, format);
    EXPECT_GE(drawn.box.width(), 0.85);
    EXPECT_EQ(drawn.legend, LegendPlace::kInside);
    // PLplot's frame lies inside the rectangle the layout kept for it, and no datum is near it.
    EXPECT_TRUE(Contains(layout.legend_rect, drawn.legend_rect));
    EXPECT_TRUE(Contains(drawn.box, drawn.legend_rect));
    EXPECT_FALSE(DataWithin(plot, drawn, drawn.legend_rect, 3));
  }
}

// Each kind of figure with a legend: the frame PLplot draws stays inside the rectangle the layout
// kept free (so the estimate of its labels' width is never short, on either device); inside the
// box it hides no data and the box spans the page, beside it the box keeps at least the old
// layout's 47 %.
TEST(FigureLayoutTest, EveryKindDrawsItsLegendInsideTheRoomKeptForIt) {
  std::vector<Plot> plots = {DensitySweepUz()};
  api::RunResult result;
  result.analysis = api::kAnalysisVersion;
  result.conclusive = true;
  result.uz = 0.01;
  result.uz_stderr = 0.001;
  result.uz_blocks = 1;
  result.block_s = 1.0 / 3;
  result.window_t0 = 0.2;
  result.window_t1 = 0.2 + 1.0 / 3;
  plots.push_back(RunTrajectoryPlot(7, OscillatoryPoint(0.03, 3, -80, 0.6), Wiggle(0.01, 0), &result));
  std::vector<RunTrajectory> runs;
  for (int n = 0; n < 8; ++n) {
    for (int sign : {-1, 1}) {
      const double omega = sign * 10 * (n + 1);
      runs.push_back({n * 2 + (sign > 0), OscillatoryPoint(0.03, 3, omega, 0.6), Wiggle(-sign * 0.002 * (n + 1), n)});
    }
  }
  plots.push_back(SweepTrajectoriesPlot("every run", runs, "Omega"));                                   // 16 entries
  plots.push_back(SweepTrajectoriesPlot("rising", std::vector<RunTrajectory>(runs.begin(), runs.begin() + 3), "Omega"));
  std::vector<SweepSample> samples;
  for (int n = 0; n < 6; ++n) {
    const double w = 10 * std::pow(2.0, n);
    samples.push_back({OscillatoryPoint(0.03, 3, -w, 4), 0.02 * (1 - std::exp(-0.02 * w)) + 1e-4 * (n % 2), 2e-4});
    samples.push_back({OscillatoryPoint(0.03, 3, w, 4), -0.01 * (1 - std::exp(-0.03 * w)) - 1e-4 * (n % 3), 2e-4});
  }
  plots.push_back(SweepUzPlot("omega sweep: U_z", samples, FitSweep(samples)));  // 6 entries, fits and bands
  for (const Plot& plot : plots) {
    for (ImageFormat format : {ImageFormat::kPng, ImageFormat::kSvg}) {
      SCOPED_TRACE(plot.title + " " + ImageExtension(format));
      const FigureLayout layout = LayOutFigure(plot, format);
      const FigureLayout drawn = Drawn(plot, format);
      EXPECT_EQ(drawn.legend, layout.legend);
      EXPECT_TRUE(Contains(layout.legend_rect, drawn.legend_rect));
      EXPECT_GE(drawn.box.width(), 0.47);
      EXPECT_LE(drawn.legend_rect.x1, 1.0);
      if (drawn.legend == LegendPlace::kInside) {
        EXPECT_GE(drawn.box.width(), 0.85);
        EXPECT_FALSE(DataWithin(plot, drawn, drawn.legend_rect, 1));
      } else {
        EXPECT_GE(drawn.legend_rect.x0, drawn.box.x1);  // beside the box, not over it
      }
    }
  }
}

// Data through every corner (a sine over many periods): the y axis grows at one end, and the
// legend sits above (below) every datum instead of beside the plot.
TEST(FigureLayoutTest, ACrowdedPlotMakesHeadroomForItsLegend) {
  Plot plot;
  plot.title = "crowded";
  plot.x_label = "t (s)";
  plot.y_label = "Δz (m)";
  Series wave{"Δz = z(t) − z(0)", {}, {}, {}, false, false};
  for (int i = 0; i <= 400; ++i) {
    wave.x.push_back(i * 0.01);
    wave.y.push_back(std::sin(2 * M_PI * 3 * i * 0.01));
  }
  plot.series = {wave, Series{"zero", {0, 4}, {0, 0}, {}, false, true}};
  const FigureLayout layout = LayOutFigure(plot, ImageFormat::kPng);
  ASSERT_EQ(layout.legend, LegendPlace::kInside);
  EXPECT_TRUE(layout.headroom);
  // The data's own range is -1.1..1.1 (5 % of room); one end grows, at the legend's side.
  EXPECT_EQ(layout.axes[3] > 1.1 + 1e-9, layout.legend_top);
  EXPECT_EQ(layout.axes[2] < -1.1 - 1e-9, !layout.legend_top);
  const FigureLayout drawn = Drawn(plot, ImageFormat::kPng);
  EXPECT_GE(drawn.box.width(), 0.85);
  EXPECT_FALSE(DataWithin(plot, drawn, drawn.legend_rect, 1));

  // Given limits are kept as they are: no headroom; the legend stands right of the box.
  plot.limits = std::array<double, 4>{0, 4, -1, 1};
  const FigureLayout fixed = LayOutFigure(plot, ImageFormat::kPng);
  EXPECT_EQ(fixed.legend, LegendPlace::kRight);
  EXPECT_EQ(fixed.axes, *plot.limits);
  EXPECT_NEAR(fixed.legend_rect.x1, 1 - 12.0 / 1200, 1e-9);
}

// A legend too tall for the box stands right of it, as wide as its longest label: short labels
// leave the box most of the page; long ones are drawn smaller rather than take half of it.
TEST(FigureLayoutTest, ATallLegendStandsBesideTheBoxAsWideAsItsText) {
  Plot plot;
  plot.title = "tall";
  plot.x_label = "t (s)";
  plot.y_label = "Δz (m)";
  for (int i = 0; i < 16; ++i) {
    plot.series.push_back({"Ω = " + std::to_string(-10 * (i + 1)) + " rad/s", {0, 1}, {0, 0.01 * i}, {}, false, false});
  }
  const FigureLayout short_labels = LayOutFigure(plot, ImageFormat::kPng);
  ASSERT_EQ(short_labels.legend, LegendPlace::kRight);
  EXPECT_GT(short_labels.box.width(), 0.7);
  EXPECT_LT(short_labels.legend_rect.width(), 0.2);
  for (Series& s : plot.series) s.label += ", so_density = 5000 kg/m^3, replicate bed 2 of 3";
  const FigureLayout long_labels = LayOutFigure(plot, ImageFormat::kPng);
  EXPECT_LE(long_labels.legend_rect.width(), 0.42 + 1e-9);
  EXPECT_LT(long_labels.text_scale, short_labels.text_scale);
  EXPECT_GT(long_labels.box.width(), 0.45);
}

// A bed slice keeps its box to the bed's proportions, its colour bar and legend right of it.
TEST(FigureLayoutTest, ASliceKeepsItsLegendBesideTheColourBar) {
  const Plot plot = BedSlicePlot(20, true);
  const FigureLayout drawn = Drawn(plot, ImageFormat::kPng);
  EXPECT_EQ(drawn.legend, LegendPlace::kRight);
  EXPECT_GT(drawn.legend_rect.x0, drawn.box.x1);
  EXPECT_LE(drawn.legend_rect.x1, 1.0);
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

// Points that differ only in their materials do not read alike: a label ends with the materials
// that are not Table 1's, and a swept material leads it.
TEST(FiguresTest, PointLabelsNameMaterialsThatAreNotTable1s) {
  Point p;
  p.mode = Mode::kOscillatory;
  p.A = 0.03;
  p.f = 3;
  p.Omega = -80;
  const std::string table1 = PointLabel(p, "");
  EXPECT_EQ(table1.find("so_density"), std::string::npos) << table1;
  p.materials.rho_so = 5000;
  EXPECT_EQ(PointLabel(p, ""), table1 + ", so_density = 5000 kg/m^3");
  EXPECT_EQ(PointLabel(p, "Omega"), "Ω = -80 rad/s, so_density = 5000 kg/m^3");
  p.materials.mu_grain_grain = 0.3;
  EXPECT_EQ(PointLabel(p, "so_density"), "so_density = 5000 kg/m^3, Ω = -80 rad/s, grain_friction = 0.3");
  p.materials.rho_so = Materials().rho_so;  // the sweep's Table 1 point still names the swept field
  EXPECT_EQ(PointLabel(p, "so_density"), "so_density = 2500 kg/m^3, Ω = -80 rad/s, grain_friction = 0.3");
}

}  // namespace
}  // namespace sandswim
