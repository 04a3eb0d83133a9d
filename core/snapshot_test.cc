#include "core/snapshot.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;

struct SnapAtom {
  int64_t id;
  int type;
  double x, y, z, vx, vy, vz, radius;

  double Value(const std::string& column) const {
    const std::map<std::string, double> v = {
        {"id", double(id)}, {"type", double(type)}, {"x", x},       {"y", y}, {"z", z}, {"vx", vx}, {"vy", vy},
        {"vz", vz},         {"radius", radius},     {"omegax", -80}};
    return v.at(column);
  }
};

std::string ShortestText(double v) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

constexpr double kSnapLo[3] = {-0.1, -0.19, -0.25}, kSnapHi[3] = {0.1, 0.19, 0.65};

// A frame as the engine writes one: its header ("pp pp fm": x and y periodic), the ATOMS line and
// every atom line ending in a blank before the newline.
std::string SnapDump(const std::vector<SnapAtom>& atoms, const std::string& columns = kSnapshotColumns,
                     int64_t step = 4200) {
  std::ostringstream out;
  out << "ITEM: TIMESTEP\n" << step << "\nITEM: NUMBER OF ATOMS\n" << atoms.size() << "\nITEM: BOX BOUNDS pp pp fm\n";
  for (int k = 0; k < 3; ++k) out << ShortestText(kSnapLo[k]) << " " << ShortestText(kSnapHi[k]) << "\n";
  out << "ITEM: ATOMS " << columns << " \n";
  for (const SnapAtom& a : atoms) {
    std::istringstream names(columns);
    for (std::string name; names >> name;) out << ShortestText(a.Value(name)) << " ";
    out << "\n";
  }
  return out.str();
}

// A few grains (r = 0.01 m) around the SO (r = 0.03 m), which sits near the box's upper x bound so
// that one grain near the lower bound is cut by the plane through the SO at its periodic image.
constexpr double kSoX = 0.095, kGrainR = 0.01;
std::vector<SnapAtom> SmallBed() {
  return {
      {11, 1, kSoX, 0.05, 0.1, 0.1, -0.2, 0.3, kGrainR},                    // on the plane
      {12, 1, kSoX - 0.6 * kGrainR, -0.05, 0.12, 0, 0, -1.5, kGrainR},      // dx = -0.6 r
      {7, 2, kSoX, 0.02, 0.0, 0.01, 0.02, -0.03, 0.03},                     // the SO
      {13, 1, kSoX + 0.6 * kGrainR - 0.2, 0.15, -0.2, 0, 0.5, 0, kGrainR},  // dx = 0.6 r, across x
      {14, 1, kSoX - 1.5 * kGrainR, 0.0, 0.3, 1e-7, 0, 0, kGrainR},         // too far from the plane
      {15, 1, 0.0, -0.1, 0.2, 2.5e-3, 1.25e-17, -7.0, kGrainR},             // far away
  };
}

TEST(SnapshotParseTest, ReadsAFrameAsTheEngineWritesIt) {
  const std::vector<SnapAtom> atoms = SmallBed();
  auto s = ParseBedSnapshot(SnapDump(atoms));
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->step, 4200);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(s->box_lo[k], kSnapLo[k]);
    EXPECT_EQ(s->box_hi[k], kSnapHi[k]);
  }
  ASSERT_EQ(s->size(), atoms.size());
  EXPECT_EQ(s->grains(), static_cast<int64_t>(atoms.size()) - 1);
  ASSERT_EQ(s->type[s->so], 2);
  EXPECT_EQ(s->id[s->so], 7);
  for (size_t i = 0; i < atoms.size(); ++i) {
    const SnapAtom& a = atoms[i];
    EXPECT_EQ(s->id[i], a.id);
    EXPECT_EQ(s->type[i], a.type);
    EXPECT_EQ(s->x[i], a.x);
    EXPECT_EQ(s->y[i], a.y);
    EXPECT_EQ(s->z[i], a.z);
    EXPECT_EQ(s->vx[i], a.vx);
    EXPECT_EQ(s->vy[i], a.vy);
    EXPECT_EQ(s->vz[i], a.vz);
    EXPECT_EQ(s->radius[i], a.radius);
  }
}

TEST(SnapshotParseTest, ColumnsInAnyOrderAndMoreColumnsReadTheSame) {
  auto usual = ParseBedSnapshot(SnapDump(SmallBed()));
  auto other = ParseBedSnapshot(SnapDump(SmallBed(), "radius vz omegax vy vx z y x type id"));
  ASSERT_TRUE(usual.ok() && other.ok()) << other.status().ToString();
  EXPECT_EQ(other->id, usual->id);
  EXPECT_EQ(other->x, usual->x);
  EXPECT_EQ(other->vz, usual->vz);
  EXPECT_EQ(other->radius, usual->radius);
  EXPECT_EQ(other->so, usual->so);
}

TEST(SnapshotParseTest, RefusesWhatIsNotOneSnapshotNamingWhy) {
  const std::string one = SnapDump(SmallBed());
  auto reason = [](const std::string& text) {
    auto s = ParseBedSnapshot(text);
    EXPECT_EQ(s.status().code(), StatusCode::kInvalidArgument) << text;
    return s.status().reason();
  };
  EXPECT_THAT(reason(one + SnapDump(SmallBed())), HasSubstr("holds 2"));
  EXPECT_THAT(reason(""), HasSubstr("holds 0"));
  EXPECT_THAT(reason(SnapDump(SmallBed(), "id type x y z vx vy radius")), HasSubstr("missing: vz"));
  EXPECT_THAT(reason(SnapDump(SmallBed(), "id x y z radius")), HasSubstr("missing: type vx vy vz"));

  std::vector<SnapAtom> none = SmallBed();
  for (SnapAtom& a : none) a.type = 1;
  EXPECT_THAT(reason(SnapDump(none)), HasSubstr("none"));
  // Atom lines start on line 10 (after the 9 header lines).
  std::vector<SnapAtom> two = SmallBed();
  two[4].type = 2;
  EXPECT_THAT(reason(SnapDump(two)), HasSubstr("dump line 14: a second SO"));
  EXPECT_THAT(reason(SnapDump(two)), HasSubstr("the first is on dump line 12"));
  std::vector<SnapAtom> other_type = SmallBed();
  other_type[1].type = 3;
  EXPECT_THAT(reason(SnapDump(other_type)), HasSubstr("dump line 11: atom type 3"));
  std::vector<SnapAtom> flat = SmallBed();
  flat[5].radius = 0;
  EXPECT_THAT(reason(SnapDump(flat)), HasSubstr("dump line 15: radius 0"));
  std::vector<SnapAtom> blown_up = SmallBed();
  blown_up[3].vy = NAN;
  EXPECT_THAT(reason(SnapDump(blown_up)), HasSubstr("dump line 13: vy is nan"));
  blown_up[3].vy = INFINITY;
  EXPECT_THAT(reason(SnapDump(blown_up)), HasSubstr("vy is inf"));

  // Cut anywhere, even just before the last newline, the frame is torn: the last number might
  // be cut short, so it is not read.
  EXPECT_THAT(reason(one.substr(0, one.size() - 1)), HasSubstr("torn"));
  EXPECT_THAT(reason(one.substr(0, one.size() / 2)), HasSubstr("torn"));
  EXPECT_THAT(reason(one + one.substr(0, 40)), HasSubstr("torn"));
  // What the dump reader refuses, with its line.
  std::string garbled = one;
  garbled.replace(garbled.find("ITEM: NUMBER"), 12, "ITEM: COUNT ");
  EXPECT_THAT(reason(garbled), HasSubstr("dump line 3"));
  std::string tilted = one;
  tilted.replace(tilted.find("-0.1 0.1\n"), 9, "-0.1 0.1 0.01\n");
  EXPECT_THAT(reason(tilted), HasSubstr("dump line 6: a snapshot's box is orthogonal"));
}

// The legacy VTK file read back by a reader of its own: the header's four lines, then POINTS,
// VERTICES and POINT_DATA sections read as tokens. Integer arrays must hold integers.
struct VtkReadBack {
  std::vector<std::string> header;  // the first four lines
  std::vector<double> points;       // x y z per point
  std::vector<std::vector<int64_t>> vertices;
  size_t point_data = 0;
  std::map<std::string, std::string> type;  // array name -> data type
  std::map<std::string, std::vector<double>> values;
  std::string error;
};

VtkReadBack ReadVtkBack(const std::string& text) {
  VtkReadBack r;
  std::istringstream in(text);
  for (std::string line; r.header.size() < 4 && std::getline(in, line);) r.header.push_back(line);
  auto fail = [&r](const std::string& what) {
    if (r.error.empty()) r.error = what;
    return r;
  };
  auto number = [&in](const std::string& type, double* v) {
    std::string tok;
    if (!(in >> tok)) return false;
    const char* end = tok.data() + tok.size();
    if (type == "double") return std::from_chars(tok.data(), end, *v).ptr == end;
    int64_t n = 0;
    if (std::from_chars(tok.data(), end, n).ptr != end) return false;
    *v = static_cast<double>(n);
    return true;
  };
  std::string word, kind;
  size_t n = 0, size = 0;
  if (!(in >> word >> n >> kind) || word != "POINTS") return fail("no POINTS");
  r.points.resize(3 * n);
  for (double& v : r.points)
    if (!number(kind, &v)) return fail("bad point");
  if (!(in >> word >> n >> size) || word != "VERTICES") return fail("no VERTICES");
  for (size_t c = 0; c < n; ++c) {
    int64_t count = 0;
    in >> count;
    std::vector<int64_t> cell(std::max<int64_t>(count, 0));
    for (int64_t& p : cell) in >> p;
    r.vertices.push_back(cell);
  }
  if (!(in >> word >> r.point_data) || word != "POINT_DATA") return fail("no POINT_DATA");
  while (in >> word) {
    std::string name, type;
    size_t components = 3;
    if (word == "SCALARS") {
      std::string lookup, table;
      if (!(in >> name >> type >> components >> lookup >> table) || lookup != "LOOKUP_TABLE")
        return fail("bad SCALARS " + name);
    } else if (word == "VECTORS") {
      if (!(in >> name >> type)) return fail("bad VECTORS");
    } else {
      return fail("unknown section " + word);
    }
    r.type[name] = type;
    std::vector<double>& v = r.values[name];
    v.resize(components * r.point_data);
    for (double& x : v)
      if (!number(type, &x)) return fail("bad value in " + name);
  }
  return r;
}

TEST(SnapshotVtkTest, ReadsBackAsEveryAtomWithItsData) {
  auto s = ParseBedSnapshot(SnapDump(SmallBed()));
  ASSERT_TRUE(s.ok());
  const VtkReadBack v = ReadVtkBack(BedSnapshotVtk(*s, "bed 3, run 42, t = 1.5 s"));
  ASSERT_EQ(v.error, "");
  ASSERT_EQ(v.header.size(), 4u);
  EXPECT_EQ(v.header[0], "# vtk DataFile Version 3.0");
  EXPECT_EQ(v.header[1], "bed 3, run 42, t = 1.5 s");
  EXPECT_EQ(v.header[2], "ASCII");
  EXPECT_EQ(v.header[3], "DATASET POLYDATA");

  const size_t n = static_cast<size_t>(s->grains()) + 1;  // the grains and the SO
  ASSERT_EQ(v.points.size(), 3 * n);
  ASSERT_EQ(v.vertices.size(), n);
  EXPECT_EQ(v.point_data, n);
  for (size_t i = 0; i < n; ++i) {
    EXPECT_EQ(v.points[3 * i], s->x[i]);
    EXPECT_EQ(v.points[3 * i + 1], s->y[i]);
    EXPECT_EQ(v.points[3 * i + 2], s->z[i]);
    EXPECT_EQ(v.vertices[i], std::vector<int64_t>{static_cast<int64_t>(i)});
  }
  const std::map<std::string, std::string> types = {
      {"id", "vtktypeint64"}, {"type", "int"}, {"radius", "double"}, {"speed", "double"}, {"velocity", "double"}};
  EXPECT_EQ(v.type, types);
  for (const auto& [name, values] : v.values) EXPECT_EQ(values.size(), (name == "velocity" ? 3 : 1) * n) << name;
  for (size_t i = 0; i < n; ++i) {
    EXPECT_EQ(v.values.at("id")[i], s->id[i]);
    EXPECT_EQ(v.values.at("type")[i], s->type[i]);
    EXPECT_EQ(v.values.at("radius")[i], s->radius[i]);
    EXPECT_EQ(v.values.at("speed")[i], std::hypot(s->vx[i], s->vy[i], s->vz[i]));
    EXPECT_EQ(v.values.at("velocity")[3 * i], s->vx[i]);
    EXPECT_EQ(v.values.at("velocity")[3 * i + 1], s->vy[i]);
    EXPECT_EQ(v.values.at("velocity")[3 * i + 2], s->vz[i]);
  }
}

TEST(SnapshotVtkTest, TheTitleIsOneLineOfAtMost255Bytes) {
  auto s = ParseBedSnapshot(SnapDump(SmallBed()));
  ASSERT_TRUE(s.ok());
  const VtkReadBack two_lines = ReadVtkBack(BedSnapshotVtk(*s, "first\nsecond\r\n"));
  EXPECT_EQ(two_lines.error, "");
  EXPECT_EQ(two_lines.header[1].find_first_of("\r\n"), std::string::npos);
  EXPECT_THAT(two_lines.header[1], HasSubstr("second"));

  const VtkReadBack long_title = ReadVtkBack(BedSnapshotVtk(*s, std::string(400, 'a')));
  EXPECT_EQ(long_title.error, "");
  EXPECT_EQ(long_title.header[1], std::string(255, 'a'));
  // A two-byte character across the 255th byte is left out whole.
  const VtkReadBack accented = ReadVtkBack(BedSnapshotVtk(*s, std::string(254, 'a') + "\xC3\xA9 and more"));
  EXPECT_EQ(accented.header[1], std::string(254, 'a'));
  EXPECT_EQ(accented.header[2], "ASCII");
}

TEST(SnapshotSliceTest, TheParsedBedCutThroughTheSo) {
  auto s = ParseBedSnapshot(SnapDump(SmallBed()));
  ASSERT_TRUE(s.ok());
  const BedSlice slice = SliceThroughSo(*s);
  EXPECT_EQ(slice.x0, kSoX);
  EXPECT_EQ(slice.so.y, 0.02);
  EXPECT_EQ(slice.so.z, 0.0);
  EXPECT_EQ(slice.so.r, 0.03);
  EXPECT_DOUBLE_EQ(slice.so.speed, std::sqrt(0.01 * 0.01 + 0.02 * 0.02 + 0.03 * 0.03));
  EXPECT_EQ(slice.y_lo, kSnapLo[1]);
  EXPECT_EQ(slice.y_hi, kSnapHi[1]);
  EXPECT_EQ(slice.z_lo, kSnapLo[2]);
  EXPECT_EQ(slice.z_hi, kSnapHi[2]);
  // The grain on the plane, the one at dx = -0.6 r, and the one across the x boundary at dx = 0.6 r
  // (its nearest image), in the snapshot's order; not the ones 1.5 r and farther away.
  ASSERT_EQ(slice.grains.size(), 3u);
  EXPECT_EQ(slice.grains[0].y, 0.05);
  EXPECT_DOUBLE_EQ(slice.grains[0].r, kGrainR);
  EXPECT_DOUBLE_EQ(slice.grains[0].speed, std::sqrt(0.1 * 0.1 + 0.2 * 0.2 + 0.3 * 0.3));
  EXPECT_EQ(slice.grains[1].y, -0.05);
  EXPECT_NEAR(slice.grains[1].r, 0.8 * kGrainR, 1e-12);
  EXPECT_DOUBLE_EQ(slice.grains[1].speed, 1.5);
  EXPECT_EQ(slice.grains[2].y, 0.15);
  EXPECT_EQ(slice.grains[2].z, -0.2);
  EXPECT_NEAR(slice.grains[2].r, 0.8 * kGrainR, 1e-12);
}

// A snapshot made by hand with exact binary numbers: the SO at x = 0, grains of radius 5/8.
BedSnapshot HandMadeSnapshot(const std::vector<double>& grain_x) {
  BedSnapshot s;
  s.box_lo = {-4, -4, 0};
  s.box_hi = {4, 4, 16};
  auto add = [&s](int type, double x, double r) {
    s.id.push_back(static_cast<int64_t>(s.id.size()) + 1);
    s.type.push_back(type);
    s.x.push_back(x);
    s.y.push_back(static_cast<double>(s.id.size()));
    s.z.push_back(1);
    s.vx.push_back(3);
    s.vy.push_back(0);
    s.vz.push_back(4);
    s.radius.push_back(r);
  };
  add(2, 0, 1.5);
  for (double x : grain_x) add(1, x, 0.625);
  return s;
}

TEST(SnapshotSliceTest, ADiscIsThePlanesCutThroughTheGrain) {
  // dx = 0.6 r (3/8 of 5/8) gives a disc of 0.8 r; |dx| = r only touches the plane: no disc.
  const BedSlice slice = SliceThroughSo(HandMadeSnapshot({0.375, -0.375, 0.625, -0.625, 0.7, 0}));
  ASSERT_EQ(slice.grains.size(), 3u);
  EXPECT_EQ(slice.grains[0].r, 0.5);
  EXPECT_EQ(slice.grains[1].r, 0.5);
  EXPECT_EQ(slice.grains[2].r, 0.625);
  EXPECT_EQ(slice.grains[2].y, 7);  // the last grain: the slice keeps the snapshot's order
  EXPECT_EQ(slice.grains[0].speed, 5);
  EXPECT_EQ(slice.so.r, 1.5);
  EXPECT_EQ(slice.so.speed, 5);
  EXPECT_EQ(slice.x0, 0);
}

TEST(SnapshotSliceTest, GrainsAreCutAtTheirNearestPeriodicImageInX) {
  BedSnapshot s = HandMadeSnapshot({-3.625, 3.625, -3.25});
  s.x[s.so] = 3.75;  // near the upper x bound (4); the box is 8 wide
  const BedSlice slice = SliceThroughSo(s);
  // -3.625 is 0.625 from the plane through the image at 4.375: touching, no disc; 3.625 is 0.125
  // away; -3.25 is 1 away (at 4.75) but 7 in the box: no disc either way.
  ASSERT_EQ(slice.grains.size(), 1u);
  EXPECT_EQ(slice.grains[0].y, 3);
  s.x[s.so] = 3.875;  // now -3.625 is 0.5 away through the boundary, 3.625 0.25 away in the box
  const BedSlice moved = SliceThroughSo(s);
  ASSERT_EQ(moved.grains.size(), 2u);
  EXPECT_EQ(moved.grains[0].r, std::sqrt(0.625 * 0.625 - 0.5 * 0.5));
  EXPECT_EQ(moved.grains[1].r, std::sqrt(0.625 * 0.625 - 0.25 * 0.25));
}

// The nearest frame by looking at every frame; of two equally near, the earlier.
size_t NearestFrameByScan(const std::vector<double>& t, double target) {
  size_t best = 0;
  for (size_t i = 1; i < t.size(); ++i)
    if (std::abs(t[i] - target) < std::abs(t[best] - target)) best = i;
  return best;
}

TEST(SnapshotFramesTest, PicksTheFrameNearestEachFraction) {
  std::vector<double> t;
  for (int i = 0; i <= 10; ++i) t.push_back(0.5 * i);  // 0, 0.5, ..., 5 s
  // The run stopped at 4.6 s: its start, its middle (2.3 s: nearest 2.5) and its end (4.5).
  EXPECT_EQ(PickSnapshotFrames(t, {0, 0.5, 1}, 4.6), (std::vector<size_t>{0, 5, 9}));
  EXPECT_EQ(PickSnapshotFrames(t, {1, 0.5, 0}, 4.6), (std::vector<size_t>{9, 5, 0}));  // in the order asked
  // 2.25 s is as near 2 s as 2.5 s: the earlier.
  EXPECT_EQ(PickSnapshotFrames(t, {0.5}, 4.5), (std::vector<size_t>{4}));
  // Past the last frame: the last frame.
  EXPECT_EQ(PickSnapshotFrames(t, {1}, 7), (std::vector<size_t>{10}));
  // Frames sharing a time: the first of them.
  EXPECT_EQ(PickSnapshotFrames({0, 1, 1, 1, 2}, {0.5, 0.6, 0.4}, 2), (std::vector<size_t>{1, 1, 1}));
  EXPECT_EQ(PickSnapshotFrames({0, 0, 1}, {0}, 1), (std::vector<size_t>{0}));

  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> u(0, 1);
  for (int c = 0; c < 300; ++c) {
    std::vector<double> times = {0};
    const int n = 1 + static_cast<int>(rng() % 12);
    for (int i = 1; i < n; ++i) times.push_back(times.back() + (rng() % 4) * 0.25);  // ties and shared times
    const double t_end = (rng() % 20) * 0.125;
    const std::vector<double> fractions = {0, 0.25, 0.5, 1, u(rng)};
    const std::vector<size_t> picked = PickSnapshotFrames(times, fractions, t_end);
    for (size_t f = 0; f < fractions.size(); ++f)
      EXPECT_EQ(picked[f], NearestFrameByScan(times, fractions[f] * t_end)) << "case " << c << " fraction " << f;
  }
}

TEST(SnapshotFramesTest, OnlyFramesNoPickCanTakeAreLetGo) {
  std::vector<double> t;
  for (int i = 0; i <= 10; ++i) t.push_back(i);
  // At t = 10 s: the start is frame 0 whatever the run's length; the middle is at least 5 s and
  // the end at least 10 s, so frames 1 to 4 will never be picked.
  const std::vector<bool> keep = SnapshotFramesStillNeeded(t, {0, 0.5, 1}, 10);
  for (size_t i = 0; i < t.size(); ++i) EXPECT_EQ(keep[i], i == 0 || i >= 5) << i;
  // Asking for no snapshot needs no frame; asking for the end only needs the latest.
  EXPECT_EQ(SnapshotFramesStillNeeded(t, {}, 10), std::vector<bool>(t.size(), false));
  const std::vector<bool> end_only = SnapshotFramesStillNeeded(t, {1}, 10);
  EXPECT_EQ(std::count(end_only.begin(), end_only.end(), true), 1);
  EXPECT_TRUE(end_only.back());
  EXPECT_TRUE(SnapshotFramesStillNeeded({}, {0.5}, 3).empty());
}

// The promise the deletion rests on: whatever the run's length t_end >= t_now turns out to be, and
// whatever frames come after t_now, every frame PickSnapshotFrames picks at the end was kept.
TEST(SnapshotFramesTest, EveryFrameAPickCanTakeIsStillNeeded) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  int let_go = 0;
  for (int c = 0; c < 500; ++c) {
    // Frames of a whole run, evenly spaced (ties with targets) or not, sometimes sharing a time.
    const bool even = rng() % 2 == 0;
    const double dt = even ? 0.25 : 0.05 + u(rng);
    std::vector<double> all = {0};
    const int n = 1 + static_cast<int>(rng() % 40);
    for (int i = 1; i < n; ++i) all.push_back(all.back() + (rng() % 8 == 0 ? 0 : even ? dt : dt * u(rng)));
    std::vector<double> fractions;
    for (int f = 1 + static_cast<int>(rng() % 4); f > 0; --f) {
      const double choices[] = {0, 0.5, 1, u(rng), u(rng)};
      fractions.push_back(choices[rng() % 5]);
    }
    // Now: at a frame, or between frames; the frames so far are those at or before it.
    const double t_now = rng() % 2 == 0 ? all[rng() % all.size()] : all.back() * u(rng);
    std::vector<double> so_far;
    for (double t : all)
      if (t <= t_now) so_far.push_back(t);
    const std::vector<bool> keep = SnapshotFramesStillNeeded(so_far, fractions, t_now);
    ASSERT_EQ(keep.size(), so_far.size());
    let_go += static_cast<int>(std::count(keep.begin(), keep.end(), false));

    const double t_ends[] = {t_now, t_now + dt * u(rng), t_now * (1 + u(rng)), std::max(t_now, all.back()),
                             all.back() + 10 * dt};
    for (double t_end : t_ends) {
      // The run ends now with the frames so far, or later with more frames.
      for (size_t p : PickSnapshotFrames(so_far, fractions, t_end))
        EXPECT_TRUE(keep[p]) << "case " << c << ": frame " << p << " picked for t_end " << t_end;
      for (size_t p : PickSnapshotFrames(all, fractions, t_end))
        if (p < so_far.size()) {
          EXPECT_TRUE(keep[p]) << "case " << c << ": frame " << p << " of all, t_end " << t_end;
        }
    }
  }
  EXPECT_GT(let_go, 500);  // the property holds with frames let go, not by keeping them all
}

}  // namespace
}  // namespace sandswim
