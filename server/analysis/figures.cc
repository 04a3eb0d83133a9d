#include "server/analysis/figures.h"

#include "core/materials.h"

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>

#include <plplot.h>

#include "core/branch.h"
#include "core/keys.h"
#include "core/materials.h"
#include "core/text.h"
#include "core/trajectory.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

// Bumped whenever the drawing changes, so files drawn the old way are not served.
constexpr const char* kStyleVersion = "figures-v6";
constexpr int kWidthPx = 1200, kHeightPx = 600;
constexpr PLINT kBackground = 0, kInk = 1, kFirstSeries = 2;  // cmap0 indices

// PLplot's state is global: one drawing at a time in this process.
std::mutex& PlplotMutex() {
  static std::mutex mu;
  return mu;
}

struct Rgb {
  int r, g, b;
};

// Well-separated fixed colours, then golden-angle hues.
Rgb SeriesRgb(size_t i) {
  // Tableau 10, then six more far from them (the paper's Ω sweep has 16 runs).
  static const Rgb kBase[] = {{31, 119, 180},  {255, 127, 14}, {44, 160, 44},   {214, 39, 40},
                              {148, 103, 189}, {140, 86, 75},  {227, 119, 194}, {127, 127, 127},
                              {188, 189, 34},  {23, 190, 207}, {0, 0, 139},     {128, 0, 0},
                              {0, 128, 128},   {255, 0, 255},  {85, 107, 47},   {218, 165, 32}};
  constexpr size_t kBaseCount = sizeof(kBase) / sizeof(kBase[0]);
  if (i < kBaseCount) return kBase[i];
  double h = std::fmod(static_cast<double>(i - kBaseCount) * 137.508 + 15.0, 360.0) / 60.0;
  double s = 0.75, v = (i % 2 == 0) ? 0.80 : 0.60;
  double c = v * s, x = c * (1 - std::fabs(std::fmod(h, 2.0) - 1)), m = v - c;
  double r = 0, g = 0, b = 0;
  switch (static_cast<int>(h)) {
    case 0:
      r = c, g = x;
      break;
    case 1:
      r = x, g = c;
      break;
    case 2:
      g = c, b = x;
      break;
    case 3:
      g = x, b = c;
      break;
    case 4:
      r = x, b = c;
      break;
    default:
      r = c, b = x;
      break;
  }
  return {static_cast<int>(std::lround((r + m) * 255)), static_cast<int>(std::lround((g + m) * 255)),
          static_cast<int>(std::lround((b + m) * 255))};
}

std::string Hex(const Rgb& c) {
  char buf[8];
  std::snprintf(buf, sizeof(buf), "#%02X%02X%02X", c.r, c.g, c.b);
  return buf;
}

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void Add(double v) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  // 5 % of room each side; an empty or flat range gets a width of its own.
  void Pad() {
    if (!std::isfinite(lo)) lo = 0, hi = 1;
    double width = hi - lo;
    if (width <= 0) width = std::max(1e-3, std::fabs(hi) * 0.2);
    double mid = (hi + lo) / 2;
    if (hi - lo <= 0) lo = mid - width / 2, hi = mid + width / 2;
    lo -= 0.05 * width;
    hi += 0.05 * width;
  }
};

// The plot box's edges, in fractions of the page. A plot with discs (a bed slice, narrowed to its
// proportions) keeps its box left of kDiscBoxRight, the colour bar and the legend right of it;
// any other plot's box reaches kBoxRight, with its legend inside (LayOutFigure).
constexpr PLFLT kBoxLeft = 0.085, kBoxRight = 0.97, kDiscBoxRight = 0.56, kBoxBottom = 0.11, kBoxTop = 0.91;
constexpr PLFLT kCharScale = 0.85;  // of PLplot's default character height
// PLplot's default character height on this page, in pixels (both devices: plgchr after plinit).
constexpr double kDefaultCharPx = 18.01;

// Colour map 1 for discs: perceptually ordered, dark violet (low) through blue and green to yellow
// (high), readable in grey and by most colour-blind readers.
void SetDiscColourMap() {
  static const PLFLT kAt[] = {0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0};
  static const Rgb kStops[] = {{68, 1, 84},    {71, 45, 123}, {59, 82, 139},  {44, 114, 142}, {33, 145, 140},
                               {40, 174, 128}, {94, 201, 98}, {173, 220, 48}, {253, 231, 37}};
  constexpr PLINT kCount = sizeof(kAt) / sizeof(kAt[0]);
  PLFLT r[kCount], g[kCount], b[kCount];
  for (PLINT i = 0; i < kCount; ++i) {
    r[i] = kStops[i].r / 255.0;
    g[i] = kStops[i].g / 255.0;
    b[i] = kStops[i].b / 255.0;
  }
  plscmap1n(256);
  plscmap1l(1, kCount, kAt, r, g, b, nullptr);
}

// The range the colour map spans: the values' own; a flat one gets a width of its own.
Range DiscValueRange(const Discs& discs) {
  Range range;
  for (double v : discs.value) range.Add(v);
  if (!std::isfinite(range.lo)) return Range{0, 1};
  if (range.hi > range.lo) return range;
  const double v = range.lo;
  if (v == 0) return Range{0, 1};
  return Range{v - 0.1 * std::fabs(v), v + 0.1 * std::fabs(v)};
}

// Each disc a filled polygon in its value's colour. `px_per_unit`: pixels per axis unit (the larger
// of x's and y's), so a small disc is drawn with fewer vertices.
void DrawDiscs(const Discs& discs, const Range& values, double px_per_unit) {
  std::vector<PLFLT> x, y;
  for (size_t i = 0; i < discs.x.size(); ++i) {
    const double r_px = discs.r[i] * px_per_unit;
    // About 4 px of outline per edge: round to the eye, and the SVG stays small.
    const int n = std::clamp(static_cast<int>(std::ceil(2 * M_PI * r_px / 4)), 8, 32);
    x.resize(static_cast<size_t>(n));
    y.resize(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) {
      const double a = 2 * M_PI * k / n;
      x[static_cast<size_t>(k)] = discs.x[i] + discs.r[i] * std::cos(a);
      y[static_cast<size_t>(k)] = discs.y[i] + discs.r[i] * std::sin(a);
    }
    plcol1(std::clamp((discs.value[i] - values.lo) / (values.hi - values.lo), 0.0, 1.0));
    plfill(n, x.data(), y.data());
  }
}

// ---- Axes of an equal-aspect plot ----
// A box narrowed to its data's proportions (a bed slice is four times as tall as it is wide) has
// little room across: PLplot's own choice of ticks writes the x labels over each other there. So
// such a plot picks its own steps, wide enough apart for their labels, and writes each label as
// its shortest decimal ("0", "0.05").

struct TickSteps {
  double x = 0, y = 0;
};

std::string TickLabel(double value, double step) {
  const int decimals = std::max(0, static_cast<int>(std::ceil(-std::log10(step) - 1e-9)));
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, std::round(value / step) * step);
  std::string label = buf;
  if (label.find('.') != std::string::npos) {
    while (label.back() == '0') label.pop_back();
    if (label.back() == '.') label.pop_back();
  }
  return label == "-0" ? "0" : label;
}

// A label's width in character heights (a digit is about 0.85 of one, '-' and '.' less than half;
// measured on both devices' fonts, rounded up).
double TickLabelWidth(const std::string& label) {
  double width = 0;
  for (char c : label) width += std::isdigit(static_cast<unsigned char>(c)) ? 0.85 : 0.45;
  return width;
}

// How many multiples of `step` lie in [lo, hi].
int TickCount(double lo, double hi, double step) {
  return static_cast<int>(std::floor(hi / step + 1e-9) - std::ceil(lo / step - 1e-9)) + 1;
}

// The smallest step of 1, 2 or 5 times a power of ten, at least a sixth of [lo, hi], whose labels
// keep apart: side by side along x (neighbours 0.6 of a character height apart), or stacked along
// y (two character heights from one to the next).
double TickStep(double lo, double hi, double px_per_unit, double char_px, bool along_x) {
  const double least = (hi - lo) / 6;
  double decade = std::pow(10.0, std::floor(std::log10(least)));
  for (;; decade *= 10) {
    for (double m : {1.0, 2.0, 5.0}) {
      const double step = m * decade;
      if (step < least * (1 - 1e-9)) continue;
      const double step_px = step * px_per_unit;
      if (!along_x) {
        if (step_px >= 2 * char_px) return step;
        continue;
      }
      // Counted, not summed: at most seven ticks, however far from 0 the range lies.
      const double first = std::ceil(lo / step - 1e-9);
      bool apart = true;
      for (int k = 0; k + 1 < TickCount(lo, hi, step) && apart; ++k) {
        const double t = (first + k) * step;
        const double half_widths = (TickLabelWidth(TickLabel(t, step)) + TickLabelWidth(TickLabel(t + step, step))) / 2;
        apart = step_px >= (half_widths + 0.6) * char_px;
      }
      if (apart) return step;
    }
  }
}

void ShortestTickLabel(PLINT axis, PLFLT value, char* label, PLINT length, PLPointer data) {
  const TickSteps& steps = *static_cast<const TickSteps*>(data);
  std::snprintf(label, static_cast<size_t>(length), "%s",
                TickLabel(value, axis == PL_X_AXIS ? steps.x : steps.y).c_str());
}

// ---- Layout (LayOutFigure) ----

// The axes' ranges: the limits as they are, or the data's with 5 % of room.
std::array<double, 4> DataAxes(const Plot& plot) {
  if (plot.limits) return *plot.limits;
  Range xr, yr;
  for (const Series& s : plot.series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      xr.Add(s.x[i]);
      const double e = s.y_err.empty() ? 0 : std::fabs(s.y_err[i]);
      yr.Add(s.y[i] - e);
      yr.Add(s.y[i] + e);
    }
  }
  if (plot.discs) {
    const Discs& d = *plot.discs;
    for (size_t i = 0; i < d.x.size(); ++i) {
      xr.Add(d.x[i] - d.r[i]);
      xr.Add(d.x[i] + d.r[i]);
      yr.Add(d.y[i] - d.r[i]);
      yr.Add(d.y[i] + d.r[i]);
    }
  }
  xr.Pad();
  yr.Pad();
  return {xr.lo, xr.hi, yr.lo, yr.hi};
}

// A label's width in character heights as PLplot sizes the legend's frame by it: pngcairo measures
// the text it draws (DejaVu Sans); the svg device has no measure of its own, and PLplot falls back
// on its Hershey fonts (wider, and twice as wide for a Greek letter or a math sign). Measured per
// kind of character on both devices, then 5 % added. A PLplot escape ("#d", "#u") draws nothing;
// "##" draws '#'.
double LabelWidth(const std::string& label, ImageFormat format) {
  const bool svg = format == ImageFormat::kSvg;
  double width = 0;
  for (size_t k = 0; k < label.size(); ++k) {
    const unsigned char c = static_cast<unsigned char>(label[k]);
    if (c == '#' && k + 1 < label.size()) {
      if (label[k + 1] != '#') {
        ++k;
        continue;
      }
      ++k;
    }
    if ((c & 0xC0) == 0x80) continue;  // inside a UTF-8 sequence: counted at its first byte
    if (c >= 0x80) {
      width += svg ? 2.05 : 1.1;  // Ω, Δ, −, ≤, ±
    } else if (c == ' ') {
      width += svg ? 0.83 : 0.48;
    } else if (std::strchr(".,:;'!|()[]{}/-_ijlftrI", c) != nullptr) {
      width += svg ? 0.62 : 0.45;
    } else if (std::strchr("mwMW%", c) != nullptr) {
      width += svg ? 1.35 : 1.31;
    } else if (std::strchr("=+<>~*&@?#^", c) != nullptr) {
      width += svg ? 1.22 : 1.15;
    } else if (std::isupper(c)) {
      width += svg ? 1.01 : 0.95;
    } else {
      width += svg ? 1.01 : 0.82;  // digits and the other lower-case letters
    }
  }
  return 1.05 * width;
}

// The legend's frame, laid out as pllegend lays it out: a border of 0.4 character and a gap of
// 0.5 around the text, one sample (line or symbol) of kSamplePx, a row of 2 characters per entry.
// Its characters are measured in the page's y fraction, used as is along x (as pllegend does).
constexpr double kSamplePx = 34, kTextOffset = 0.5, kTextSpacing = 2.0;
struct LegendSize {
  double width = 0, height = 0;  // fractions of the page
};
LegendSize EstimateLegend(const Plot& plot, ImageFormat format, double text_scale) {
  const double char_y = kCharScale * kDefaultCharPx / kHeightPx;
  double longest = 0;
  for (const Series& s : plot.series) longest = std::max(longest, LabelWidth(s.label, format));
  LegendSize size;
  size.width = (0.8 + kTextOffset) * char_y + kSamplePx / kWidthPx + longest * text_scale * kDefaultCharPx / kWidthPx;
  size.height = static_cast<double>(plot.series.size()) * kTextSpacing * char_y;
  return size;
}

// Clearances kept between the legend's frame and the data: a marker's radius with its error bar's
// cap, a line's width, in pixels; and the legend's inset from the box's edges.
constexpr double kMarkerClearPx = 9, kLineClearPx = 4, kInsetPx = 10, kLegendGapPx = 14, kRightMarginPx = 12;

// Whether the segment a-b (page fractions) meets the rectangle r (Liang-Barsky clipping).
bool SegmentMeets(const PageRect& r, double ax, double ay, double bx, double by) {
  double t0 = 0, t1 = 1;
  const double dx = bx - ax, dy = by - ay;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {ax - r.x0, r.x1 - ax, ay - r.y0, r.y1 - ay};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double t = q[i] / p[i];
    if (p[i] < 0) {
      t0 = std::max(t0, t);
    } else {
      t1 = std::min(t1, t);
    }
    if (t0 > t1) return false;
  }
  return true;
}

PageRect Grown(const PageRect& r, double px) {
  return {r.x0 - px / kWidthPx, r.x1 + px / kWidthPx, r.y0 - px / kHeightPx, r.y1 + px / kHeightPx};
}

// How many of the plot's data (markers, error bars, line segments) meet `legend` on the page.
int DataMet(const Plot& plot, const PageRect& box, const std::array<double, 4>& axes, const PageRect& legend) {
  const auto page_x = [&](double x) { return box.x0 + (x - axes[0]) / (axes[1] - axes[0]) * box.width(); };
  const auto page_y = [&](double y) { return box.y0 + (y - axes[2]) / (axes[3] - axes[2]) * box.height(); };
  int met = 0;
  for (const Series& s : plot.series) {
    if (s.markers) {
      const PageRect near = Grown(legend, kMarkerClearPx);
      for (size_t i = 0; i < s.x.size(); ++i) {
        const double x = page_x(s.x[i]);
        const double e = s.y_err.empty() ? 0 : std::fabs(s.y_err[i]);
        if (SegmentMeets(near, x, page_y(s.y[i] - e), x, page_y(s.y[i] + e))) ++met;
      }
    } else {
      const PageRect near = Grown(legend, kLineClearPx);
      for (size_t i = 0; i + 1 < s.x.size(); ++i) {
        if (SegmentMeets(near, page_x(s.x[i]), page_y(s.y[i]), page_x(s.x[i + 1]), page_y(s.y[i + 1]))) ++met;
      }
      if (s.x.size() == 1 && SegmentMeets(near, page_x(s.x[0]), page_y(s.y[0]), page_x(s.x[0]), page_y(s.y[0]))) ++met;
    }
  }
  return met;
}

// The legend's rectangle of `size` in a corner of `box`, kInsetPx from its edges.
PageRect CornerRect(const PageRect& box, const LegendSize& size, bool top, bool left) {
  PageRect r;
  r.x0 = left ? box.x0 + kInsetPx / kWidthPx : box.x1 - kInsetPx / kWidthPx - size.width;
  r.x1 = r.x0 + size.width;
  r.y1 = top ? box.y1 - kInsetPx / kHeightPx : box.y0 + kInsetPx / kHeightPx + size.height;
  r.y0 = r.y1 - size.height;
  return r;
}

// Draws under the PLplot mutex into `path`; `drawn` (optional) gets the layout as drawn. REQUIRES:
// CheckPlot(plot) passed.
void Draw(const Plot& plot, ImageFormat format, const std::string& path, FigureLayout* drawn) {
  std::lock_guard<std::mutex> lock(PlplotMutex());
  plsdev(format == ImageFormat::kSvg ? "svg" : "pngcairo");
  plsfnam(path.c_str());
  plspage(0, 0, kWidthPx, kHeightPx, 0, 0);
  const PLINT n_series = static_cast<PLINT>(plot.series.size());
  plscmap0n(kFirstSeries + n_series);
  plscol0(kBackground, 255, 255, 255);
  plscol0(kInk, 0, 0, 0);
  for (PLINT i = 0; i < n_series; ++i) {
    Rgb c = SeriesRgb(static_cast<size_t>(i));
    plscol0(kFirstSeries + i, c.r, c.g, c.b);
  }
  plinit();
  pladv(0);
  plschr(0, kCharScale);

  const FigureLayout layout = LayOutFigure(plot, format);
  const PageRect& area = layout.box;
  const Range xr{layout.axes[0], layout.axes[1]}, yr{layout.axes[2], layout.axes[3]};
  if (plot.equal_aspect) {
    plvpas(area.x0, area.x1, area.y0, area.y1, (yr.hi - yr.lo) / (xr.hi - xr.lo));
  } else {
    plvpor(area.x0, area.x1, area.y0, area.y1);
  }
  // Plain decimals on the axes (no "(x10^-2)" factor floating above the axis).
  plsxax(8, 0);
  plsyax(8, 0);
  PLFLT box_x0 = 0, box_x1 = 0, box_y0 = 0, box_y1 = 0;
  plgvpd(&box_x0, &box_x1, &box_y0, &box_y1);
  const PLFLT box_w_px = (box_x1 - box_x0) * kWidthPx, box_h_px = (box_y1 - box_y0) * kHeightPx;
  // Offsets right of the box are in units of the box's width: a box narrowed to its aspect keeps
  // the usual gaps in pixels.
  const PLFLT per_usual_width = plot.equal_aspect ? area.width() * kWidthPx / box_w_px : 1.0;

  plwind(xr.lo, xr.hi, yr.lo, yr.hi);
  Range values;
  if (plot.discs) {
    // Under the frame and the series, so both stay visible over the grains.
    SetDiscColourMap();
    values = DiscValueRange(*plot.discs);
    DrawDiscs(*plot.discs, values, std::max(box_w_px / (xr.hi - xr.lo), box_h_px / (yr.hi - yr.lo)));
  }
  plcol0(kInk);
  plwidth(1);
  if (plot.equal_aspect) {
    PLFLT char_mm = 0, sub_x0 = 0, sub_x1 = 0, sub_y0 = 0, sub_y1 = 0, unused = 0;
    plgchr(&unused, &char_mm);
    plgspa(&sub_x0, &sub_x1, &sub_y0, &sub_y1);
    const double char_px = char_mm * kWidthPx / (sub_x1 - sub_x0);
    const double x_px_per_unit = box_w_px / (xr.hi - xr.lo);
    TickSteps steps{TickStep(xr.lo, xr.hi, x_px_per_unit, char_px, true),
                    TickStep(yr.lo, yr.hi, box_h_px / (yr.hi - yr.lo), char_px, false)};
    // A box too narrow for three x labels at the usual size gets them a quarter smaller: "-0.05 0
    // 0.05" under a slice 0.18 m wide says more than a lone "0".
    PLFLT x_label_scale = 1;
    if (TickCount(xr.lo, xr.hi, steps.x) < 3) {
      const double smaller = TickStep(xr.lo, xr.hi, x_px_per_unit, 0.75 * char_px, true);
      if (TickCount(xr.lo, xr.hi, smaller) > TickCount(xr.lo, xr.hi, steps.x)) {
        steps.x = smaller;
        x_label_scale = 0.75;
      }
    }
    plslabelfunc(ShortestTickLabel, &steps);
    plschr(0, kCharScale * x_label_scale);
    plbox("bcnsto", steps.x, 0, "", 0, 0);
    plschr(0, kCharScale);
    plbox("", 0, 0, "bcnstvo", steps.y, 0);
    plslabelfunc(nullptr, nullptr);  // the colour bar labels its own axis
  } else {
    plbox("bcnst", 0, 0, "bcnstv", 0, 0);
  }
  // A zero line where U_z or Δz changes sign (not across a slice of the bed).
  if (!plot.discs && yr.lo < 0 && yr.hi > 0) {
    pllsty(3);
    PLFLT zx[2] = {xr.lo, xr.hi}, zy[2] = {0, 0};
    plline(2, zx, zy);
    pllsty(1);
  }
  pllab(plot.x_label.c_str(), plot.y_label.c_str(), plot.title.c_str());

  std::vector<PLINT> opts, colors, styles, symbol_numbers, text_colors;
  std::vector<PLFLT> widths, symbol_scales;
  std::vector<const char*> texts, symbols;
  for (PLINT i = 0; i < n_series; ++i) {
    const Series& s = plot.series[static_cast<size_t>(i)];
    const PLINT color = kFirstSeries + i;
    plcol0(color);
    std::vector<PLFLT> x(s.x.begin(), s.x.end()), y(s.y.begin(), s.y.end());
    const PLINT n = static_cast<PLINT>(x.size());
    if (s.markers) {
      if (!s.y_err.empty()) {
        std::vector<PLFLT> lo(x.size()), hi(x.size());
        for (size_t k = 0; k < x.size(); ++k) {
          lo[k] = s.y[k] - std::fabs(s.y_err[k]);
          hi[k] = s.y[k] + std::fabs(s.y_err[k]);
        }
        plerry(n, x.data(), lo.data(), hi.data());
      }
      plssym(0, 1.3);
      plpoin(n, x.data(), y.data(), 17);
    } else {
      pllsty(s.dashed ? 2 : 1);
      if (plot.discs) {
        // A halo of background under the line keeps it visible on grains of any colour.
        plcol0(kBackground);
        plwidth(5);
        plline(n, x.data(), y.data());
        plcol0(color);
        plwidth(2.5);
      } else {
        plwidth(1.5);
      }
      plline(n, x.data(), y.data());
      plwidth(1);
      pllsty(1);
    }
    opts.push_back(s.markers ? PL_LEGEND_SYMBOL : PL_LEGEND_LINE);
    colors.push_back(color);
    styles.push_back(s.dashed ? 2 : 1);
    widths.push_back(plot.discs ? 2.5 : 1.5);
    symbol_numbers.push_back(1);
    symbol_scales.push_back(0.8);
    symbols.push_back("●");
    text_colors.push_back(kInk);
    texts.push_back(s.label.c_str());
  }
  // With discs, the colour bar sits right of the box, the legend right of the colour bar: both
  // are placed in units of the box's width and centred on it vertically, so they never overlap.
  // Without, the legend goes where LayOutFigure put it.
  PLFLT legend_x = kLegendGapPx / box_w_px, legend_y = 0, sample_width = kSamplePx / box_w_px;
  PLINT position = PL_POSITION_RIGHT | PL_POSITION_OUTSIDE;
  PLFLT text_scale = layout.text_scale;
  if (plot.discs) {
    legend_x = 0.02 * per_usual_width;
    sample_width = 0.06 * per_usual_width;
    constexpr PLFLT kGapPx = 14, kBarWidthPx = 22;
    const PLFLT bar_x = kGapPx / box_w_px;
    const char* axis_opts[] = {"bcvtm"};
    const char* labels[] = {plot.discs->value_label.c_str()};
    PLINT label_opts[] = {PL_COLORBAR_LABEL_TOP};
    PLFLT ticks[] = {0}, range[] = {values.lo, values.hi};
    PLINT sub_ticks[] = {0}, n_values[] = {2};
    const PLFLT* values_of_axis[] = {range};
    PLFLT bar_width = 0, bar_height = 0;
    plcol0(kInk);
    plcolorbar(&bar_width, &bar_height, PL_COLORBAR_GRADIENT | PL_COLORBAR_ORIENT_TOP,
               PL_POSITION_RIGHT | PL_POSITION_OUTSIDE | PL_POSITION_VIEWPORT, bar_x, 0.0, kBarWidthPx / box_w_px, 0.8,
               kBackground, kInk, 1, 0, 0, kInk, 1, 1, label_opts, labels, 1, axis_opts, ticks, sub_ticks, n_values,
               values_of_axis);
    legend_x = bar_x + bar_width + kGapPx / box_w_px;
    // Labels longer than the space right of the colour bar holds (about 46 characters at the
    // usual size beside the usual box) are drawn smaller rather than cut at the page's edge.
    const PLFLT usual_room_px = (1 - kDiscBoxRight - 0.02 * (kDiscBoxRight - kBoxLeft)) * kWidthPx;
    const PLFLT fits = 46 * (kWidthPx - box_x1 * kWidthPx - legend_x * box_w_px) / usual_room_px;
    size_t longest = 0;
    for (const Series& s : plot.series) {
      size_t chars = 0;
      for (size_t k = 0; k < s.label.size(); ++k) {
        if (s.label[k] == '#' && k + 1 < s.label.size()) {  // a PLplot escape (#d, #u) draws nothing
          ++k;
          continue;
        }
        if ((static_cast<unsigned char>(s.label[k]) & 0xC0) != 0x80) ++chars;  // UTF-8 code points
      }
      longest = std::max(longest, chars);
    }
    if (longest > fits) text_scale *= fits / static_cast<PLFLT>(longest);
  } else if (layout.legend == LegendPlace::kInside) {
    position = PL_POSITION_INSIDE | (layout.legend_top ? PL_POSITION_TOP : PL_POSITION_BOTTOM) |
               (layout.legend_left ? PL_POSITION_LEFT : PL_POSITION_RIGHT);
    legend_x = kInsetPx / box_w_px;
    legend_y = kInsetPx / box_h_px;
  }
  FigureLayout as_drawn = layout;
  as_drawn.box = {box_x0, box_x1, box_y0, box_y1};
  as_drawn.text_scale = text_scale;
  if (n_series > 0) {
    PLFLT legend_width = 0, legend_height = 0;
    plcol0(kInk);
    pllegend(&legend_width, &legend_height, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX, position, legend_x,
             legend_y, sample_width, kBackground, kInk, 1, 0, 0, n_series, opts.data(), kTextOffset, text_scale,
             kTextSpacing, 0.0, text_colors.data(), texts.data(), nullptr, nullptr, nullptr, nullptr, colors.data(),
             styles.data(), widths.data(), colors.data(), symbol_scales.data(), symbol_numbers.data(), symbols.data());
    // Where PLplot put it, from the size it reports (in units of the box).
    const double w = legend_width * (box_x1 - box_x0), h = legend_height * (box_y1 - box_y0);
    PageRect r;
    if (position & PL_POSITION_INSIDE) {
      r.x0 = layout.legend_left ? box_x0 + legend_x * (box_x1 - box_x0) : box_x1 - legend_x * (box_x1 - box_x0) - w;
      r.y1 = layout.legend_top ? box_y1 - legend_y * (box_y1 - box_y0) : box_y0 + legend_y * (box_y1 - box_y0) + h;
    } else {
      r.x0 = box_x1 + legend_x * (box_x1 - box_x0);
      r.y1 = (box_y0 + box_y1) / 2 + h / 2;
    }
    r.x1 = r.x0 + w;
    r.y0 = r.y1 - h;
    as_drawn.legend_rect = r;
  }
  if (drawn != nullptr) *drawn = as_drawn;
  plend();
}

std::string Signed(double v) { return Num(v, 4); }

}  // namespace

const char* FigureStyleVersion() { return kStyleVersion; }

const char* ImageExtension(ImageFormat format) { return format == ImageFormat::kSvg ? "svg" : "png"; }
const char* ImageContentType(ImageFormat format) { return format == ImageFormat::kSvg ? "image/svg+xml" : "image/png"; }

void to_json(json& j, const Plot& p) {
  json series = json::array();
  for (const Series& s : p.series) {
    series.push_back(
        {{"label", s.label}, {"x", s.x}, {"y", s.y}, {"y_err", s.y_err}, {"markers", s.markers}, {"dashed", s.dashed}});
  }
  j = {{"title", p.title}, {"x_label", p.x_label}, {"y_label", p.y_label}, {"series", series}};
  // Only when set: the JSON (and so the cache name) of a plot without them stays what it was.
  if (p.discs) {
    const Discs& d = *p.discs;
    j["discs"] = {{"x", d.x}, {"y", d.y}, {"r", d.r}, {"value", d.value}, {"value_label", d.value_label}};
  }
  if (p.equal_aspect) j["equal_aspect"] = true;
  if (p.limits) j["limits"] = *p.limits;
}

Status CheckPlot(const Plot& plot) {
  if (plot.series.empty() && !plot.discs)
    return Status::InvalidArgument("plot", "nothing to draw: no series and no discs");
  for (const Series& s : plot.series) {
    if (s.x.size() != s.y.size() || (!s.y_err.empty() && s.y_err.size() != s.y.size())) {
      return Status::InvalidArgument("plot", "series \"" + s.label + "\": x, y and errors differ in length");
    }
    for (const auto* v : {&s.x, &s.y, &s.y_err}) {
      for (double d : *v) {
        if (!std::isfinite(d))
          return Status::InvalidArgument("plot", "series \"" + s.label + "\" has a non-finite value");
      }
    }
  }
  if (plot.discs) {
    const Discs& d = *plot.discs;
    const size_t n = d.x.size();
    if (d.y.size() != n || d.r.size() != n || d.value.size() != n)
      return Status::InvalidArgument("plot", "discs: x, y, r and value differ in length");
    for (const auto* v : {&d.x, &d.y, &d.r, &d.value}) {
      for (double x : *v) {
        if (!std::isfinite(x)) return Status::InvalidArgument("plot", "discs: a non-finite value");
      }
    }
    for (double r : d.r) {
      if (r <= 0) return Status::InvalidArgument("plot", "discs: a radius of " + Num(r, 4) + ", not > 0");
    }
  }
  if (plot.limits) {
    const std::array<double, 4>& l = *plot.limits;
    for (double v : l) {
      if (!std::isfinite(v)) return Status::InvalidArgument("plot", "limits: a non-finite value");
    }
    if (!(l[0] < l[1]) || !(l[2] < l[3]))
      return Status::InvalidArgument("plot", "limits: each axis needs lo < hi (x_lo, x_hi, y_lo, y_hi)");
  }
  return Status::Ok();
}

Result<Plot> PlotFromJson(const json& j) {
  auto bad = [](const std::string& what) { return Status::InvalidArgument("plot", what); };
  if (!j.is_object()) return bad("a plot is a JSON object");
  Plot p;
  for (const char* key : {"title", "x_label", "y_label"}) {
    if (!j.contains(key) || !j[key].is_string()) return bad(std::string("\"") + key + "\" must be a string");
  }
  p.title = j["title"].get<std::string>();
  p.x_label = j["x_label"].get<std::string>();
  p.y_label = j["y_label"].get<std::string>();
  if (!j.contains("series") || !j["series"].is_array()) return bad("\"series\" must be an array");
  for (const json& sj : j["series"]) {
    Series s;
    if (!sj.is_object() || !sj.contains("label") || !sj["label"].is_string())
      return bad("every series needs a string \"label\"");
    s.label = sj["label"].get<std::string>();
    for (auto [key, out] : {std::pair{"x", &s.x}, std::pair{"y", &s.y}, std::pair{"y_err", &s.y_err}}) {
      if (!sj.contains(key) || !sj[key].is_array())
        return bad("series \"" + s.label + "\": \"" + key + "\" must be an array");
      for (const json& v : sj[key]) {
        if (!v.is_number()) return bad("series \"" + s.label + "\": \"" + key + "\" holds a non-number");
        out->push_back(v.get<double>());
      }
    }
    for (auto [key, out] : {std::pair{"markers", &s.markers}, std::pair{"dashed", &s.dashed}}) {
      if (!sj.contains(key)) continue;
      if (!sj[key].is_boolean()) return bad("series \"" + s.label + "\": \"" + key + "\" must be true or false");
      *out = sj[key].get<bool>();
    }
    p.series.push_back(std::move(s));
  }
  if (j.contains("discs")) {
    const json& dj = j["discs"];
    if (!dj.is_object()) return bad("\"discs\" must be an object");
    Discs d;
    if (!dj.contains("value_label") || !dj["value_label"].is_string())
      return bad("discs: \"value_label\" must be a string");
    d.value_label = dj["value_label"].get<std::string>();
    for (auto [key, out] :
         {std::pair{"x", &d.x}, std::pair{"y", &d.y}, std::pair{"r", &d.r}, std::pair{"value", &d.value}}) {
      if (!dj.contains(key) || !dj[key].is_array()) return bad(std::string("discs: \"") + key + "\" must be an array");
      for (const json& v : dj[key]) {
        if (!v.is_number()) return bad(std::string("discs: \"") + key + "\" holds a non-number");
        out->push_back(v.get<double>());
      }
    }
    p.discs = std::move(d);
  }
  if (j.contains("equal_aspect")) {
    if (!j["equal_aspect"].is_boolean()) return bad("\"equal_aspect\" must be true or false");
    p.equal_aspect = j["equal_aspect"].get<bool>();
  }
  if (j.contains("limits")) {
    const json& lj = j["limits"];
    if (!lj.is_array() || lj.size() != 4)
      return bad("\"limits\" must be an array of 4 numbers (x_lo, x_hi, y_lo, y_hi)");
    std::array<double, 4> limits{};
    for (size_t i = 0; i < 4; ++i) {
      if (!lj[i].is_number()) return bad("\"limits\" holds a non-number");
      limits[i] = lj[i].get<double>();
    }
    p.limits = limits;
  }
  return p;
}

std::string SeriesColor(size_t i) { return Hex(SeriesRgb(i)); }

FigureLayout LayOutFigure(const Plot& plot, ImageFormat format) {
  FigureLayout layout;
  layout.axes = DataAxes(plot);
  const size_t n = plot.series.size();
  layout.text_scale = n > 12 ? 0.65 : 0.75;
  layout.legend = n > 0 ? LegendPlace::kRight : LegendPlace::kNone;
  if (plot.discs) {
    layout.box = {kBoxLeft, kDiscBoxRight, kBoxBottom, kBoxTop};
    return layout;  // the legend stands right of the colour bar, which PLplot sizes
  }
  layout.box = {kBoxLeft, kBoxRight, kBoxBottom, kBoxTop};
  if (n == 0) return layout;
  const PageRect box = layout.box;
  const LegendSize size = EstimateLegend(plot, format, layout.text_scale);
  if (size.width <= 0.7 * box.width() && size.height <= 0.85 * box.height()) {
    // A free corner: top right, top left, bottom right, bottom left, the first that is.
    struct Corner {
      bool top, left;
    };
    int fewest = std::numeric_limits<int>::max();
    Corner best{true, false};
    for (const Corner c : {Corner{true, false}, Corner{true, true}, Corner{false, false}, Corner{false, true}}) {
      const int met = DataMet(plot, box, layout.axes, CornerRect(box, size, c.top, c.left));
      if (met < fewest) fewest = met, best = c;
      if (met == 0) break;
    }
    // None: the corner with the fewest data gets room of its own, the y axis grown at its end so
    // that every datum (with a marker's clearance) stays below (above) the legend.
    const double taken = (size.height + (kInsetPx + kMarkerClearPx) / kHeightPx) / box.height();
    if (fewest == 0 || (!plot.limits && taken <= 0.45)) {
      layout.legend = LegendPlace::kInside;
      layout.legend_top = best.top;
      layout.legend_left = best.left;
      layout.legend_rect = CornerRect(box, size, best.top, best.left);
      if (fewest > 0) {
        layout.headroom = true;
        const double span = (layout.axes[3] - layout.axes[2]) / (1 - taken);
        if (best.top) {
          layout.axes[3] = layout.axes[2] + span;
        } else {
          layout.axes[2] = layout.axes[3] - span;
        }
      }
      return layout;
    }
  }
  // Right of the box, as wide as its longest label up to kMaxRightWidth of the page (longer labels
  // are drawn smaller), centred on the box vertically; the box takes the rest of the width.
  constexpr double kMaxRightWidth = 0.42;
  LegendSize right = size;
  if (right.width > kMaxRightWidth) {
    const double frame = EstimateLegend(plot, format, 0).width;
    layout.text_scale *= (kMaxRightWidth - frame) / (right.width - frame);
    right = EstimateLegend(plot, format, layout.text_scale);
  }
  layout.box.x1 = 1 - (kRightMarginPx + kLegendGapPx) / kWidthPx - right.width;
  layout.legend_rect.x0 = layout.box.x1 + kLegendGapPx / kWidthPx;
  layout.legend_rect.x1 = layout.legend_rect.x0 + right.width;
  layout.legend_rect.y0 = (box.y0 + box.y1 - right.height) / 2;
  layout.legend_rect.y1 = layout.legend_rect.y0 + right.height;
  return layout;
}

Status DrawPlotToFile(const Plot& plot, ImageFormat format, const std::string& path, FigureLayout* drawn) {
  SANDSWIM_RETURN_IF_ERROR(CheckPlot(plot));
  Draw(plot, format, path, drawn);
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  if (ec || size == 0) return Status::IOError("PLplot wrote nothing to " + path + " (disk full?)");
  return Status::Ok();
}

Result<std::string> RenderPlot(const Plot& plot, ImageFormat format) {
  SANDSWIM_RETURN_IF_ERROR(CheckPlot(plot));
  std::string pattern = (std::filesystem::temp_directory_path() / "sandswim-figure-XXXXXX").string();
  int fd = mkstemp(pattern.data());
  if (fd < 0) return Status::IOError("cannot make a temporary file for a figure in " + pattern);
  close(fd);
  Status drawn = DrawPlotToFile(plot, format, pattern);
  std::string bytes;
  if (drawn.ok()) {
    std::ifstream in(pattern, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::error_code ec;
  std::filesystem::remove(pattern, ec);
  if (!drawn.ok()) return drawn;
  return bytes;
}

// ---- Builders ----------------------------------------------------------------------------------

std::string PointLabel(const Point& p, const std::string& param) {
  // Materials that are not Table 1's close every label (points differing only in them must not read
  // alike); a swept material leads it, like a swept drive parameter.
  const std::string materials = MaterialsLabel(p.materials);
  const auto with_materials = [&](std::string label) {
    return materials.empty() ? label : label + ", " + materials;
  };
  const std::string omega = "Ω = " + Signed(p.Omega) + " rad/s";
  if (param == "Omega") return with_materials(omega);
  if (param == "A") return with_materials("A = " + Num(p.A, 4) + " m, " + omega);
  if (param == "f") return with_materials("f = " + Num(p.f, 4) + " Hz, " + omega);
  if (const MaterialField* m = FindMaterialField(param)) {
    const std::string rest = MaterialsLabel(p.materials, m->name);
    return std::string(m->name) + " = " + Num(p.materials.*m->member, 4) +
           (m->unit.empty() ? "" : " " + std::string(m->unit)) + ", " + omega + (rest.empty() ? "" : ", " + rest);
  }
  std::string label = std::string(ModeName(p.mode));
  if (p.has_vibration()) label += ", A = " + Num(p.A, 4) + " m, f = " + Num(p.f, 4) + " Hz";
  if (p.mode == Mode::kOscillatory) label += ", " + omega;
  if (p.has_constant_rotation()) label += ", ω = " + Num(p.omega, 4) + " rad/s (" + std::string(AxisName(p.axis)) + ")";
  return with_materials(label);
}

Plot RunTrajectoryPlot(int64_t run_id, const Point& point, const api::Trajectory& trajectory,
                       const api::RunResult* result) {
  Plot plot;
  plot.title = "run " + std::to_string(run_id) + ": " + PointLabel(point, "");
  plot.x_label = "t (s)";
  plot.y_label = "displacement of the SO (m)";
  Series dz{"Δz = z(t) − z(0)", trajectory.t, {}, {}, false, false};
  Series dx{"Δx = x(t) − x(0)", trajectory.t, {}, {}, false, true};
  double z0 = trajectory.z.empty() ? 0 : trajectory.z.front();
  double x0 = trajectory.x.empty() ? 0 : trajectory.x.front();
  for (double z : trajectory.z) dz.y.push_back(z - z0);
  for (double x : trajectory.x) dx.y.push_back(x - x0);
  plot.series = {dz, dx};
  if (result != nullptr && result->uz && result->uz_blocks >= 1 && trajectory.t.size() >= 2) {
    // z at t, linearly interpolated in the stored (possibly downsampled) trajectory.
    auto z_at = [&](double t) {
      auto it = std::lower_bound(trajectory.t.begin(), trajectory.t.end(), t);
      if (it == trajectory.t.end()) return trajectory.z.back() - z0;
      size_t i = static_cast<size_t>(it - trajectory.t.begin());
      if (i == 0 || trajectory.t[i] == t) return trajectory.z[i] - z0;
      double w = (t - trajectory.t[i - 1]) / (trajectory.t[i] - trajectory.t[i - 1]);
      return trajectory.z[i - 1] + w * (trajectory.z[i] - trajectory.z[i - 1]) - z0;
    };
    Series blocks{result->block_kind == "block" ? "Δz at the window's block boundaries"
                                                : "Δz once per period (the window's blocks)",
                  {},
                  {},
                  {},
                  true,
                  false};
    for (int k = 0; k <= result->uz_blocks; ++k) {
      double t = result->window_t0 + k * result->block_s;
      blocks.x.push_back(t);
      blocks.y.push_back(z_at(t));
    }
    const double start = blocks.y.front();
    // U_z goes in the legend, not the title: a title holding the point and U_z overflows the plot.
    Series line{"slope U#dz#u: " + DescribeUz(*result),
                {result->window_t0, result->window_t1},
                {start, start + *result->uz * (result->window_t1 - result->window_t0)},
                {},
                false,
                true};
    plot.series.push_back(std::move(blocks));
    plot.series.push_back(std::move(line));
  }
  return plot;
}

std::string PlplotLiteral(const std::string& text) {
  std::string out;
  for (char c : text) {
    if (c == '#') out += '#';
    out += c;
  }
  return out;
}

Plot SweepTrajectoriesPlot(const std::string& title, const std::vector<RunTrajectory>& runs, const std::string& param,
                           Coordinate coordinate) {
  Plot plot;
  plot.title = title;
  plot.x_label = "t (s)";
  plot.y_label = coordinate == Coordinate::kZ ? "Δz = z(t) − z(0) (m)" : "Δx = x(t) − x(0) (m)";
  std::set<int> replicates;
  for (const RunTrajectory& r : runs) replicates.insert(r.replicate);
  for (const RunTrajectory& r : runs) {
    Series s{
        PointLabel(r.point, param) + (replicates.size() > 1 ? ", replicate bed " + std::to_string(r.replicate) : ""),
        r.trajectory.t,
        {},
        {},
        false,
        false};
    const std::vector<double>& v = coordinate == Coordinate::kZ ? r.trajectory.z : r.trajectory.x;
    const double v0 = v.empty() ? 0 : v.front();
    for (double c : v) s.y.push_back(c - v0);
    plot.series.push_back(std::move(s));
  }
  return plot;
}

namespace {

// The outline of a fitted law's 95 % band over [from, to] (drawn at side * x): along its upper
// edge and back along its lower one, one dashed series. `law(x)` is {value, half width}.
template <typename Law>
Series BandOutline(const std::string& branch, double from, double to, double side, Law law) {
  Series band{branch + " fit: 95 % band", {}, {}, {}, false, true};
  constexpr int kSteps = 60;
  for (int k = 0; k <= 2 * kSteps + 1; ++k) {
    const bool upper = k <= kSteps;
    const int i = upper ? k : 2 * kSteps + 1 - k;
    const double x = from + (to - from) * i / kSteps;
    const auto [value, half] = law(x);
    band.x.push_back(side * x);
    band.y.push_back(upper ? value + half : value - half);
  }
  return band;
}

}  // namespace

double SweptValue(const Point& p, const std::string& param) {
  if (const MaterialField* m = FindMaterialField(param)) return p.materials.*m->member;
  return param == "A" ? p.A : param == "f" ? p.f : p.Omega;
}

Plot SweepUzPlot(const std::string& title, const std::vector<SweepSample>& samples, const SweepFits& fits) {
  const std::string& param = fits.choice.param;
  Plot plot;
  plot.title = title;
  plot.y_label = "U#dz#u (m/s), bars: 95 % interval";
  const MaterialField* material = FindMaterialField(param);
  plot.x_label = material ? std::string(material->name) + (material->unit.empty() ? "" : " (" + std::string(material->unit) + ")")
                 : param == "A" ? "A (m)"
                 : param == "f" ? "f (Hz)"
                                : "Ω (rad/s)";
  auto x_of = [&](const Point& p) { return SweptValue(p, param); };
  for (const Branch branch : {Branch::kRising, Branch::kSinking}) {
    Series s{std::string(BranchName(branch)) + " (" + std::string(OmegaSide(branch)) + ")",
             {},
             {},
             {},
             true,
             false};
    for (const SweepSample& sample : samples) {
      if (!sample.conclusive || sample.uz_stderr <= 0 || BranchOf(sample.point) != branch) {
        continue;
      }
      s.x.push_back(x_of(sample.point));
      s.y.push_back(sample.uz);
      s.y_err.push_back(sample.uz_ci95);
    }
    if (!s.x.empty()) plot.series.push_back(std::move(s));
  }
  // Conclusive points whose window held too few blocks for an error: drawn apart, so that a dot
  // without a bar never reads as a precise one.
  Series no_error{"conclusive, no error (< 3 periods)", {}, {}, {}, true, false};
  for (const SweepSample& sample : samples) {
    if (!sample.conclusive || sample.uz_stderr > 0) continue;
    no_error.x.push_back(x_of(sample.point));
    no_error.y.push_back(sample.uz);
  }
  if (!no_error.x.empty()) plot.series.push_back(std::move(no_error));
  // Points of neither branch (Omega = 0, or other modes): one series of their own.
  Series other{"Ω = 0 or other drive", {}, {}, {}, true, false};
  for (const SweepSample& sample : samples) {
    if (!sample.conclusive || sample.uz_stderr <= 0 || BranchOf(sample.point) != Branch::kNone) continue;
    other.x.push_back(x_of(sample.point));
    other.y.push_back(sample.uz);
    other.y_err.push_back(sample.uz_ci95);
  }
  if (!other.x.empty()) plot.series.push_back(std::move(other));
  // Inconclusive runs (too few whole periods): drawn without error bars, not fitted.
  Series inconclusive{"inconclusive (not fitted)", {}, {}, {}, true, false};
  for (const SweepSample& sample : samples) {
    if (sample.conclusive || !sample.has_uz) continue;
    inconclusive.x.push_back(x_of(sample.point));
    inconclusive.y.push_back(sample.uz);
  }
  if (!inconclusive.x.empty()) plot.series.push_back(std::move(inconclusive));

  for (const BranchFit& b : fits.branches) {
    if (b.saturation) {
      const SaturationFit& fit = *b.saturation;
      double max_abs = 0;
      for (const SweepSample& s : samples) max_abs = std::max(max_abs, std::fabs(s.point.Omega));
      Series curve{b.branch + " fit: C1 = " + Num(fit.c1, 3) + " m/s, C2 = " + Num(fit.c2, 3) + " s/rad",
                   {},
                   {},
                   {},
                   false,
                   false};
      const double side = fit.sign > 0 ? -1.0 : 1.0;  // rising is drawn at Ω < 0
      for (int k = 0; k <= 100; ++k) {
        double w = max_abs * k / 100.0;
        curve.x.push_back(side * w);
        curve.y.push_back(SaturationModel(fit, w));
      }
      plot.series.push_back(std::move(curve));
      plot.series.push_back(BandOutline(b.branch, 0, max_abs, side, [&](double w) {
        return std::pair{SaturationModel(fit, w), SaturationBandHalfWidth(fit, w)};
      }));
    }
    if (b.linear) {
      const LinearFit& fit = *b.linear;
      Series line{b.branch + " fit: C3 = " + Num(fit.c3, 3) + " 1/s (A ≤ " + Num(fit.a_to, 3) + " m)",
                  {0.0, fit.a_to},
                  {0.0, fit.c3 * fit.a_to},
                  {},
                  false,
                  false};
      plot.series.push_back(std::move(line));
      plot.series.push_back(BandOutline(b.branch, 0, fit.a_to, 1.0, [&](double a) {
        return std::pair{fit.c3 * a, LinearBandHalfWidth(fit, a)};
      }));
    }
    if (b.fastest_rise) {
      const FastestRise& fr = *b.fastest_rise;
      double lo = 0, hi = 0;
      for (const SweepSample& s : samples) {
        if (!s.conclusive) continue;
        lo = std::min(lo, s.uz - s.uz_ci95);
        hi = std::max(hi, s.uz + s.uz_ci95);
      }
      Series mark{"f#dc#u = " + Num(fr.f_c, 3) + " Hz" + (fr.at_edge ? " (at the sweep's edge)" : ""),
                  {fr.f_c, fr.f_c},
                  {lo, hi},
                  {},
                  false,
                  true};
      plot.series.push_back(std::move(mark));
    }
  }
  return plot;
}

}  // namespace sandswim
