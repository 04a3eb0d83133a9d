#include "core/snapshot.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <utility>

#include "core/dump_reader.h"
#include "core/text.h"

namespace sandswim {
namespace {

// The whole text is at fault, so no field is named.
Status RefuseSnapshot(std::string reason) { return Status::InvalidArgument("", std::move(reason)); }

std::vector<std::string_view> SnapshotColumnNames() {
  std::vector<std::string_view> names;
  std::string_view all = kSnapshotColumns;
  for (size_t at = 0; at < all.size();) {
    const size_t end = std::min(all.find(' ', at), all.size());
    names.push_back(all.substr(at, end - at));
    at = end + 1;
  }
  return names;
}

// What the dump reader checks but does not hand out: the box bounds, and the line of the first
// atom (so that a refusal can name an atom's line). Read once the reader has accepted the text as
// one complete frame, so every line looked for is there.
struct SnapshotLayout {
  std::array<double, 3> lo{}, hi{};
  int64_t first_atom_line = 0;
};

Result<SnapshotLayout> ReadSnapshotLayout(std::string_view text) {
  SnapshotLayout layout;
  int box_row = -1;  // the box line being read, 0..2; -1 before "ITEM: BOX BOUNDS"
  int64_t line = 0;
  for (size_t at = 0; at < text.size() && layout.first_atom_line == 0;) {
    const size_t end = std::min(text.find('\n', at), text.size());
    const std::string_view l = Trim(text.substr(at, end - at));
    at = end + 1;
    ++line;
    if (box_row >= 0 && box_row < 3) {
      // "lo hi", as the reader accepted it (a leading '+' included); a third number is a tilt.
      double v[2];
      const char* p = l.data();
      const char* const stop = l.data() + l.size();
      for (double& x : v) {
        while (p < stop && (*p == ' ' || *p == '\t')) ++p;
        if (p < stop && *p == '+') ++p;
        p = std::from_chars(p, stop, x).ptr;
      }
      if (p != stop)
        return RefuseSnapshot("dump line " + std::to_string(line) + ": a snapshot's box is orthogonal, got \"" +
                              std::string(l) + "\"");
      if (!(v[0] < v[1]))
        return RefuseSnapshot("dump line " + std::to_string(line) + ": box bounds \"" + std::string(l) +
                              "\" are not lo < hi");
      layout.lo[box_row] = v[0];
      layout.hi[box_row] = v[1];
      ++box_row;
    } else if (StartsWith(l, "ITEM: BOX BOUNDS")) {
      box_row = 0;
    } else if (StartsWith(l, "ITEM: ATOMS")) {
      layout.first_atom_line = line + 1;
    }
  }
  return layout;
}

// The first frame at or after time `at` (frames may share a time).
size_t FirstSnapshotFrameAt(const std::vector<double>& t, double at) {
  return std::lower_bound(t.begin(), t.end(), at) - t.begin();
}

// The frame nearest `target`; of two equally near, the earlier (and of frames sharing a time, the
// first).
size_t NearestSnapshotFrame(const std::vector<double>& t, double target) {
  const size_t after = FirstSnapshotFrameAt(t, target);
  if (after == 0) return 0;
  if (after == t.size() || target - t[after - 1] <= t[after] - target) return FirstSnapshotFrameAt(t, t[after - 1]);
  return after;
}

}  // namespace

int64_t BedSnapshot::grains() const { return std::count(type.begin(), type.end(), 1); }

Result<BedSnapshot> ParseBedSnapshot(std::string_view text) {
  DumpReader reader;
  DumpFrameCollector collector;
  if (Status s = reader.Feed(text, collector); !s.ok()) return RefuseSnapshot(s.reason());
  // A text that stops inside a frame (the engine still writing it, a truncated copy) is refused,
  // not completed: its last number may be cut short.
  if (reader.torn())
    return RefuseSnapshot("the frame is torn: the text ends inside it, after dump line " +
                          std::to_string(reader.lines()));
  std::vector<DumpFrame> frames = collector.Take();
  if (frames.size() != 1)
    return RefuseSnapshot("a snapshot is one frame, this dump holds " + std::to_string(frames.size()));
  const DumpFrame& f = frames.front();

  const std::vector<std::string_view> names = SnapshotColumnNames();
  std::vector<int> col;
  std::string missing;
  for (std::string_view name : names) {
    col.push_back(f.Column(name));
    if (col.back() < 0) missing += (missing.empty() ? "" : " ") + std::string(name);
  }
  if (!missing.empty())
    return RefuseSnapshot("a snapshot needs the columns " + std::string(kSnapshotColumns) + "; missing: " + missing);
  auto layout = ReadSnapshotLayout(text);
  if (!layout.ok()) return layout.status();

  BedSnapshot s;
  s.step = f.step;
  s.box_lo = layout->lo;
  s.box_hi = layout->hi;
  // In kSnapshotColumns' order: id, type, then these.
  std::vector<double>* const values[] = {nullptr, nullptr, &s.x, &s.y, &s.z, &s.vx, &s.vy, &s.vz, &s.radius};
  int64_t so_line = 0;
  for (int64_t i = 0; i < f.atoms; ++i) {
    const std::string where = "dump line " + std::to_string(layout->first_atom_line + i) + ": ";
    for (size_t c = 0; c < names.size(); ++c)
      if (!std::isfinite(f.At(i, col[c])))
        return RefuseSnapshot(where + std::string(names[c]) + " is " + Num(f.At(i, col[c])));
    const double type = f.At(i, col[1]), radius = f.At(i, col[8]);
    if (type != 1 && type != 2)
      return RefuseSnapshot(where + "atom type " + Num(type) + "; a snapshot holds grains (1) and the SO (2)");
    if (!(radius > 0)) return RefuseSnapshot(where + "radius " + Num(radius) + " is not > 0");
    if (type == 2) {
      if (so_line != 0)
        return RefuseSnapshot(where + "a second SO (type 2); the first is on dump line " + std::to_string(so_line));
      so_line = layout->first_atom_line + i;
      s.so = static_cast<size_t>(i);
    }
    s.id.push_back(static_cast<int64_t>(f.At(i, col[0])));
    s.type.push_back(static_cast<int>(type));
    for (size_t c = 2; c < names.size(); ++c) values[c]->push_back(f.At(i, col[c]));
  }
  if (so_line == 0) return RefuseSnapshot("a snapshot holds one SO (an atom of type 2), this one none");
  return s;
}

std::string BedSnapshotVtk(const BedSnapshot& s, std::string_view title) {
  std::string head(title.substr(0, 255));
  std::replace(head.begin(), head.end(), '\n', ' ');
  std::replace(head.begin(), head.end(), '\r', ' ');
  // Cut at 255 bytes, not inside a UTF-8 character (its continuation bytes are 10xxxxxx).
  if (title.size() > 255)
    while (!head.empty() && (static_cast<unsigned char>(title[head.size()]) & 0xC0) == 0x80) head.pop_back();

  std::string out;
  auto number = [&out](double v) {
    char buf[32];
    out.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
  };
  auto scalars = [&](const char* name, const char* type, auto&& value) {
    out += std::string("SCALARS ") + name + " " + type + " 1\nLOOKUP_TABLE default\n";
    for (size_t i = 0; i < s.size(); ++i) {
      value(i);
      out += '\n';
    }
  };
  auto triples = [&](const std::vector<double>& a, const std::vector<double>& b, const std::vector<double>& c) {
    for (size_t i = 0; i < s.size(); ++i) {
      number(a[i]);
      out += ' ';
      number(b[i]);
      out += ' ';
      number(c[i]);
      out += '\n';
    }
  };
  const size_t n = s.size();
  out += "# vtk DataFile Version 3.0\n" + head + "\nASCII\nDATASET POLYDATA\n";
  out += "POINTS " + std::to_string(n) + " double\n";
  triples(s.x, s.y, s.z);
  out += "VERTICES " + std::to_string(n) + " " + std::to_string(2 * n) + "\n";
  for (size_t i = 0; i < n; ++i) out += "1 " + std::to_string(i) + "\n";
  out += "POINT_DATA " + std::to_string(n) + "\n";
  scalars("id", "vtktypeint64", [&](size_t i) { out += std::to_string(s.id[i]); });
  scalars("type", "int", [&](size_t i) { out += std::to_string(s.type[i]); });
  scalars("radius", "double", [&](size_t i) { number(s.radius[i]); });
  scalars("speed", "double", [&](size_t i) { number(std::hypot(s.vx[i], s.vy[i], s.vz[i])); });
  out += "VECTORS velocity double\n";
  triples(s.vx, s.vy, s.vz);
  return out;
}

BedSlice SliceThroughSo(const BedSnapshot& s) {
  auto disc = [&s](size_t i, double r) { return SliceDisc{s.y[i], s.z[i], r, std::hypot(s.vx[i], s.vy[i], s.vz[i])}; };
  BedSlice slice;
  slice.x0 = s.x[s.so];
  slice.so = disc(s.so, s.radius[s.so]);
  slice.y_lo = s.box_lo[1];
  slice.y_hi = s.box_hi[1];
  slice.z_lo = s.box_lo[2];
  slice.z_hi = s.box_hi[2];
  const double lx = s.box_hi[0] - s.box_lo[0];
  for (size_t i = 0; i < s.size(); ++i) {
    if (s.type[i] != 1) continue;
    double dx = s.x[i] - slice.x0;
    dx -= lx * std::round(dx / lx);  // the nearest periodic image
    const double r = s.radius[i];
    if (std::abs(dx) < r) slice.grains.push_back(disc(i, std::sqrt(r * r - dx * dx)));
  }
  return slice;
}

std::vector<size_t> PickSnapshotFrames(const std::vector<double>& t, const std::vector<double>& fractions,
                                       double t_end) {
  std::vector<size_t> picked;
  for (double phi : fractions) picked.push_back(NearestSnapshotFrame(t, phi * t_end));
  return picked;
}

std::vector<bool> SnapshotFramesStillNeeded(const std::vector<double>& t, const std::vector<double>& fractions,
                                            double t_now) {
  std::vector<bool> keep(t.size(), false);
  if (t.empty()) return keep;
  for (double phi : fractions) {
    if (phi == 0) {  // the target is 0 whatever the run's length
      keep[NearestSnapshotFrame(t, 0)] = true;
      continue;
    }
    // The target phi * t_end is at least phi * t_now, so a frame before the last one at or before
    // phi * t_now is at least as far from it as that one: as far only when the two share a time,
    // and then the tie goes to the earliest of that time. That earliest frame and every frame
    // after it can still be picked; no frame before.
    const size_t upto = std::upper_bound(t.begin(), t.end(), phi * t_now) - t.begin();
    const size_t from = upto == 0 ? 0 : FirstSnapshotFrameAt(t, t[upto - 1]);
    for (size_t i = from; i < t.size(); ++i) keep[i] = true;
  }
  return keep;
}

}  // namespace sandswim
