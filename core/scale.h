// Scale: a preset of box size, grain count and duration (SPEC.md "scale"), and the materials of
// Table 1, which are the same at every scale. This file is the one place both are defined.
//
// A scale sizes its periodic box so that the SO never meets its own periodic image at its full
// swing (SPEC.md): L_y >= 2 A + d_SO + 3 d_grain and L_x >= d_SO + 3 d_grain. A point whose A
// needs a bigger box is refused by FitsScale() with the name of a scale that would take it.
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

// Table 1 of the paper and Sec. 2.3. Nothing here is tuned.
struct Materials {
  double d_grain = 0.02;       // m
  double rho_grain = 2500;     // kg/m^3
  double d_so = 0.12;          // m
  double rho_so = 2500;        // kg/m^3
  double youngs = 1e7;         // Pa, grains and SO
  double poisson = 0.25;       // grains and SO
  double e_grain_grain = 0.9;  // coefficient of restitution
  double e_so_grain = 0.5;
  double mu_grain_grain = 0.45;  // coefficient of friction
  double mu_so_grain = 0.5;
  double gravity = 9.81;  // m/s^2, along -z
  double dt = 1e-5;       // s
};
inline constexpr Materials kMaterials{};

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
  // Derived: the largest A this box takes, (y_len - d_so - 3 d_grain) / 2.
  double max_amplitude() const;
};

// paper, mini, smoke, in that order (largest first).
const std::vector<Scale>& AllScales();
const Scale* FindScale(std::string_view name);

// Refuses a point the scale's box cannot hold ("A": "needs L_y >= ...; scale 'mini' takes it").
Status FitsScale(const Point& p, const Scale& scale);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_SCALE_H_
