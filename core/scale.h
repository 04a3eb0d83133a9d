// Scale: a preset of box size, grain count and duration (SPEC.md "scale"). Table 1's materials are
// in core/materials.h; a point may set others, and the box follows them (BoxFor).
//
// A scale sizes its periodic box so that the SO never meets its own periodic image at its full
// swing (SPEC.md): L_y >= 2 A + d_SO + 3 d_grain and L_x >= d_SO + 3 d_grain. A point whose A
// needs a bigger box is refused by FitsScale() with the name of a scale that would take it.
// A point with a larger SO or larger grains gets a box grown by as much as d_SO + 3 d_grain grew
// (in x and y), and a floor and top moved out by as much as the SO's radius grew, so it keeps the
// scale's largest A and its travel above and below the SO (BoxFor). A scale runs at most
// max_grains grains and steps no shorter than kMinTimeStepS: past those, FitsScale() refuses the
// point naming the field and a scale that would take it (if any).
// A scale may carry a default precision target (core/precision.h): a sweep that sets none runs to
// it, so runs last as long as their answer needs, within the target's maximum.
//
// Thread safety: immutable data.
#ifndef SANDSWIM_CORE_SCALE_H_
#define SANDSWIM_CORE_SCALE_H_

#include <optional>
#include <string_view>
#include <vector>

#include "core/point.h"
#include "core/precision.h"
#include "core/status.h"

namespace sandswim {


struct Scale {
  std::string_view name;
  std::string_view purpose;
  double x_len;      // m, periodic
  double y_len;      // m, periodic; the vibration direction
  double z_floor;    // m, rigid floor
  double z_bed_top;  // m, target height of the poured bed
  // The target of sweeps that set none (absent: runs last the duration they ask for).
  std::optional<PrecisionTarget> default_precision;
  // The scatter of U_z from bed to bed, as a fraction of |U_z|, that a point measured on one bed
  // adds to its run's own error (core/aggregate.h): a prior, measured on replicate beds of this
  // box (absent: not measured, and a one-bed point's error leaves it out, saying so).
  std::optional<double> bed_sd_rel;
  // The most grains its bed may hold (EstimatedGrains): what a run at the scale's purpose can take
  // (core/scale.cc says why each).
  double max_grains = 0;
  // The drive's time step for Table 1's materials when a sweep asks for none (core/numerics.h
  // ResolveDriveStep scales it by a point's materials and shrinks it where a point needs): Table
  // 1's until a convergence study decides otherwise (core/scale.cc says which study).
  double default_dt_s = 1e-5;
  // Derived: the largest A this box takes with Table 1's materials, (y_len - d_so - 3 d_grain) / 2.
  double max_amplitude() const;
};

// The shortest time step any scale runs (core/materials.h TimeStep): a fifth of the paper's, five
// times the steps of a Table 1 run.
inline constexpr double kMinTimeStepS = 2e-6;

// A scale's box for a point's materials (the scale's own box for Table 1's).
struct Box {
  double x_len = 0, y_len = 0, z_floor = 0, z_bed_top = 0;  // m
  double max_amplitude = 0;                                  // m: (y_len - d_so - 3 d_grain) / 2
};
Box BoxFor(const Scale& scale, const Materials& m);

// The grains a scale's bed holds for these materials before one was prepared: smoke's 6,682 (as
// prepared here), scaled by the bed's volume less the SO's and by the grain's volume.
double EstimatedGrains(const Scale& scale, const Materials& m = kTable1);

// paper, mini, smoke, in that order (largest first).
const std::vector<Scale>& AllScales();
const Scale* FindScale(std::string_view name);
// The scale's bed-to-bed prior, Scale::bed_sd_rel (0: an unknown scale, or none measured).
double BedPriorOf(std::string_view scale);

// Refuses a point the scale's box cannot hold ("A": "needs L_y >= ...; scale 'mini' takes it"),
// whose bed would pass the scale's max_grains ("grain_diameter" or "so_diameter"), or whose time
// step would be shorter than kMinTimeStepS (the material field that shortens it most).
Status FitsScale(const Point& p, const Scale& scale);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_SCALE_H_
