#include "core/dump_reader.h"
#include "tests/fixture_file.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

using testing::Fixture;  // tests/fixture_file.h

constexpr char kTwoFrames[] =
    "ITEM: TIMESTEP\n"
    "0\n"
    "ITEM: NUMBER OF ATOMS\n"
    "2\n"
    "ITEM: BOX BOUNDS pp pp ff\n"
    "-0.1 0.1\n"
    "-0.19 0.19\n"
    "-0.25 0.65\n"
    "ITEM: ATOMS id x y z \n"
    "1 0.5 0.25 -1e-3 \n"
    "2 1.5 -2 3.25\n"
    "ITEM: TIMESTEP\n"
    "100\n"
    "ITEM: NUMBER OF ATOMS\n"
    "2\n"
    "ITEM: BOX BOUNDS pp pp ff\n"
    "-0.1 0.1\n"
    "-0.19 0.19\n"
    "-0.25 0.65\n"
    "ITEM: ATOMS id x y z\n"
    "1 0.6 0.35 -2e-3\n"
    "2 1.6 -2.1 3.5\n";

TEST(DumpReaderTest, ReadsFramesAndColumns) {
  auto frames = ReadDump(kTwoFrames);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 2u);
  const DumpFrame& f0 = (*frames)[0];
  EXPECT_EQ(f0.step, 0);
  EXPECT_EQ(f0.atoms, 2);
  EXPECT_EQ(*f0.columns, (std::vector<std::string>{"id", "x", "y", "z"}));
  EXPECT_EQ(f0.Column("z"), 3);
  EXPECT_EQ(f0.Column("omegax"), -1);
  EXPECT_DOUBLE_EQ(f0.At(0, 3), -1e-3);
  EXPECT_DOUBLE_EQ(f0.At(1, 2), -2.0);
  EXPECT_EQ((*frames)[1].step, 100);
  EXPECT_DOUBLE_EQ((*frames)[1].At(1, 3), 3.5);
}

TEST(DumpReaderTest, ChunkBoundariesDoNotMatter) {
  const std::string text = kTwoFrames;
  for (size_t chunk = 1; chunk <= 17; ++chunk) {
    DumpReader r;
    DumpFrameCollector collector;
    std::vector<DumpFrame> frames;
    for (size_t i = 0; i < text.size(); i += chunk) {
      ASSERT_TRUE(r.Feed(std::string_view(text).substr(i, chunk), collector).ok());
      for (auto& f : collector.Take()) frames.push_back(std::move(f));
    }
    ASSERT_TRUE(r.Finish().ok());
    EXPECT_FALSE(r.torn());
    ASSERT_EQ(frames.size(), 2u) << "chunk " << chunk;
    EXPECT_DOUBLE_EQ(frames[1].At(0, 1), 0.6);
  }
}

// A file cut at any byte yields exactly the frames that were complete before the cut, with the
// values they had in the whole file: a torn frame is held back, never misread.
TEST(DumpReaderTest, TornFrameAtEveryCutIsHeldBack) {
  const std::string text = kTwoFrames;
  const size_t first_frame_end = text.find("ITEM: TIMESTEP\n100");
  for (size_t cut = 0; cut < text.size(); ++cut) {
    DumpReader r;
    DumpFrameCollector collector;
    ASSERT_TRUE(r.Feed(std::string_view(text).substr(0, cut), collector).ok()) << "cut " << cut;
    auto frames = collector.Take();
    ASSERT_TRUE(r.Finish().ok());
    size_t expected = cut >= first_frame_end ? 1 : 0;
    ASSERT_EQ(frames.size(), expected) << "cut " << cut;
    if (expected == 1) {
      EXPECT_DOUBLE_EQ(frames[0].At(1, 3), 3.25);
    }
    // Cut after the last complete frame's newline: nothing torn; anywhere else: torn.
    EXPECT_EQ(r.torn(), cut != 0 && cut != first_frame_end) << "cut " << cut;
  }
}

TEST(DumpReaderTest, CutInsideANumberIsNotReadAsAShorterNumber) {
  // "3.5" cut to "3." would parse as 3.0 if the reader used an unterminated line.
  std::string text = kTwoFrames;
  text.resize(text.size() - 2);  // drop "5\n"
  DumpReader r;
  DumpFrameCollector collector;
  ASSERT_TRUE(r.Feed(text, collector).ok());
  EXPECT_EQ(collector.Take().size(), 1u);
  EXPECT_TRUE(r.torn());
}

TEST(DumpReaderTest, CorruptNumberNamesLineAndColumn) {
  std::string text = kTwoFrames;
  text.replace(text.find("1.6 -2.1"), 3, "1.x");
  auto frames = ReadDump(text);
  ASSERT_FALSE(frames.ok());
  EXPECT_EQ(frames.status().code(), StatusCode::kCorruption);
  EXPECT_NE(frames.status().reason().find("dump line 22"), std::string::npos) << frames.status().reason();
  EXPECT_NE(frames.status().reason().find("column 'x'"), std::string::npos) << frames.status().reason();
}

TEST(DumpReaderTest, CorruptStructureIsReported) {
  struct Case {
    std::string from, to, needle;
  } cases[] = {
      {"ITEM: NUMBER OF ATOMS\n2", "ITEM: NUMBER OF ATOMS\ntwo", "dump line 4"},
      {"100\n", "1e2\n", "timestep"},
      {"ITEM: TIMESTEP\n0", "ITEM: TIMESTAMP\n0", "dump line 1"},
      {"2 1.5 -2 3.25", "2 1.5 -2", "3 values"},
      {"2 1.5 -2 3.25", "2 1.5 -2 3.25 7", "more than 4"},
      {"-0.19 0.19\n-0.25", "-0.19\n-0.25", "box bound"},
  };
  for (const Case& c : cases) {
    std::string text = kTwoFrames;
    text.replace(text.find(c.from), c.from.size(), c.to);
    auto frames = ReadDump(text);
    ASSERT_FALSE(frames.ok()) << c.to;
    EXPECT_EQ(frames.status().code(), StatusCode::kCorruption);
    EXPECT_NE(frames.status().reason().find(c.needle), std::string::npos) << frames.status().reason();
  }
}

TEST(DumpReaderTest, ErrorStateIsSticky) {
  DumpReader r;
  DumpFrameCollector collector;
  EXPECT_FALSE(r.Feed("ITEM: NONSENSE\n", collector).ok());
  EXPECT_FALSE(r.Feed("ITEM: TIMESTEP\n", collector).ok());
  EXPECT_FALSE(r.Finish().ok());
}

TEST(DumpReaderTest, RealLiggghtsDumpOfTheSo) {
  const std::string text = Fixture("so_omega_minus80.dump");
  ASSERT_FALSE(text.empty());
  auto frames = ReadDump(text);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 301u);  // every 100 steps over 30000 steps
  const DumpFrame& first = frames->front();
  EXPECT_EQ(first.columns->size(), 10u);
  EXPECT_EQ(first.columns, frames->back().columns) << "frames share their column names";
  EXPECT_EQ(first.atoms, 1);
  EXPECT_EQ(first.Column("omegax"), 7);
  EXPECT_DOUBLE_EQ(first.At(0, first.Column("id")), 2621);
  EXPECT_DOUBLE_EQ(first.At(0, first.Column("z")), -0.0112944);
  EXPECT_DOUBLE_EQ(first.At(0, first.Column("omegax")), -80);
  EXPECT_EQ(frames->back().step, 30000);
  EXPECT_DOUBLE_EQ(frames->back().At(0, 3), 0.0266815);
}

TEST(DumpReaderTest, RealDumpTornAtSeveralCuts) {
  const std::string text = Fixture("so_omega_plus80.dump");
  auto all = ReadDump(text);
  ASSERT_TRUE(all.ok());
  for (size_t cut : {text.size() - 1, text.size() - 30, text.size() / 2 + 7, size_t{1000}}) {
    DumpReader r;
    DumpFrameCollector collector;
    // Feed in 4 KB chunks, as the worker does while tailing.
    for (size_t i = 0; i < cut; i += 4096) {
      ASSERT_TRUE(r.Feed(std::string_view(text).substr(i, std::min<size_t>(4096, cut - i)), collector).ok());
    }
    auto frames = collector.Take();
    EXPECT_TRUE(r.torn());
    ASSERT_LT(frames.size(), all->size());
    ASSERT_FALSE(frames.empty());
    for (size_t i = 0; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i].values, (*all)[i].values) << "cut " << cut << " frame " << i;
    }
  }
}

// --- Property tests against a simple reference parser -----------------------------------------

struct RefFrame {
  int64_t step = 0;
  std::vector<std::string> columns;
  int64_t atoms = 0;
  std::vector<double> values;
};

std::vector<std::string> Tokens(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ' ' || c == '\t' || c == '\r') {
      if (!cur.empty()) out.push_back(cur);
      cur.clear();
    } else {
      cur.push_back(c);
    }
  }
  if (!cur.empty()) out.push_back(cur);
  return out;
}

// One std::from_chars per token; a '+' is stripped and a denormal-small out-of-range result kept.
double RefNumber(const std::string& tok) {
  const char* first = tok.data() + (tok[0] == '+' ? 1 : 0);
  double v = 0;
  auto [ptr, ec] = std::from_chars(first, tok.data() + tok.size(), v);
  EXPECT_TRUE(ptr == tok.data() + tok.size() && (ec == std::errc() || std::fabs(v) < 1.0)) << tok;
  return v;
}

// The frames of a well-formed dump whose every line is complete (text after the last '\n' is
// ignored); a frame missing lines at the end is dropped.
std::vector<RefFrame> RefParse(const std::string& text) {
  std::vector<std::string> lines;
  size_t start = 0;
  for (size_t nl; (nl = text.find('\n', start)) != std::string::npos; start = nl + 1) {
    lines.push_back(text.substr(start, nl - start));
  }
  std::vector<RefFrame> frames;
  size_t i = 0;
  auto next = [&](std::vector<std::string>* toks) {
    if (i >= lines.size()) return false;
    *toks = Tokens(lines[i++]);
    return true;
  };
  std::vector<std::string> t;
  while (i < lines.size()) {
    if (!next(&t)) break;
    if (t.empty()) continue;  // blank line between frames
    RefFrame f;
    if (!next(&t)) break;
    f.step = std::stoll(t.at(0));
    if (!next(&t) || !next(&t)) break;
    f.atoms = std::stoll(t.at(0));
    if (!next(&t) || !next(&t) || !next(&t) || !next(&t) || !next(&t)) break;
    f.columns.assign(t.begin() + 2, t.end());
    bool whole = true;
    for (int64_t a = 0; a < f.atoms && whole; ++a) {
      whole = next(&t);
      if (!whole) break;
      for (const std::string& tok : t) f.values.push_back(RefNumber(tok));
    }
    if (!whole) break;
    frames.push_back(std::move(f));
  }
  return frames;
}

uint64_t Bits(double v) {
  uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}

// Frames equal to the reference's, values bit for bit.
void ExpectSameFrames(const std::vector<DumpFrame>& got, const std::vector<RefFrame>& want, const std::string& what) {
  ASSERT_EQ(got.size(), want.size()) << what;
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].step, want[i].step) << what << " frame " << i;
    ASSERT_EQ(got[i].atoms, want[i].atoms) << what << " frame " << i;
    ASSERT_TRUE(got[i].columns != nullptr);
    ASSERT_EQ(*got[i].columns, want[i].columns) << what << " frame " << i;
    ASSERT_EQ(got[i].values.size(), want[i].values.size()) << what << " frame " << i;
    for (size_t k = 0; k < got[i].values.size(); ++k) {
      ASSERT_EQ(Bits(got[i].values[k]), Bits(want[i].values[k]))
          << what << " frame " << i << " value " << k << ": " << got[i].values[k] << " vs " << want[i].values[k];
    }
  }
}

// A dump with awkward numbers and spacing: many digits, leading zeros, exponents, signs, negative
// zero, denormals, 2^53 + 1, a 70-digit number, tabs, trailing blanks, "\r\n", blank lines.
std::string AwkwardDump(uint32_t seed, int frames) {
  static const char* kOdd[] = {"0",
                               "-0",
                               "-0.0",
                               "+0",
                               "000123.4500",
                               "1e-320",
                               "-4.9e-324",
                               "+1.5",
                               "9007199254740993",
                               "9007199254740992",
                               "123456789012345678901234",
                               ".5",
                               "5.",
                               "2.2250738585072014e-308",
                               "1.7976931348623157e308",
                               "1E5",
                               "1e+05",
                               "-1.5e-05",
                               "12345678.87654321",
                               "1234567.1234567",
                               "0.000000123",
                               "1e22",
                               "1e23",
                               "1e-22",
                               "123456789012345678901234567890123456789012345678901234567890123456789.5",
                               "0.1",
                               "-80",
                               "2621",
                               "1e0",
                               "7e-5",
                               "99999999",
                               "0.99999999"};
  std::mt19937 rng(seed);
  auto pick = [&](int n) { return static_cast<int>(rng() % static_cast<uint32_t>(n)); };
  std::uniform_real_distribution<double> u(-1, 1);
  std::string out;
  char buf[64];
  const char* eols[] = {"\n", " \n", "\r\n", " \t\n"};
  for (int f = 0; f < frames; ++f) {
    if (pick(4) == 0) out += "\n";
    const int atoms = pick(4) == 0 ? pick(3) : 1 + pick(40);
    const int ncol = 1 + pick(12);
    out += "ITEM: TIMESTEP\n" + std::to_string(100 * f) + "\nITEM: NUMBER OF ATOMS\n" + std::to_string(atoms) +
           "\nITEM: BOX BOUNDS pp pp ff\n-0.1 0.1\n-0.19 0.19\n" + (pick(5) == 0 ? "-0.25 0.7" : "-0.25 0.65") +
           "\nITEM: ATOMS";
    for (int c = 0; c < ncol; ++c) out += " c" + std::to_string(c);
    out += eols[pick(4)];
    for (int a = 0; a < atoms; ++a) {
      if (pick(10) == 0) out += " ";
      for (int c = 0; c < ncol; ++c) {
        if (c > 0) out += pick(20) == 0 ? "\t  " : " ";
        switch (pick(4)) {
          case 0:
            out += kOdd[pick(sizeof(kOdd) / sizeof(kOdd[0]))];
            break;
          case 1:
            std::snprintf(buf, sizeof buf, "%.17g", u(rng) * std::pow(10.0, pick(40) - 20));
            out += buf;
            break;
          default:
            std::snprintf(buf, sizeof buf, "%g", u(rng) * std::pow(10.0, pick(12) - 6));
            out += buf;
        }
      }
      out += eols[pick(4)];
    }
  }
  return out;
}

// Collects copies of the frames lent to it; checks the view's invariants on the way.
class CopySink final : public DumpFrameSink {
 public:
  void OnFrame(const DumpFrameView& f) override {
    EXPECT_NE(f.names, nullptr);
    EXPECT_NE(f.columns_serial, 0u);
    // The serial changes exactly when the column list does.
    if (!frames.empty()) {
      EXPECT_EQ(f.columns_serial == last_serial_, *frames.back().columns == f.columns()) << "step " << f.step;
    }
    last_serial_ = f.columns_serial;
    frames.push_back(f.ToFrame());
  }
  std::vector<DumpFrame> frames;

 private:
  uint64_t last_serial_ = 0;
};

// Feeds `text` in random chunks, into a DumpFrameCollector or (use_sink) into the given sink.
std::vector<DumpFrame> FeedInChunks(const std::string& text, std::mt19937* rng, bool* ok, bool use_sink = false) {
  DumpReader r;
  CopySink sink;
  DumpFrameCollector collector;
  std::vector<DumpFrame> frames;
  *ok = true;
  for (size_t i = 0; i < text.size();) {
    size_t n;
    switch ((*rng)() % 3) {
      case 0:
        n = 1 + (*rng)() % 8;
        break;
      case 1:
        n = 1 + (*rng)() % 400;
        break;
      default:
        n = 1 + (*rng)() % 100000;
        break;
    }
    n = std::min(n, text.size() - i);
    Status s = use_sink ? r.Feed(std::string_view(text).substr(i, n), sink)
                        : r.Feed(std::string_view(text).substr(i, n), collector);
    if (!s.ok()) {
      ADD_FAILURE() << s.ToString();
      *ok = false;
      return frames;
    }
    for (auto& f : collector.Take()) frames.push_back(std::move(f));
    i += n;
  }
  EXPECT_TRUE(r.Finish().ok());
  if (use_sink) {
    EXPECT_TRUE(frames.empty());  // the collector saw nothing on the sink path
    return std::move(sink.frames);
  }
  return frames;
}

TEST(DumpReaderPropertyTest, RandomChunkingsMatchAFromCharsReference) {
  std::vector<std::pair<std::string, std::string>> texts = {
      {"so_omega_minus80.dump", Fixture("so_omega_minus80.dump")},
      {"so_omega_plus80.dump", Fixture("so_omega_plus80.dump")},
      {"two frames", kTwoFrames},
  };
  for (uint32_t seed = 1; seed <= 4; ++seed)
    texts.push_back({"awkward " + std::to_string(seed), AwkwardDump(seed, 60)});
  std::mt19937 rng(7);
  for (const auto& [name, text] : texts) {
    ASSERT_FALSE(text.empty()) << name;
    const std::vector<RefFrame> want = RefParse(text);
    ASSERT_FALSE(want.empty()) << name;
    auto whole = ReadDump(text);
    ASSERT_TRUE(whole.ok()) << name << ": " << whole.status().ToString();
    ExpectSameFrames(*whole, want, name + " whole");
    CopySink whole_sink;
    ASSERT_TRUE(ReadDump(text, whole_sink).ok()) << name;
    ExpectSameFrames(whole_sink.frames, want, name + " whole, sink");
    for (int round = 0; round < 6; ++round) {
      bool ok;
      std::vector<DumpFrame> got = FeedInChunks(text, &rng, &ok, /*use_sink=*/round % 2 == 1);
      ASSERT_TRUE(ok) << name;
      ExpectSameFrames(got, want, name + " round " + std::to_string(round));
    }
  }
}

// Cut at every byte: exactly the frames complete before the cut come out, equal to the whole
// file's; the torn one is never emitted or misread.
TEST(DumpReaderPropertyTest, TornAtEveryByteIsDropped) {
  const std::string real = Fixture("so_omega_minus80.dump");
  size_t fifth = 0;
  for (int i = 0; i < 6; ++i) fifth = real.find("ITEM: TIMESTEP", fifth + 1);
  for (const std::string& text : {real.substr(0, fifth), AwkwardDump(11, 4)}) {
    const std::vector<RefFrame> all = RefParse(text);
    ASSERT_GE(all.size(), 3u);
    for (size_t cut = 0; cut <= text.size(); ++cut) {
      const std::string prefix = text.substr(0, cut);
      const std::vector<RefFrame> want = RefParse(prefix);
      ASSERT_LE(want.size(), all.size());
      // The reference's complete frames of the prefix are the first frames of the whole text.
      std::vector<RefFrame> head(all.begin(), all.begin() + want.size());
      auto got = ReadDump(prefix);
      ASSERT_TRUE(got.ok()) << "cut " << cut << ": " << got.status().ToString();
      ExpectSameFrames(*got, head, "cut " + std::to_string(cut));
      // And fed in two pieces around the cut's middle.
      DumpReader r;
      DumpFrameCollector collector;
      ASSERT_TRUE(r.Feed(std::string_view(prefix).substr(0, cut / 2), collector).ok());
      ASSERT_TRUE(r.Feed(std::string_view(prefix).substr(cut / 2), collector).ok());
      ExpectSameFrames(collector.Take(), head, "two pieces, cut " + std::to_string(cut));
      // And through a sink, in three pieces.
      DumpReader rs;
      CopySink sink;
      ASSERT_TRUE(rs.Feed(std::string_view(prefix).substr(0, cut / 3), sink).ok());
      ASSERT_TRUE(rs.Feed(std::string_view(prefix).substr(cut / 3, cut / 3), sink).ok());
      ASSERT_TRUE(rs.Feed(std::string_view(prefix).substr(2 * (cut / 3)), sink).ok());
      ExpectSameFrames(sink.frames, head, "sink, cut " + std::to_string(cut));
      if (::testing::Test::HasFatalFailure()) return;
    }
  }
}

// An error deep in a big chunk (the fast path) names the same line and column as line by line.
TEST(DumpReaderPropertyTest, CorruptionInABigChunkNamesLineAndColumn) {
  std::string text = AwkwardDump(5, 30);
  std::mt19937 rng(3);
  for (int round = 0; round < 20; ++round) {
    // A random atom value: a token after the last ATOMS line before a random offset.
    size_t at = rng() % text.size();
    size_t atoms_line = text.rfind("ITEM: ATOMS", at);
    if (atoms_line == std::string::npos) continue;
    size_t line_start = text.find('\n', atoms_line) + 1;
    size_t line_end = text.find('\n', line_start);
    if (line_start >= text.size() || text.compare(line_start, 5, "ITEM:") == 0 || line_end == line_start) continue;
    std::string line = text.substr(line_start, line_end - line_start);
    std::vector<std::string> toks = Tokens(line);
    if (toks.empty()) continue;
    size_t col = rng() % toks.size();
    size_t tok_pos = 0;
    for (size_t c = 0; c <= col; ++c) {
      tok_pos = line.find_first_not_of(" \t\r", tok_pos);
      if (c < col) tok_pos = line.find_first_of(" \t\r", tok_pos);
    }
    std::string bad = text;
    bad.insert(line_start + tok_pos + 1, "x");
    const int64_t line_no = std::count(text.begin(), text.begin() + line_start, '\n') + 1;
    auto frames = ReadDump(bad);
    ASSERT_FALSE(frames.ok()) << line;
    EXPECT_NE(frames.status().reason().find("dump line " + std::to_string(line_no) + ":"), std::string::npos)
        << frames.status().reason();
    EXPECT_NE(frames.status().reason().find("column 'c" + std::to_string(col) + "'"), std::string::npos)
        << frames.status().reason();
  }
}

// The sink path lends each frame from one reused buffer: a frame is seen once, complete, in
// order, with its own values even when a bigger or smaller frame came before.
TEST(DumpReaderSinkTest, FramesAreLentInOrderFromAReusedBuffer) {
  std::string text;
  const int atoms[] = {3, 1, 7, 0, 2, 7};
  for (int i = 0; i < 6; ++i) {
    text += "ITEM: TIMESTEP\n" + std::to_string(10 * i) + "\nITEM: NUMBER OF ATOMS\n" + std::to_string(atoms[i]) +
            "\nITEM: BOX BOUNDS pp pp ff\n-1 1\n-1 1\n-1 1\nITEM: ATOMS id z\n";
    for (int a = 0; a < atoms[i]; ++a)
      text += std::to_string(a) + " " + std::to_string(i) + "." + std::to_string(a) + "\n";
  }
  std::vector<int64_t> steps;
  DumpFrameFn sink([&](const DumpFrameView& f) {
    steps.push_back(f.step);
    ASSERT_EQ(f.atoms, atoms[f.step / 10]);
    ASSERT_EQ(f.Column("z"), 1);
    for (int a = 0; a < f.atoms; ++a) {
      EXPECT_EQ(f.At(a, 0), a);
      EXPECT_DOUBLE_EQ(f.At(a, 1), std::stod(std::to_string(f.step / 10) + "." + std::to_string(a)));
    }
  });
  DumpReader r;
  for (size_t i = 0; i < text.size(); i += 13) ASSERT_TRUE(r.Feed(std::string_view(text).substr(i, 13), sink).ok());
  EXPECT_EQ(steps, (std::vector<int64_t>{0, 10, 20, 30, 40, 50}));

  EXPECT_FALSE(r.torn());
}

// A frame whose box or ATOMS line differs from the last one's is checked line by line: a bad box
// line after good frames (the memcmp fast path) is still an error naming its line.
TEST(DumpReaderSinkTest, ChangedHeaderAfterRepeatedOnesIsChecked) {
  std::string text = kTwoFrames;
  text += text;  // frames 3 and 4 repeat the header text of 1 and 2
  std::string bad = text;
  const size_t third = bad.find("ITEM: TIMESTEP\n0", 10);
  bad.replace(bad.find("-0.19 0.19", third), 10, "-0.19 0.x9");
  const int64_t line_no = std::count(bad.begin(), bad.begin() + bad.find("0.x9"), '\n') + 1;
  CopySink sink;
  Status s = ReadDump(bad, sink);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.reason().find("dump line " + std::to_string(line_no) + ":"), std::string::npos) << s.reason();
  EXPECT_EQ(sink.frames.size(), 2u);  // the frames before the bad one were delivered
  // Different columns in a later frame: new names, new serial.
  std::string renamed = text;
  renamed.replace(renamed.find("ITEM: ATOMS id x y z\n"), 21, "ITEM: ATOMS id x y q\n");
  CopySink sink2;
  ASSERT_TRUE(ReadDump(renamed, sink2).ok());
  ASSERT_EQ(sink2.frames.size(), 4u);
  EXPECT_EQ(sink2.frames[1].Column("q"), 3);
  EXPECT_EQ(sink2.frames[2].Column("z"), 3);
  EXPECT_EQ(sink2.frames[3].Column("q"), -1);
}

}  // namespace
}  // namespace sandswim
