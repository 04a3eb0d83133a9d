#include "core/dump_reader.h"

#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

std::string Fixture(const std::string& name) {
  std::ifstream in(std::string(SANDSWIM_SOURCE_DIR) + "/tests/fixtures/" + name, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

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
  EXPECT_EQ(f0.columns, (std::vector<std::string>{"id", "x", "y", "z"}));
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
    std::vector<DumpFrame> frames;
    for (size_t i = 0; i < text.size(); i += chunk) {
      ASSERT_TRUE(r.Feed(std::string_view(text).substr(i, chunk)).ok());
      for (auto& f : r.TakeFrames()) frames.push_back(std::move(f));
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
    ASSERT_TRUE(r.Feed(std::string_view(text).substr(0, cut)).ok()) << "cut " << cut;
    auto frames = r.TakeFrames();
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
  ASSERT_TRUE(r.Feed(text).ok());
  EXPECT_EQ(r.TakeFrames().size(), 1u);
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
    EXPECT_NE(frames.status().reason().find(c.needle), std::string::npos)
        << frames.status().reason();
  }
}

TEST(DumpReaderTest, ErrorStateIsSticky) {
  DumpReader r;
  EXPECT_FALSE(r.Feed("ITEM: NONSENSE\n").ok());
  EXPECT_FALSE(r.Feed("ITEM: TIMESTEP\n").ok());
  EXPECT_FALSE(r.Finish().ok());
}

TEST(DumpReaderTest, RealLiggghtsDumpOfTheSo) {
  const std::string text = Fixture("so_omega_minus80.dump");
  ASSERT_FALSE(text.empty());
  auto frames = ReadDump(text);
  ASSERT_TRUE(frames.ok()) << frames.status().ToString();
  ASSERT_EQ(frames->size(), 301u);  // every 100 steps over 30000 steps
  const DumpFrame& first = frames->front();
  EXPECT_EQ(first.columns.size(), 10u);
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
    // Feed in 4 KB chunks, as the worker does while tailing.
    for (size_t i = 0; i < cut; i += 4096) {
      ASSERT_TRUE(r.Feed(std::string_view(text).substr(i, std::min<size_t>(4096, cut - i))).ok());
    }
    auto frames = r.TakeFrames();
    EXPECT_TRUE(r.torn());
    ASSERT_LT(frames.size(), all->size());
    ASSERT_FALSE(frames.empty());
    for (size_t i = 0; i < frames.size(); ++i) {
      EXPECT_EQ(frames[i].values, (*all)[i].values) << "cut " << cut << " frame " << i;
    }
  }
}

}  // namespace
}  // namespace sandswim
