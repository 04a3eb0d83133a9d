// What a prepared bed is like, measured from the dump of all its atoms that the bed deck writes
// last (kBedDumpFile: id type x y z radius; type 2 is the SO). A bed reports these with its grain
// count (api::BedResult), so a result can be traced to the bed it ran on.
//
//   packing_fraction  the grains' solid volume fraction in the spherical shell from the SO's
//                     surface out to kShellThickness (1 grain diameter): each grain's volume
//                     inside the shell, computed exactly (the lenses of two spheres), over the
//                     shell's volume. Grains are taken at their nearest periodic image in x and
//                     y; the shell plus a grain radius (0.09 m) must fit in half the smallest box
//                     side (smoke: 0.18 m), so no grain reaches the shell twice.
//   bed_height        highest grain centre above the floor (the box's lower z bound)
//   so_depth          grains above the SO: highest grain centre minus the SO's top
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_BED_FIGURES_H_
#define SANDSWIM_CORE_BED_FIGURES_H_

#include <cstdint>
#include <string_view>

#include "core/deck.h"
#include "core/scale.h"
#include "core/status.h"

namespace sandswim {

inline constexpr double kShellThickness = kMaterials.d_grain;

struct BedFigures {
  int64_t grains = 0;
  double so_x = 0, so_y = 0, so_z = 0;  // m
  double grain_top = 0;                 // m, highest grain centre
  double bed_height = 0;                // m
  double so_depth = 0;                  // m
  double packing_fraction = 0;          // solid fraction in the shell around the SO
  int64_t shell_grains = 0;             // grains whose centre is in that shell
};

// InvalidArgument (with the line) when the text is not a one-frame dump with columns id, type, x,
// y, z, radius, box bounds and exactly one SO (type 2); FailedPrecondition when the box is too
// narrow for the shell.
Result<BedFigures> MeasureBed(std::string_view dump_text);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_BED_FIGURES_H_
