#include "core/trajectory.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "core/dump_reader.h"
#include "core/engine_log.h"

namespace sandswim {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string Fixture(const std::string& name) {
  std::ifstream in(std::string(SANDSWIM_SOURCE_DIR) + "/tests/fixtures/" + name, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// z = z0 + u t + amp sin(2 pi f t + phase), x = x0 + vx t, sampled every 1 ms.
std::vector<SoSample> Synthetic(double duration, double z0, double u, double amp, double f, double phase, double vx) {
  std::vector<SoSample> s;
  for (int64_t step = 0; step * 1e-5 <= duration + 1e-12; step += 100) {
    SoSample p;
    p.step = step;
    p.t = step * 1e-5;
    p.x = 0.01 + vx * p.t;
    p.z = z0 + u * p.t + amp * std::sin(2 * kPi * f * p.t + phase);
    s.push_back(p);
  }
  return s;
}

TEST(TrajectoryTest, RecoversSlopeAndAmplitudeOfASyntheticRun) {
  // A start-up transient in the first period that the window must skip.
  auto s = Synthetic(4.0, -0.1, 0.02, 0.004, 3.0, 0.7, 0.001);
  for (auto& p : s) {
    if (p.t < 1.0 / 3.0) p.z += 0.05 * (1.0 / 3.0 - p.t);
  }
  auto r = AnalyzeTrajectory(s, 3.0, std::nullopt, std::nullopt);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_NEAR(r->window_t0, 1.0 / 3.0, 1e-3);
  EXPECT_DOUBLE_EQ(r->window_t1, 4.0);
  EXPECT_NEAR(r->uz, 0.02, 2e-5);
  EXPECT_GT(r->uz_stderr, 0.0);
  EXPECT_LT(r->uz_stderr, 1e-4);
  EXPECT_NEAR(r->z_osc_amplitude, 0.004, 2e-5);
  EXPECT_NEAR(r->dz, s.back().z - s.front().z, 1e-15);
  EXPECT_NEAR(r->x_drift, 0.004, 1e-12);
  EXPECT_DOUBLE_EQ(r->z0, s.front().z);
  EXPECT_EQ(r->steps, 400000);
  EXPECT_EQ(r->stop_reason, "duration");
}

TEST(TrajectoryTest, ShortWindowAmplitudeNotFittedPlainSlope) {
  // 0.5 s at 1 Hz: window [0.25, 0.5] is a quarter period; the line fit stands.
  auto s = Synthetic(0.5, 0.0, 0.1, 0.0, 1.0, 0.0, 0.0);
  auto r = AnalyzeTrajectory(s, 1.0, std::nullopt, std::nullopt);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->uz, 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(r->z_osc_amplitude, 0.0);
}

TEST(TrajectoryTest, SinkingAndNoOscillation) {
  auto s = Synthetic(1.0, 0.0, -0.05, 0.0, 5.0, 0.0, 0.0);
  auto r = AnalyzeTrajectory(s, 5.0, std::nullopt, std::nullopt);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->uz, -0.05, 1e-12);
  EXPECT_NEAR(r->uz_stderr, 0.0, 1e-12);
  EXPECT_NEAR(r->z_osc_amplitude, 0.0, 1e-12);
}

TEST(TrajectoryTest, ConstantRotationSkipsTenPercent) {
  auto s = Synthetic(2.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0);
  auto r = AnalyzeTrajectory(s, 0.0, std::nullopt, std::nullopt);
  ASSERT_TRUE(r.ok());
  EXPECT_NEAR(r->window_t0, 0.2, 1e-9);
  EXPECT_DOUBLE_EQ(r->z_osc_amplitude, 0.0);
}

TEST(TrajectoryTest, ShortRunWindowStartsAtMostHalfway) {
  EXPECT_DOUBLE_EQ(SteadyWindowStart(3.0, 0.3), 0.15);
  EXPECT_DOUBLE_EQ(SteadyWindowStart(3.0, 4.0), 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(SteadyWindowStart(0.0, 4.0), 0.4);
}

TEST(TrajectoryTest, StopMarkerSetsFlags) {
  auto s = Synthetic(0.5, 0.0, 0.3, 0.0, 3.0, 0.0, 0.0);
  DriveStopMarker stop{"surface", 50000, 0.5, 0.15};
  DriveStartMarker start{5024, 0.0, 0.2};
  auto r = AnalyzeTrajectory(s, 3.0, start, stop);
  ASSERT_TRUE(r.ok());
  EXPECT_TRUE(r->broke_surface);
  EXPECT_FALSE(r->near_floor);
  EXPECT_EQ(r->stop_reason, "surface");
  EXPECT_EQ(r->grains, 5024);
  stop.reason = "floor";
  r = AnalyzeTrajectory(s, 3.0, start, stop);
  EXPECT_TRUE(r->near_floor);
  EXPECT_FALSE(r->broke_surface);
}

TEST(TrajectoryTest, TooFewSamplesIsRefused) {
  auto s = Synthetic(0.001, 0.0, 0.3, 0.0, 3.0, 0.0, 0.0);
  auto r = AnalyzeTrajectory(s, 3.0, std::nullopt, std::nullopt);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kFailedPrecondition);
}

TEST(TrajectoryTest, DownsampleKeepsEndsAndCap) {
  auto s = Synthetic(10.0, 0.0, 0.01, 0.0, 3.0, 0.0, 0.0);  // 10001 samples
  api::Trajectory t = Downsample(s, 2000);
  ASSERT_EQ(t.t.size(), 2000u);
  EXPECT_EQ(t.z.size(), 2000u);
  EXPECT_DOUBLE_EQ(t.t.front(), 0.0);
  EXPECT_DOUBLE_EQ(t.t.back(), 10.0);
  for (size_t i = 1; i < t.t.size(); ++i) ASSERT_LT(t.t[i - 1], t.t[i]);
  EXPECT_EQ(Downsample(Synthetic(0.01, 0, 0, 0, 3, 0, 0), 2000).t.size(), 11u);
}

TEST(TrajectoryTest, ReadDriveInfoFromARealDeck) {
  auto info = ReadDriveInfo(Fixture("drive_omega_minus80.in"));
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  EXPECT_DOUBLE_EQ(info->dt, 1e-5);
  EXPECT_DOUBLE_EQ(info->f, 3.0);
  EXPECT_DOUBLE_EQ(info->A, 0.03);
  EXPECT_FALSE(ReadDriveInfo("units si\n").ok());
}

// The real smoke runs: Omega = -80 rose, Omega = +80 sank (signs read from the first and last
// frames independently of the fit).
TEST(TrajectoryTest, RealFixturesRiseAndSink) {
  for (const char* name : {"so_omega_minus80.dump", "so_omega_plus80.dump"}) {
    auto frames = ReadDump(Fixture(name));
    ASSERT_TRUE(frames.ok());
    const DumpFrame& a = frames->front();
    const DumpFrame& b = frames->back();
    const double dz_frames = b.At(0, b.Column("z")) - a.At(0, a.Column("z"));
    auto samples = SamplesFromFrames(*frames, 1e-5);
    ASSERT_TRUE(samples.ok());
    auto r = AnalyzeTrajectory(*samples, 3.0, std::nullopt, std::nullopt);
    ASSERT_TRUE(r.ok());
    EXPECT_TRUE(std::isfinite(r->uz));
    EXPECT_DOUBLE_EQ(r->dz, dz_frames);
    EXPECT_DOUBLE_EQ(r->window_t1, 0.3);
    EXPECT_NEAR(r->window_t0, 0.15, 1e-9);
    if (std::string(name) == "so_omega_minus80.dump") {
      EXPECT_GT(dz_frames, 0.01) << "Omega = -80 rose in this run";
      EXPECT_GT(r->uz, 0.0);
    } else {
      EXPECT_LT(dz_frames, -0.01) << "Omega = +80 sank in this run";
      EXPECT_LT(r->uz, 0.0);
    }
    // 0.15 s of window is less than one period at 3 Hz: no oscillation fit.
    EXPECT_DOUBLE_EQ(r->z_osc_amplitude, 0.0);
  }
}

TEST(TrajectoryTest, SamplesNeedRisingStepsAndColumns) {
  DumpFrame f;
  f.step = 5;
  f.columns = DumpFrame::Names({"id", "x", "z"});
  f.atoms = 1;
  f.values = {1, 0, 0};
  EXPECT_EQ(SamplesFromFrames({f}, 1e-5).status().code(), StatusCode::kCorruption);
  f.columns = DumpFrame::Names({"x", "y", "z"});
  EXPECT_TRUE(SamplesFromFrames({f}, 1e-5).ok());
  EXPECT_EQ(SamplesFromFrames({f, f}, 1e-5).status().code(), StatusCode::kCorruption);
}

// The streaming form (no DumpFrames) gives exactly the samples of SamplesFromFrames(ReadDump()),
// and the same errors.
TEST(TrajectoryTest, SamplesFromDumpEqualsSamplesFromFrames) {
  const std::string text = Fixture("so_omega_minus80.dump");
  auto frames = ReadDump(text);
  ASSERT_TRUE(frames.ok());
  auto want = SamplesFromFrames(*frames, 1e-5);
  auto got = SamplesFromDump(text, 1e-5);
  ASSERT_TRUE(want.ok() && got.ok());
  ASSERT_EQ(got->size(), want->size());
  ASSERT_GT(got->size(), 3u);
  for (size_t i = 0; i < got->size(); ++i) {
    EXPECT_EQ((*got)[i].step, (*want)[i].step);
    EXPECT_EQ((*got)[i].t, (*want)[i].t);
    EXPECT_EQ((*got)[i].x, (*want)[i].x);
    EXPECT_EQ((*got)[i].y, (*want)[i].y);
    EXPECT_EQ((*got)[i].z, (*want)[i].z);
  }
  // Steps that do not rise (the file twice), a missing column, text that is not a dump.
  EXPECT_EQ(SamplesFromDump(text + text, 1e-5).status().code(), StatusCode::kCorruption);
  std::string no_z = text;
  for (size_t at; (at = no_z.find(" z vx")) != std::string::npos;) no_z.replace(at, 5, " q vx");
  EXPECT_NE(SamplesFromDump(no_z, 1e-5).status().reason().find("lacks column"), std::string::npos);
  EXPECT_NE(SamplesFromDump("ITEM: NONSENSE\n", 1e-5).status().reason().find("dump line 1"), std::string::npos);
}

}  // namespace
}  // namespace sandswim
