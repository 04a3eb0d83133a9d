// Figures: the paper's plots of a run and of a sweep, drawn by PLplot (Debian's libplplot-dev) as
// SVG (PLplot's own "svg" device) or PNG ("pngcairo", plplot-driver-cairo).
//
//   per run    Δz(t) and Δx(t) of the SO (paper Fig. 2 and 4 style);
//   per sweep  every run's Δz(t) on one plot (Fig. 6a/b, 7a/b, 8a/b), and U_z against the swept
//              parameter with error bars and the fitted law (Fig. 6c/d, 7c/d, 8c/d).
//
// A Plot is a value (title, axis labels with units, series); the builders below make one from
// stored results, RenderPlot() draws it. Every series has its own colour (SeriesColor(i) for the
// i-th), also in the legend: a reader of the SVG can count the series by their colours.
//
// A plot may also hold discs coloured by a value, with a colour bar: a slice through the bed
// (paper Fig. 5), grains coloured by their speed, the SO's outline a series drawn over them. Such a
// plot usually wants equal_aspect (a metre as long across as up) and limits (the whole box).
//
// Thread safety: PLplot keeps global state and is not thread-safe; RenderPlot() serialises every
// drawing behind one process-wide mutex. PLplot ends the process on an internal error
// (plexit), so RenderPlot() checks what it can first (finite data, a writable temporary file), and
// sandswimd draws through sandswim-render, a process of its own (server/analysis/plot_renderer.h).
#ifndef SANDSWIM_SERVER_ANALYSIS_FIGURES_H_
#define SANDSWIM_SERVER_ANALYSIS_FIGURES_H_

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/fit.h"
#include "core/point.h"
#include "core/status.h"

namespace sandswim {

enum class ImageFormat { kSvg, kPng };
// What a cached figure's name hashes with besides its data (server/analysis/figure_cache.h):
// changed whenever the drawing changes, so files drawn the old way are not served.
const char* FigureStyleVersion();
const char* ImageExtension(ImageFormat format);    // "svg", "png"
const char* ImageContentType(ImageFormat format);  // "image/svg+xml", "image/png"

struct Series {
  std::string label;
  std::vector<double> x, y;
  std::vector<double> y_err;  // empty, or one error bar per point
  bool markers = false;       // data points (markers) rather than a line
  bool dashed = false;
};

// Filled circles coloured by a value on a continuous colour map, with a colour bar labelled
// value_label (a bed slice: grains coloured by speed). Drawn under the series, whose lines get a
// white halo to stand out on them; the colour bar stands right of the plot, the legend right of it.
struct Discs {
  std::vector<double> x, y, r, value;  // centre, radius (in axis units), the coloured value
  std::string value_label;             // e.g. "|v| (m/s)"
};

struct Plot {
  std::string title;
  std::string x_label, y_label;  // with units: "t (s)", "U_z (m/s)"
  std::vector<Series> series;
  std::optional<Discs> discs;
  // One unit on x as long on the page as one unit on y (a slice must not be stretched): the plot
  // box shrinks inside its usual area to the data's (or the limits') proportions.
  bool equal_aspect = false;
  // x_lo, x_hi, y_lo, y_hi of the axes, used as they are; unset: the data's range with 5 % of room.
  std::optional<std::array<double, 4>> limits;
};
// "discs", "equal_aspect" and "limits" are written only when set (true), so a plot without them
// has the JSON, hence the cache name, it had before they existed.
void to_json(nlohmann::json& j, const Plot& p);
// The inverse of to_json: InvalidArgument ("plot") naming what is missing or of the wrong type.
Result<Plot> PlotFromJson(const nlohmann::json& j);

// "#RRGGBB" of the i-th series; distinct from each other for i < 64 and never black, white or
// the axes' colour.
std::string SeriesColor(size_t i);

// InvalidArgument ("plot") for a plot with neither series nor discs, a series whose x and y differ
// in length, discs whose x, y, r and value differ in length or whose radius is not positive, limits
// with lo >= hi, or a non-finite value: what RenderPlot refuses before PLplot sees it.
Status CheckPlot(const Plot& plot);

// ---- Layout ------------------------------------------------------------------------------------
// Where a figure's parts go on its page (1200 x 600 px). The plot box takes the page's width; a
// legend up to 70 % of the box's width and 85 % of its height goes inside it, in the first corner
// (top right, top left, bottom right, bottom left) its rectangle shares with no data (markers,
// error bars, lines, with a few pixels of clearance); else, when it takes at most 45 % of the
// box's height and the axes are the data's own (no `limits`), the y axis grows at the end of the
// corner with the fewest data, so that the legend sits above (below) every datum; else (many or
// long entries) it stands right of the box, as wide as its longest label (at most 42 % of the
// page: longer labels are drawn smaller), and the box takes the rest. A plot with discs keeps its
// box to the data's proportions in the left 56 %, the colour bar and the legend right of it.

// A rectangle in fractions of the page: x from its left edge, y from its bottom edge.
struct PageRect {
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;
  double width() const { return x1 - x0; }
  double height() const { return y1 - y0; }
};
enum class LegendPlace { kNone, kInside, kRight };
struct FigureLayout {
  PageRect box;                  // the area of the plot box (an equal-aspect box shrinks inside it)
  std::array<double, 4> axes{};  // x_lo, x_hi, y_lo, y_hi
  LegendPlace legend = LegendPlace::kNone;
  bool legend_top = true, legend_left = false;  // kInside: the corner
  bool headroom = false;                        // kInside: the y axis grew to make room for it
  // kInside and kRight without discs: the legend's rectangle, estimated from its labels (at least
  // as large as PLplot draws it). As drawn (DrawPlotToFile's `drawn`): the one PLplot reports.
  PageRect legend_rect;
  double text_scale = 0.75;  // the legend's labels, of PLplot's default character height
};
// The layout of `plot` drawn as `format` (pure: no drawing; the formats measure the legend's text
// differently). REQUIRES: CheckPlot(plot) passed.
FigureLayout LayOutFigure(const Plot& plot, ImageFormat format);

// Draws the plot in this process (CheckPlot first); IOError when the temporary file cannot be
// made. PLplot may end the process on an error of its own: the daemon draws through a
// PlotRenderer (server/analysis/plot_renderer.h) in a process of its own instead.
Result<std::string> RenderPlot(const Plot& plot, ImageFormat format);
// The same, drawn into the file at `path` (created or replaced): what sandswim-render does, so
// that a renderer PLplot ends leaves no file of its own behind. `drawn` (optional): the layout
// as drawn, the box PLplot used and the legend's rectangle as PLplot reports it.
Status DrawPlotToFile(const Plot& plot, ImageFormat format, const std::string& path, FigureLayout* drawn = nullptr);

// Text shown as it is in a PLplot label: '#' (PLplot's escape, as in "U#dz#u") doubled. For
// user-given names (a sweep's) inside titles.
std::string PlplotLiteral(const std::string& text);

// ---- The figures of a run and of a sweep -------------------------------------------------------

// "Ω = -80 rad/s" (param "Omega"), "A = 0.03 m, Ω = -80 rad/s", "f = 3 Hz, Ω = -80 rad/s";
// for param "" the whole drive.
std::string PointLabel(const Point& point, const std::string& param);

// Δz(t) and Δx(t) of one run. With its result: also Δz read once per period over the steady
// window (the points U_z is the mean rate of) and the line of slope U_z through the first of them,
// and U_z (DescribeUz) in the title. REQUIRES: the trajectory has at least one sample.
Plot RunTrajectoryPlot(int64_t run_id, const Point& point, const api::Trajectory& trajectory,
                       const api::RunResult* result = nullptr);

struct RunTrajectory {
  int64_t run_id = 0;
  Point point;
  api::Trajectory trajectory;
  int replicate = 0;  // the replicate bed it ran on
};
enum class Coordinate { kX, kZ };
// Every run's Δz(t) (or Δx(t)), one series each, labelled by PointLabel(point, param), and by its
// replicate bed when the runs are on more than one.
Plot SweepTrajectoriesPlot(const std::string& title, const std::vector<RunTrajectory>& runs, const std::string& param,
                           Coordinate coordinate = Coordinate::kZ);

// The value a U_z figure plots a point at: A for param "A", f for "f", else the signed Ω.
double SweptValue(const Point& point, const std::string& param);

// U_z against the swept parameter (signed Ω for an Ω sweep, else A or f), one series of points
// with error bars per branch, plus the fitted law of each branch that has one (the curve of eq.
// 8, the line of eq. 9 over its range, or a vertical line at f_c).
Plot SweepUzPlot(const std::string& title, const std::vector<SweepSample>& samples, const SweepFits& fits);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_FIGURES_H_
