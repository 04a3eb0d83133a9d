#include "server/figures.h"

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>

#include <plplot.h>

#include "core/keys.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "server/plot_renderer.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

// Bumped whenever the drawing changes, so files drawn the old way are not served.
constexpr const char* kStyleVersion = "figures-v5";
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

// Draws under the PLplot mutex into `path`. REQUIRES: CheckPlot(plot) passed.
void Draw(const Plot& plot, ImageFormat format, const std::string& path) {
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
  plschr(0, 0.85);
  plvpor(0.085, 0.56, 0.11, 0.91);
  // Plain decimals on the axes (no "(x10^-2)" factor floating above the axis).
  plsxax(8, 0);
  plsyax(8, 0);

  Range xr, yr;
  for (const Series& s : plot.series) {
    for (size_t i = 0; i < s.x.size(); ++i) {
      xr.Add(s.x[i]);
      double e = s.y_err.empty() ? 0 : std::fabs(s.y_err[i]);
      yr.Add(s.y[i] - e);
      yr.Add(s.y[i] + e);
    }
  }
  xr.Pad();
  yr.Pad();
  plwind(xr.lo, xr.hi, yr.lo, yr.hi);
  plcol0(kInk);
  plwidth(1);
  plbox("bcnst", 0, 0, "bcnstv", 0, 0);
  // A zero line where U_z or Δz changes sign.
  if (yr.lo < 0 && yr.hi > 0) {
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
      plwidth(1.5);
      plline(n, x.data(), y.data());
      plwidth(1);
      pllsty(1);
    }
    opts.push_back(s.markers ? PL_LEGEND_SYMBOL : PL_LEGEND_LINE);
    colors.push_back(color);
    styles.push_back(s.dashed ? 2 : 1);
    widths.push_back(1.5);
    symbol_numbers.push_back(1);
    symbol_scales.push_back(0.8);
    symbols.push_back("●");
    text_colors.push_back(kInk);
    texts.push_back(s.label.c_str());
  }
  // Labels longer than the space right of the plot holds (about 46 characters at the usual size)
  // are drawn smaller rather than cut at the page's edge.
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
  const PLFLT base_scale = n_series > 12 ? 0.65 : 0.75;
  const PLFLT text_scale = longest > 46 ? base_scale * 46.0 / static_cast<PLFLT>(longest) : base_scale;
  PLFLT legend_width = 0, legend_height = 0;
  plcol0(kInk);
  pllegend(&legend_width, &legend_height, PL_LEGEND_BACKGROUND | PL_LEGEND_BOUNDING_BOX,
           PL_POSITION_RIGHT | PL_POSITION_OUTSIDE, 0.02, 0.0, 0.06, kBackground, kInk, 1, 0, 0, n_series, opts.data(),
           0.5, text_scale, 2.0, 0.0, text_colors.data(), texts.data(), nullptr, nullptr, nullptr, nullptr,
           colors.data(), styles.data(), widths.data(), colors.data(), symbol_scales.data(), symbol_numbers.data(),
           symbols.data());
  plend();
}

std::string Signed(double v) { return Num(v, 4); }

}  // namespace

const char* ImageExtension(ImageFormat format) { return format == ImageFormat::kSvg ? "svg" : "png"; }
const char* ImageContentType(ImageFormat format) { return format == ImageFormat::kSvg ? "image/svg+xml" : "image/png"; }

void to_json(json& j, const Plot& p) {
  json series = json::array();
  for (const Series& s : p.series) {
    series.push_back(
        {{"label", s.label}, {"x", s.x}, {"y", s.y}, {"y_err", s.y_err}, {"markers", s.markers}, {"dashed", s.dashed}});
  }
  j = {{"title", p.title}, {"x_label", p.x_label}, {"y_label", p.y_label}, {"series", series}};
}

Status CheckPlot(const Plot& plot) {
  if (plot.series.empty()) return Status::InvalidArgument("plot", "nothing to draw: no series");
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
  return p;
}

std::string SeriesColor(size_t i) { return Hex(SeriesRgb(i)); }

Status DrawPlotToFile(const Plot& plot, ImageFormat format, const std::string& path) {
  SANDSWIM_RETURN_IF_ERROR(CheckPlot(plot));
  Draw(plot, format, path);
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
  const std::string omega = "Ω = " + Signed(p.Omega) + " rad/s";
  if (param == "Omega") return omega;
  if (param == "A") return "A = " + Num(p.A, 4) + " m, " + omega;
  if (param == "f") return "f = " + Num(p.f, 4) + " Hz, " + omega;
  std::string label = std::string(ModeName(p.mode));
  if (p.has_vibration()) label += ", A = " + Num(p.A, 4) + " m, f = " + Num(p.f, 4) + " Hz";
  if (p.mode == Mode::kOscillatory) label += ", " + omega;
  if (p.has_constant_rotation()) label += ", ω = " + Num(p.omega, 4) + " rad/s (" + std::string(AxisName(p.axis)) + ")";
  return label;
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
  return param == "A" ? p.A : param == "f" ? p.f : p.Omega;
}

Plot SweepUzPlot(const std::string& title, const std::vector<SweepSample>& samples, const SweepFits& fits) {
  const std::string& param = fits.choice.param;
  Plot plot;
  plot.title = title;
  plot.y_label = "U#dz#u (m/s), bars: 95 % interval";
  plot.x_label = param == "A" ? "A (m)" : param == "f" ? "f (Hz)" : "Ω (rad/s)";
  auto x_of = [&](const Point& p) { return SweptValue(p, param); };
  for (const char* branch : {"rising", "sinking"}) {
    Series s{std::string(branch) + " (Ω " + (std::string(branch) == "rising" ? "< 0" : "> 0") + ")",
             {},
             {},
             {},
             true,
             false};
    for (const SweepSample& sample : samples) {
      bool rising = sample.point.Omega < 0;
      if (!sample.conclusive || sample.uz_stderr <= 0 || sample.point.Omega == 0 ||
          rising != (std::string(branch) == "rising")) {
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
    if (!sample.conclusive || sample.uz_stderr <= 0 || sample.point.Omega != 0) continue;
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

// ---- FigureCache -------------------------------------------------------------------------------

FigureCache::FigureCache(std::string dir, PlotRenderer* renderer) : dir_(std::move(dir)), renderer_(renderer) {}

std::string FigureCache::PathFor(const std::string& name, const Plot& plot, ImageFormat format) const {
  std::string hash = Sha256Hex(json(plot).dump() + "\n" + ImageExtension(format) + "\n" + kStyleVersion);
  return (std::filesystem::path(dir_) / (name + "-" + hash.substr(0, 16) + "." + ImageExtension(format))).string();
}

Result<std::string> FigureCache::Get(const std::string& name, const Plot& plot, ImageFormat format) {
  const std::string path = PathFor(name, plot, format);
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (!bytes.empty()) return bytes;
    }
  }
  auto bytes = renderer_ != nullptr ? renderer_->Render(plot, format) : RenderPlot(plot, format);
  if (!bytes.ok()) return bytes.status();
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec) return Status::IOError("cannot create " + dir_ + ": " + ec.message());
  // Older figures of this name were drawn from older results: they go.
  const std::string prefix = name + "-";
  const std::string extension = std::string(".") + ImageExtension(format);
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    std::string file = entry.path().filename().string();
    if (file.rfind(prefix, 0) == 0 && file.size() == prefix.size() + 16 + extension.size() &&
        file.compare(file.size() - extension.size(), extension.size(), extension) == 0 && entry.path() != path) {
      std::filesystem::remove(entry.path(), ec);
    }
  }
  static std::atomic<uint64_t> counter{0};
  std::string temp = path + ".tmp" + std::to_string(getpid()) + "-" + std::to_string(counter.fetch_add(1));
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    out.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
    out.close();  // a failure of the last flush counts too
    if (!out) {
      std::filesystem::remove(temp, ec);
      return Status::IOError("cannot write " + temp + " (disk full?)");
    }
  }
  std::filesystem::rename(temp, path, ec);
  if (ec) {
    std::filesystem::remove(temp, ec);
    return Status::IOError("cannot rename a figure into " + path);
  }
  return bytes;
}

}  // namespace sandswim
