// Trajectory analysis: from the SO's dump frames to the results of a run (SPEC.md "Results a run
// produces").
//
// U_z is the least-squares slope of z(t) over a stated steady window [window_t0, window_t1]:
//   window_t1 = the last sample (runs stop themselves at the surface or the floor, so the whole
//               run lies before them);
//   window_t0 = skips the start-up transient: one drive period 1/f when the drive vibrates
//               (f > 0), else the first 10 % of the run; never more than half of the run.
// When the drive vibrates (f > 0) the fit is z = c0 + U_z t + a sin(2 pi f t) + b cos(2 pi f t),
// one least-squares fit of the trend and the oscillation at f together (a plain line through a
// sinusoid is biased by ~ amplitude / (f T) when the window is short); z_osc_amplitude =
// sqrt(a^2 + b^2). When f = 0, or the window is shorter than one period 1/f (a run shorter than
// two periods, which the scales do not make), it is a plain line and the amplitude is 0. The standard error of
// U_z is that fit's: sqrt(SSR / (n - p) * [(X'X)^-1]_slope), whatever remains in the residuals
// (grain collisions) counted as scatter.
// dz = z(end) - z(0), x_drift = x(end) - x(0), z0 = z(0).
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_TRAJECTORY_H_
#define SANDSWIM_CORE_TRAJECTORY_H_

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "core/api.h"
#include "core/dump_reader.h"
#include "core/engine_log.h"
#include "core/status.h"

namespace sandswim {

struct SoSample {
  int64_t step = 0;
  double t = 0;  // s, step * dt
  double x = 0, y = 0, z = 0;
};

// Drive facts a rendered drive deck states (its `timestep` and `variable f/A equal` lines).
struct DriveInfo {
  double dt = 0;  // s
  double f = 0;   // Hz; 0 when the mode does not vibrate
  double A = 0;   // m
};
// InvalidArgument naming the missing line when the deck does not state dt.
Result<DriveInfo> ReadDriveInfo(std::string_view deck);

// The SO's samples from dump frames (columns x, y, z; the SO is atom 0 of each frame, the only
// atom of the SO dump). Corruption when a column is missing or a frame is empty; steps must rise.
Result<std::vector<SoSample>> SamplesFromFrames(const std::vector<DumpFrame>& frames, double dt);

// The same, frame by frame as a DumpReader hands them over (DumpReader::Feed(chunk, sink)): no
// DumpFrame is made. Frames after the first problem are ignored; Take() reports it.
class SoSampleSink final : public DumpFrameSink {
 public:
  explicit SoSampleSink(double dt) : dt_(dt) {}
  void OnFrame(const DumpFrameView& frame) override;
  // The samples so far, or the first problem (the Status SamplesFromFrames would return).
  Result<std::vector<SoSample>> Take();

 private:
  double dt_;
  uint64_t serial_ = 0;  // columns_serial the indices below were found for (0: none)
  int cx_ = -1, cy_ = -1, cz_ = -1;
  std::vector<SoSample> samples_;
  Status status_;
};

// SamplesFromFrames(ReadDump(text)) without the frames: a dump Corruption, or a frame's problem.
Result<std::vector<SoSample>> SamplesFromDump(std::string_view text, double dt);

// Where the steady window starts for a run of `duration` seconds (see above).
double SteadyWindowStart(double f, double duration);

// REQUIRES: samples in ascending t. FailedPrecondition when fewer than 3 samples lie in the window.
// `start`/`stop` (from the log) fill grains, the stop reason and flags; without `stop` the
// reason is "duration" and steps are the last sample's.
Result<api::RunResult> AnalyzeTrajectory(const std::vector<SoSample>& samples, double f,
                                         const std::optional<DriveStartMarker>& start,
                                         const std::optional<DriveStopMarker>& stop);

// At most `max_points` samples, evenly spaced in index, always keeping the first and the last.
api::Trajectory Downsample(const std::vector<SoSample>& samples, size_t max_points = 2000);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_TRAJECTORY_H_
