// Full-bed snapshots of a drive run (the paper's Fig. 5): every atom of the bed at one moment, as
// the engine dumps it (one frame a file, columns kSnapshotColumns, x and y periodic), and what is
// made of it: a file ParaView opens, a slice of the bed in the y–z plane through the SO, and which
// of a run's frames are the snapshots asked for.
//
// Atom type 1 is a grain, type 2 the SO (the self-excited object: one sphere). Units are SI as the
// engine writes them: positions and radii in m, velocities in m/s, times in s.
//
// Snapshots are asked as fractions of the run's actual length, which is known only when the run
// ends (runs may stop early). So the engine dumps the whole bed every few steps, and when the run
// ends PickSnapshotFrames picks, for each fraction, the frame nearest it. While the run goes on,
// SnapshotFramesStillNeeded says which frames a pick may still want, so the others can be deleted
// as it goes (at a large scale every frame kept would be too much disk).
//
// Drawing the bed in ParaView: open the .vtk file (BedSnapshotVtk); its legacy reader loads every
// array. Each atom is a point, drawn as a dot. For spheres, apply the Glyph filter with Glyph Type
// "Sphere", Scale Array "radius", Scale Factor 2 and Glyph Mode "All Points". The factor is 2
// because the glyph's sphere has radius 0.5 by default (a unit diameter), so a glyph's radius is
// 0.5 x 2 x radius, the atom's own; setting the glyph's Radius to 1 with Scale Factor 1 does the
// same. Glyph Mode matters: recent versions default to a spatially uniform sample of at most a
// few thousand points, which silently leaves most grains out. Colour by "speed" or "type"; an
// orientation array does not change a sphere. (Older versions name these Scale Mode "scalar" with
// Scalars "radius".) A script reading the file with the plain legacy polydata reader must ask it
// to read all scalars: by default it reads only the first ("id").
//
// Thread safety: pure functions; values in, values out.
#ifndef SANDSWIM_CORE_SNAPSHOT_H_
#define SANDSWIM_CORE_SNAPSHOT_H_

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/status.h"

namespace sandswim {

// The columns of a snapshot dump (the deck's `dump ... custom` line names them in this order).
inline constexpr char kSnapshotColumns[] = "id type x y z vx vy vz radius";

// One frame of the whole bed: one entry per atom in each column vector, in the dump's order.
struct BedSnapshot {
  int64_t step = 0;
  std::array<double, 3> box_lo{}, box_hi{};  // m, the box bounds (x and y periodic)
  std::vector<int64_t> id;
  std::vector<int> type;  // 1 grain, 2 the SO
  std::vector<double> x, y, z, vx, vy, vz, radius;
  size_t so = 0;  // index of the SO (the one type-2 atom)
  size_t size() const { return id.size(); }
  int64_t grains() const;  // atoms of type 1
};

// The snapshot in `dump_text`: exactly one complete frame of an orthogonal box, holding at least
// the columns of kSnapshotColumns (in any order; others are ignored), atoms of type 1 and exactly one
// of type 2, every value finite and every radius > 0. Otherwise InvalidArgument naming what is
// wrong and, for a line at fault, its number ("dump line N: ..."). A frame cut short (the text
// does not end with its last atom line's newline) is refused as torn, never read as shorter.
Result<BedSnapshot> ParseBedSnapshot(std::string_view dump_text);

// The snapshot as a legacy VTK file (version 3.0, ASCII, DATASET POLYDATA): POINTS are every atom
// (grains and the SO) in the snapshot's order, one VERTICES cell each, and POINT_DATA holds
// scalars "id" (vtktypeint64), "type" (int), "radius" and "speed" (|v|) (double) and vectors
// "velocity" (double). `title` is the header's second line: newlines become blanks and it is cut
// to 255 bytes (at a character boundary), what the format's readers take. Numbers are printed in
// their shortest form that reads back as the same double.
std::string BedSnapshotVtk(const BedSnapshot& s, std::string_view title);

// A y–z slice through the SO's centre: the plane x = x0 = x of the SO. A grain whose sphere the
// plane cuts (|dx| < radius, dx the distance to the plane from the grain's nearest periodic image
// in x, box width box_hi[0] - box_lo[0]) is a disc of radius sqrt(radius^2 - dx^2) at its (y, z),
// with its speed |v|; the SO is a disc of its full radius at its (y, z), with its speed.
struct SliceDisc {
  double y = 0, z = 0, r = 0, speed = 0;  // m, m, m, m/s
};
struct BedSlice {
  double x0 = 0;                  // m, the plane
  std::vector<SliceDisc> grains;  // the grains the plane cuts, in the snapshot's order
  SliceDisc so;
  double y_lo = 0, y_hi = 0, z_lo = 0, z_hi = 0;  // m, the box bounds in y and z
};
// REQUIRES: `s` as ParseBedSnapshot makes it (s.so a type-2 atom, a box of positive width).
BedSlice SliceThroughSo(const BedSnapshot& s);

// Which of a run's frames are its snapshots. `frame_t` are the frames' times, ascending (the first
// at t = 0); `t_end` is the run's actual length. For each fraction phi, in the order given, the
// index of the frame whose time is nearest phi * t_end; of two equally near, the earlier.
// REQUIRES: frame_t non-empty; fractions in [0, 1].
std::vector<size_t> PickSnapshotFrames(const std::vector<double>& frame_t, const std::vector<double>& fractions,
                                       double t_end);

// While the run goes on (at time t_now, its length t_end >= t_now not known yet), the frames dumped
// so far (`frame_t`) that PickSnapshotFrames may still pick once the run ends, for some t_end >=
// t_now and whatever frames come after t_now: keep[i] for frame i. The others can be deleted as the
// run goes. For a fraction phi > 0 the target phi * t_end is at least phi * t_now, so only the last
// frame at or before phi * t_now (the first of that time, should frames share it) and the frames
// after it can still be nearest; for phi = 0 the target is 0, so only the first frame.
// REQUIRES: frame_t ascending; fractions in [0, 1]; t_now >= 0.
std::vector<bool> SnapshotFramesStillNeeded(const std::vector<double>& frame_t, const std::vector<double>& fractions,
                                            double t_now);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_SNAPSHOT_H_
