// Trajectory analysis: from the SO's dump frames to the results of a run (SPEC.md "Results a run
// produces", "Statistics").
//
// U_z is the SO's mean vertical rate over whole blocks of the steady window (the paper's
// U_z = <d(dz)/dt>). A block is one drive period 1/f when the drive vibrates; for modes with no
// period (constant rotation only) it is WindowRule::undriven_block_s.
//   The window starts after the start-up transient (TransientS: WindowRule::transient_s = 0.3 s
//   of physical time, as whole blocks, and at least one block; see "Transient" below), and ends
//   at the last whole block before the SO first comes within WindowRule::clearance_m of the bed
//   surface or the floor (the gap between the SO's own surface and theirs; SPEC.md: closer, they
//   change the motion) or before the run ends, whichever is first: it always covers whole blocks.
//   z is read once per block, at the window's phase: z_k = z(t0 + k T), k = 0..n (linearly
//   interpolated between samples). The block rates r_k = (z_{k+1} - z_k) / T hold no trace of
//   the oscillation at f, 2f, 3f, ... (every z_k is taken at the same phase), and
//   U_z = mean(r_k) = (z_n - z_0) / (n T).
//   Its standard error is the scatter of the block rates, sd(r_k) / sqrt(n) (batch means with whole
//   periods as blocks): it comes from the data's own correlation, not from per-sample residuals
//   (consecutive samples are correlated ~0.99). With fewer than WindowRule::min_blocks_for_error
//   blocks there is no error (uz_stderr absent, uz_stderr_note says why); the 95 % interval is
//   +- t(0.975, n - 1) * stderr.
// Why this estimator (tests/bench/bench_uz_estimator.cc, 1,000 synthetic trajectories per case:
// drift 0.05 m/s, harmonics at f, 2f, 3f with the phases a drive fixes, correlated noise):
//   - a line + sinusoid at f (analysis 1) over one period is 38 % too high (the 2f harmonic leaks
//     into the slope), 4 % over two; its least-squares 95 % interval holds the truth 1-48 % of
//     the time;
//   - a regression with f, 2f, 3f is unbiased, but no per-sample least-squares error is honest:
//     consecutive samples are correlated ~0.99, and its stated error is 10-100x too small;
//   - the block rates are unbiased by construction (0.0 ± 0.1 %), and the 95 % interval from their
//     scatter covers the truth 93 % of the time when each period's advance varies independently,
//     as measured on real 3 s smoke runs (vibration only and Omega = -10: per-period advances vary
//     by 2-4 mm and consecutive ones correlate by -0.15 and -0.26); when the deviation is instead a
//     jitter that does not accumulate, the interval is conservative (99-100 %), never too narrow.
// A run is conclusive when its window holds at least WindowRule::min_periods whole blocks;
// otherwise it is kept and shown, marked inconclusive with the reason, and the fits leave it out.
// Transient (analysis 4; analyses 1-3 skipped one period whatever f: 33 ms at 30 Hz, 1 s at
// 1 Hz). The start-up is a physical settling, not a number of periods. Measured on real smoke
// runs (LIGGGHTS 3.8.0, the smoke bed; one-period sliding rates r(t) = (z(t + T) - z(t)) / T):
//   - 3 Hz, vibration only (tests/fixtures/runs/vibration-3s): r rises from 0.003-0.008 m/s in
//     the first 0.30 s to 0.012-0.020 m/s from 0.35 s on, where it stays (period rates 0.0072,
//     then 0.0167 0.0152 0.0117 0.0165 0.0191 0.0255 0.0145 0.0270 m/s);
//   - 3 Hz, Omega = +80 (omega-plus80-floor, 0.67 s to the floor): -0.098 m/s in the first 0.05 s,
//     -0.088 from 0.05 to 0.15 s, -0.077 to -0.084 after;
//   - 30 Hz, Omega = -80 (a 0.5 s run made for this study): a launch of +36 mm in the first
//     0.10 s (period rates 0.19, 0.31, 0.50 m/s), then rates of -0.25 .. +0.32 m/s about a slow
//     swing of z (about 0.3 s, +-15 mm) with no sign of the launch after 0.13 s;
//   - 1 Hz (a real smoke run of LIGGGHTS): 15.6 mm in the first second, 1.0 mm in the second.
// So the settling lasts 0.1-0.35 s wherever it was seen: transient_s = 0.3 s, as whole periods
// (the window's phase stays the drive's), at least one: 1 period at 1-3 Hz (unchanged), 2 at
// 4-6 Hz, 3 at 8-10 Hz, 6 at 20 Hz, 9 at 30 Hz; two 0.25 s blocks for constant rotation.
// Trend (analysis 4): whether the period rates drift within the window. BlockRateTrend is the
// least-squares slope of the block rates on their mid times with its t test (blocks - 2 dof),
// from WindowRule::min_blocks_for_trend = 4 blocks; a run is `trending` when p < trend_alpha =
// 0.01 (per run: a campaign of 58 runs flags about 0.6 stationary runs by chance). Real smoke
// runs show per-period advances correlated by -0.15 and -0.26 (see above), for which the t test
// is conservative (measured: 0-0.2 % false alarms on a jitter model, 0.3-0.8 % on the truth
// engine's MA(1) of -0.2); blocks correlated positively make it liberal (1.6-1.9 % with a 0.1 s
// velocity memory; the 30 Hz run's slow swing is such a case). A trending run's U_z stays
// conclusive: U_z is defined as the window's mean rate and stays that, with its interval; the
// flag says the mean depends on the window (a residual transient, or an SO speeding up near a
// boundary), which a user should read before comparing it. Marking it inconclusive would drop
// 1 % of stationary runs from the fits while catching few real drifts at smoke's 4-5 periods
// (power: docs/measurements.md).
// z_osc_amplitude: the amplitude at f of a least-squares fit of a line and harmonics f, 2f, 3f
// over the window (0 when the window holds no whole period or the mode does not vibrate).
// x_osc_amplitude: the same fit to x (analysis 4); absent when it is not measured (no whole
// period, no drive period, or the fit cannot resolve the harmonics), never 0.
// dz = z(end) - z(0) and dz_rate = dz / (t_end - t_0) over the whole run; x_drift = x(end) - x(0).
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_TRAJECTORY_H_
#define SANDSWIM_CORE_TRAJECTORY_H_

#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "core/api.h"
#include "core/deck.h"
#include "core/dump_reader.h"
#include "core/engine_log.h"
#include "core/scale.h"
#include "core/status.h"

namespace sandswim {

struct SoSample {
  int64_t step = 0;
  double t = 0;  // s, step * dt
  double x = 0, y = 0, z = 0;
};

// The drive facts (core/deck.h DriveInfo) a deck text states, for a run directory read offline
// (`sandswim analyze`) and decks stored before migration 3; the service's workers get them typed
// in their lease. InvalidArgument naming the missing line when the deck does not state dt or f (every drive deck
// states "variable f equal", 0 for constant rotation).
Result<DriveInfo> ReadDriveInfo(std::string_view deck);
// The step a deck (a bed's or a drive's) states on its 'timestep <dt>' line: its materials' own
// (core/materials.h TimeStep). InvalidArgument ("deck") when it states none with dt > 0.
Result<double> ReadTimeStep(std::string_view deck);

// How the steady window is chosen. The defaults are the service's; `sandswim analyze` can change
// them. Each number is a stated choice, not fitted to any result:
struct WindowRule {
  double transient_s = 0.3;  // s skipped at the start (the start-up transient, see above) ...
  double transient_blocks = 1;           // ... and at least this many blocks (TransientS)
  double undriven_block_s = 0.25;        // s, the block of a mode with no period (constant rotation only)
  double clearance_m = kMaterials.d_so;  // m of grains kept between the SO and the surface/floor
  int min_periods = 2;                   // fewer whole blocks in the window: inconclusive
  int min_blocks_for_error = 3;          // fewer blocks: no standard error
  int min_blocks_for_trend = 4;          // fewer blocks: no trend test (its t test has blocks - 2 dof)
  double trend_alpha = 0.01;             // a run is "trending" when its trend test's p is below this
};

// The start-up transient a window skips, in s: the fewest whole blocks that last at least
// rule.transient_s, and at least rule.transient_blocks blocks.
double TransientS(const WindowRule& rule, double block_s);

// The trend test of `blocks` whole blocks of block_s from t0 (see above): the least-squares slope
// of the block rates on the blocks' mid times, its standard error and the two-sided p value of
// t = slope / se with blocks - 2 degrees of freedom. Absent with fewer than 3 blocks.
struct Trend {
  double slope = 0;     // m/s^2
  double slope_se = 0;  // m/s^2
  double p = 1;
};
// REQUIRES: as MeanBlockRate.
std::optional<Trend> BlockRateTrend(const std::vector<SoSample>& samples, double t0, double block_s, int blocks);

// Where the bed's boundaries are, as far as the caller knows (absent: not checked).
struct BedBounds {
  std::optional<double> surface;  // m, the bed surface (highest grain centre at the drive's start)
  std::optional<double> floor;    // m, the floor wall
  double so_radius = kMaterials.d_so / 2;  // m, the run's SO (core/deck.h DriveInfo::so_radius)
};

// The mean rate over whole blocks of [t0, t1], see above. No samples are dropped or smoothed.
struct BlockRate {
  double rate = 0;             // m/s
  std::optional<double> se;    // m/s, standard error
  std::optional<double> ci95;  // m/s, half-width of the 95 % interval
  int blocks = 0;
  double t0 = 0, t1 = 0;  // s, the whole blocks used: t1 = t0 + blocks * block_s
};
// REQUIRES: samples in ascending t covering [t0, t0 + blocks * block_s]; blocks >= 1.
BlockRate MeanBlockRate(const std::vector<SoSample>& samples, double t0, double block_s, int blocks,
                        int min_blocks_for_error = WindowRule{}.min_blocks_for_error);

// Two-sided 95 % quantile of Student's t with `dof` degrees of freedom (dof >= 1).
double StudentT95(int dof);

// Which atom of a dump is the SO: the one with this `id` (column "id"); else, when frames hold one
// atom (the service's SO dump), that atom; else the largest particle of the first frame (column
// "radius" or "diameter"), followed by its id.
struct SoSelector {
  std::optional<int64_t> id;
};

// The SO's samples (columns x, y, z; t = step x dt), frame by frame as a DumpReader hands them
// over (DumpReader::Feed(chunk, sink)): no DumpFrame is made. Corruption when a column is missing,
// a frame is empty or lacks the SO, or the SO cannot be told apart; steps must rise. Frames after
// the first problem are ignored; Take() reports it.
class SoSampleSink final : public DumpFrameSink {
 public:
  explicit SoSampleSink(double dt, SoSelector so = {}) : dt_(dt), id_(so.id) {}
  void OnFrame(const DumpFrameView& frame) override;
  // The samples so far, or the first problem.
  Result<std::vector<SoSample>> Take();
  // The samples so far, without taking them (empty after Take()).
  const std::vector<SoSample>& samples() const { return samples_; }

 private:
  // The row of the SO in `f`, or -1 with status_ set.
  int64_t SoRow(const DumpFrameView& f);

  double dt_;
  std::optional<int64_t> id_;  // the SO's id, once known (given, or found as the largest)
  uint64_t serial_ = 0;        // columns_serial the indices below were found for (0: none)
  int cx_ = -1, cy_ = -1, cz_ = -1, cid_ = -1, crad_ = -1;
  std::vector<SoSample> samples_;
  Status status_;
};

// The SO's samples of a whole dump text: a dump Corruption, or a frame's problem (SoSampleSink).
Result<std::vector<SoSample>> SamplesFromDump(std::string_view text, double dt, SoSelector so = {});

// REQUIRES: samples in ascending t. FailedPrecondition when there are fewer than 3 samples;
// InvalidArgument ("f") when `f` is not finite and >= 0, or its period is shorter than the mean
// sample interval. `f` is the drive frequency (0: no period). The window ends at the last sample
// that keeps the clearance from the surface and the floor, else at the last sample. `start`/`stop` (from the log) fill
// grains, the stop reason and flags, and the bed surface when `bounds` has none; without `stop` the reason is
// "duration" and steps are the last sample's.
Result<api::RunResult> AnalyzeTrajectory(const std::vector<SoSample>& samples, double f, BedBounds bounds,
                                         const std::optional<DriveStartMarker>& start,
                                         const std::optional<DriveStopMarker>& stop, const WindowRule& rule = {});

// What the analysis of a run reads besides its dump: the drive (from the run's deck), the bed's
// surface and the engine's stop (from its log: the drive start and stop markers), the floor (from
// the deck). The worker and `sandswim analyze` both build it here, so an offline analysis of a
// run's files gives the worker's numbers.
struct RunInputs {
  double f = 0;               // Hz, 0: no period
  double dt = kMaterials.dt;  // s per step
  BedBounds bounds;
  std::optional<DriveStartMarker> start;
  std::optional<DriveStopMarker> stop;
  std::optional<PrecisionTarget> precision;  // the run's target, if it had one
};
RunInputs RunInputsFrom(const DriveInfo& drive, const EngineLog& log,
                        const std::optional<PrecisionTarget>& precision = std::nullopt);
// AnalyzeTrajectory(samples, in.f, in.bounds, in.start, in.stop, rule), and whether the run met
// its precision target (core/precision.h TargetMet) with the sentence on why it ended.
Result<api::RunResult> AnalyzeRun(const std::vector<SoSample>& samples, const RunInputs& in,
                                  const WindowRule& rule = {});

// U_z as every surface writes it (CLI, report, dashboard), so that no surface shows more than the
// data holds: a value with its error is rounded to the error's second significant digit
// ("0.0467 ± 0.0031 m/s, 4 periods"); a value without an error gets two significant digits and
// says why ("≈0.047 m/s, no error: 2 periods"); an inconclusive one one digit and the word
// ("inconclusive (≈0.05 m/s, 1 period)"); none at all, "inconclusive (no whole period)". A result
// of an older analysis says so. `with_units` = false leaves out " m/s" (for table columns).
std::string DescribeUz(const api::RunResult& r, bool with_units = true);
// "0.0467 ± 0.0031": err to 2 significant digits and v to the same decimal place.
std::string WithError(double v, double err);

// At most `max_points` samples, evenly spaced in index, always keeping the first and the last.
api::Trajectory Downsample(const std::vector<SoSample>& samples, size_t max_points = 2000);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_TRAJECTORY_H_
