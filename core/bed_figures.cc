#include "core/bed_figures.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <string>

#include "core/dump_reader.h"

namespace sandswim {
namespace {

constexpr double kPi = 3.14159265358979323846;

// The three "lo hi" lines after the first "ITEM: BOX BOUNDS".
Result<std::array<std::array<double, 2>, 3>> BoxBounds(std::string_view text) {
  const size_t at = text.find("ITEM: BOX BOUNDS");
  if (at == std::string_view::npos) return Status::InvalidArgument("", "no ITEM: BOX BOUNDS line");
  size_t pos = text.find('\n', at);
  std::array<std::array<double, 2>, 3> box{};
  for (auto& axis : box) {
    if (pos == std::string_view::npos) return Status::InvalidArgument("", "the box bounds are cut short");
    const size_t end = text.find('\n', pos + 1);
    const std::string line(
        text.substr(pos + 1, end == std::string_view::npos ? std::string_view::npos : end - pos - 1));
    char* rest = nullptr;
    axis[0] = std::strtod(line.c_str(), &rest);
    char* after = nullptr;
    axis[1] = std::strtod(rest, &after);
    if (after == rest || !std::isfinite(axis[0]) || !std::isfinite(axis[1]) || axis[1] <= axis[0])
      return Status::InvalidArgument("", "bad box bounds line \"" + line + "\"");
    pos = end;
  }
  return box;
}

// The volume of a sphere of radius r whose centre is d from the origin that lies inside the
// sphere of radius R about the origin (the lens of two intersecting spheres).
double VolumeInside(double R, double r, double d) {
  if (d + r <= R) return 4.0 / 3.0 * kPi * r * r * r;
  if (d >= R + r) return 0;
  if (d + R <= r) return 4.0 / 3.0 * kPi * R * R * R;
  return kPi * (R + r - d) * (R + r - d) * (d * d + 2 * d * r - 3 * r * r + 2 * d * R + 6 * r * R - 3 * R * R) /
         (12 * d);
}

// The nearest periodic image's separation along a side of length `len`.
double MinImage(double d, double len) { return d - len * std::round(d / len); }

}  // namespace

Result<BedFigures> MeasureBed(std::string_view text) {
  auto box = BoxBounds(text);
  if (!box.ok()) return box.status();
  auto frames = ReadDump(text);
  if (!frames.ok()) return frames.status();
  if (frames->size() != 1)
    return Status::InvalidArgument("", "a bed dump holds one frame, not " + std::to_string(frames->size()));
  const DumpFrame& f = frames->front();
  const int c_type = f.Column("type"), c_x = f.Column("x"), c_y = f.Column("y"), c_z = f.Column("z"),
            c_r = f.Column("radius");
  if (c_type < 0 || c_x < 0 || c_y < 0 || c_z < 0 || c_r < 0)
    return Status::InvalidArgument("", "a bed dump needs the columns type x y z radius");
  const double lx = (*box)[0][1] - (*box)[0][0], ly = (*box)[1][1] - (*box)[1][0];

  BedFigures b;
  int64_t so = -1;
  for (int64_t i = 0; i < f.atoms; ++i) {
    if (f.At(i, c_type) == 2) {
      if (so >= 0) return Status::InvalidArgument("", "a bed dump holds one SO (type 2), this one more");
      so = i;
    }
  }
  if (so < 0) return Status::InvalidArgument("", "a bed dump holds one SO (type 2), this one none");
  b.so_x = f.At(so, c_x);
  b.so_y = f.At(so, c_y);
  b.so_z = f.At(so, c_z);
  const double r_so = f.At(so, c_r);
  const double inner = r_so, outer = r_so + kShellThickness;
  // A grain is counted at its nearest image; so that no grain reaches the shell twice, the shell
  // and a grain's radius fit in half the box.
  double r_max = 0;
  for (int64_t i = 0; i < f.atoms; ++i)
    if (i != so) r_max = std::max(r_max, f.At(i, c_r));
  if (2 * (outer + r_max) > std::min(lx, ly) + 1e-12)
    return Status::FailedPrecondition("", "the box (" + std::to_string(lx) + " x " + std::to_string(ly) +
                                              " m) is too narrow for a packing shell of radius " +
                                              std::to_string(outer) + " m and grains of radius " +
                                              std::to_string(r_max) + " m");

  double grain_volume = 0;
  b.grain_top = -INFINITY;
  for (int64_t i = 0; i < f.atoms; ++i) {
    if (i == so) continue;
    ++b.grains;
    b.grain_top = std::max(b.grain_top, f.At(i, c_z));
    const double dx = MinImage(f.At(i, c_x) - b.so_x, lx), dy = MinImage(f.At(i, c_y) - b.so_y, ly);
    const double dz = f.At(i, c_z) - b.so_z;
    const double d = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double r = f.At(i, c_r);
    if (d >= inner && d < outer) ++b.shell_grains;
    if (d < outer + r) grain_volume += VolumeInside(outer, r, d) - VolumeInside(inner, r, d);
  }
  if (b.grains == 0) return Status::InvalidArgument("", "a bed dump with no grains");
  const double shell_volume = 4.0 / 3.0 * kPi * (outer * outer * outer - inner * inner * inner);
  b.packing_fraction = grain_volume / shell_volume;
  b.bed_height = b.grain_top - (*box)[2][0];
  b.so_depth = b.grain_top - (b.so_z + r_so);
  return b;
}

}  // namespace sandswim
