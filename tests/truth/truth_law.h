// Truth engine: a known law for U_z and an SO trajectory generated from it, sampled as the drive
// deck dumps the SO, for measuring the claims' rules (core/claims.h) and the analysis
// (core/trajectory.h) against a known answer. Test support only: it simulates no grain.
//
// A LAW is a named set of parameters (AllLaws()). Every law agrees with `paper` at the baseline
// (A = 0.03 m, f = 3 Hz, |Omega| = 80 rad/s) and breaks one claim part, so that the other claims
// keep their truth. With S(|Omega|) the branch's |Omega| shape and s = +1 rising (Omega < 0),
// -1 sinking (Omega > 0), for the oscillatory drive:
//   rising   U_z = +S_r(|Omega|) g(f) a(A)           sinking  U_z = -S_s(|Omega|) min(A, 0.06) / 0.03
//   S(|Omega|)  saturating: U80 (1 - exp(-C2 |Omega|)) / (1 - exp(-80 C2)), C2 = 0.03 s/rad (95 % of
//               C1 reached at |Omega| = 100 rad/s, well inside the swept 10 .. 1280)
//   U80         0.118 m/s rising, 0.091 m/s sinking (the smoke baseline: rose at ~0.12 m/s, sank at
//               ~0.09 m/s, core/scale.cc; C1 = 0.130 and 0.100 m/s)
//   g(f)        peak: h(f) / h(3), h(f) = (f / 5) exp(1 - f / 5): a single maximum at f = 5 Hz
//   a(A)        proportional: A / 0.03
// The laws (name: what differs from `paper`):
//   paper          F1-F5 true as above; modes (A = 0.03, f = 3, omega = 80): vibration +0.030,
//                  vibration+rotation about x +0.090 (fastest, x drift 0), y +0.040, z +0.045,
//                  xz +0.065, rotation only about x +0.005 m/s; z oscillates at f with amplitude
//                  4 mm when omega has an x component (oscillatory included), 0.8 mm without; x
//                  oscillates at f with 4 mm when omega has a z component, 0.3 mm without
//   flat_Omega     S(|Omega|) = U80 at every |Omega| (F2 "grows" false)
//   no_saturation  S(|Omega|) = U80 ln(1 + |Omega| / 20) / ln(5): grows without bound (F2
//                  "saturates" false; 0.31 m/s rising at 1280)
//   affine_A       rising a(A) = 0.04 / U80 + (1 - 0.04 / U80) A / 0.03: 0.04 m/s at A = 0 (F3 rising false)
//   no_peak_f      g(f) = (1 - exp(-f / 4)) / (1 - exp(-3 / 4)): rises monotonically in f (F4 false)
//   modes_equal    every vibrating mode rises at 0.055 m/s, z amplitude 2 mm and x amplitude 2 mm
//                  at f (F5 "fastest" and both "oscillates" false; x drift as in paper)
//   sign_wrong     |Omega| <= 20 moves against the paper's sign at the paper's rate (F1 false)
//
// The TRAJECTORY of a run (GenerateRun) at the dump's interval (1 ms: 100 steps of 1e-5 s):
//   z(t) = z0 + Z(t) + transient(t) + sum_h a_h sin(2 pi h f t + phi_h) + e(t)
//   Z(t)   the advance, piecewise linear between block boundaries k T (T = 1/f; 0.25 s for rotation
//          only): block k advances U_bed T + sd_k eta_k, sd_k = sqrt(D T + (rel |U_bed| T)^2),
//          eta_k = (w_k + theta w_{k-1}) / sqrt(1 + theta^2) (w iid normal): per-period scatter
//          relative to |U_z| with an absolute floor, consecutive advances correlated by
//          theta / (1 + theta^2) = -0.19 (real 3 s smoke runs: 2-4 mm, -0.15 and -0.26,
//          core/trajectory.h). D = 1.5e-5 m^2/s gives 2.2 mm per period at 3 Hz.
//   U_bed  = U_z (1 + b_bed + b_bed,point) + o_bed: the BED EFFECT, shared by every point on a bed
//          (b_bed ~ N(0, 0.10), o_bed ~ N(0, 0.003 m/s), from the bed's seed) with a part of its
//          own per point on that bed (b_bed,point ~ N(0, 0.15), from the bed's seed and the
//          point). The law's U_z is the mean over beds; a run's "true U_z" is U_bed (with
//          Noise::rate_slope, the rate at t = 0: block k advances (U_bed + rate_slope t_k) T).
//   transient(t) = v0 tau (1 - exp(-t / tau)), v0 = -0.06 m/s, tau = 0.2 s: the start-up settling
//          (12 mm; 2.3 mm of it is left after the one-period transient at 3 Hz).
//   a_h    z harmonics at f, 2f, 3f (2f: 3 mm in the oscillatory mode, 2 mm otherwise; 3f 0.8 mm),
//          scaled by A / 0.03; phases fixed per mode. e: AR(1) jitter, sd 0.3 mm, 0.9 per sample.
//   x(t) = x_drift_rate t + random walk (1 mm / sqrt(s)) + x amplitude sin(2 pi f t + 0.7).
//   y(t) = A sin(2 pi f t), prescribed.
// The ENGINE's stops (templates/drive.in, after every 1 ms chunk): "surface" once the SO's top
// reaches the bed surface (z + r_SO >= surface), "floor" once z <= floor + r_SO + d_grain;
// "duration" at the run's end; a `stop_hook` stands for the worker's control file: when it asks,
// the run ends at the first chunk `lag_s` later ("target" or "window").
//
// Thread safety: pure functions; Law and Noise are values.
#ifndef SANDSWIM_TESTS_TRUTH_TRUTH_LAW_H_
#define SANDSWIM_TESTS_TRUTH_TRUTH_LAW_H_

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "core/deck.h"
#include "core/engine_log.h"
#include "core/point.h"
#include "core/scale.h"
#include "core/trajectory.h"

namespace sandswim::truth {

enum class OmegaShape { kSaturating, kFlat, kLog };
enum class FShape { kPeak, kMonotone };

struct Law {
  std::string name;
  std::string breaks;  // the claim part it makes false ("" for paper)
  OmegaShape omega_shape = OmegaShape::kSaturating;
  double u80_rise = 0.118, u80_sink = 0.091;  // m/s at |Omega| = 80, A = 0.03, f = 3
  double c2 = 0.03;                           // s/rad
  double log_omega0 = 20;                     // rad/s
  double affine_intercept = 0;                // m/s: rising U_z at A = 0 (0: proportional)
  double sink_break_A = 0.06;                 // m
  FShape f_shape = FShape::kPeak;
  double f_peak = 5, f_mono = 4;  // Hz
  bool modes_equal = false;
  double sign_wrong_below = 0;  // rad/s: |Omega| <= this moves the wrong way (0: none)
  // A CHANGE of every U_z by this factor (1 in every law): the input on which the drift report's
  // power is measured (a second night under the changed law), not a law of the paper.
  double uz_factor = 1;
  // A BIAS of the time step (0 in the paper's laws): U_z(dt) = U_z (1 + dt_bias (dt - 1e-5) /
  // 9e-5), the relative change at dt = 1e-4 s; the input on which the `converges` rule
  // (core/convergence.h) is measured. Not a law of the paper.
  double dt_bias = 0;
};

// paper, flat_Omega, no_saturation, affine_A, no_peak_f, modes_equal, sign_wrong.
const std::vector<Law>& AllLaws();
// The step laws, `paper` with a time-step bias: dt_at_margin (dt_bias 0.10: at 1e-4 s the fast
// points' U_z moves by exactly the `converges` rule's default relative margin, the least
// favourable truth for "equivalent"), dt_past_margin (0.25). Not in AllLaws: the paper's claims
// are calibrated on Table 1's step. FindLaw finds them too.
const std::vector<Law>& StepLaws();
const Law* FindLaw(const std::string& name);

// The law's U_z at a point (m/s, > 0 rising), over beds.
double LawUz(const Law& law, const Point& p);
// Amplitudes at f of z's and x's oscillation (m), and x's drift rate (m/s), by the law.
double LawZAmplitude(const Law& law, const Point& p);
double LawXAmplitude(const Law& law, const Point& p);
double LawXDriftRate(const Law& law, const Point& p);

struct Noise {
  double period_rel = 0.15;   // sd of a block's advance, relative to |U| T
  double diffusion = 1.5e-5;  // m^2/s: the absolute floor, sqrt(D T) per block
  double ma_theta = -0.2;     // MA(1) coefficient of the block advances
  double bed_common = 0.10;   // sd of a bed's factor shared by all its points
  double bed_point = 0.15;    // sd of a bed's factor per point
  double bed_offset = 0.003;  // m/s, sd of a bed's additive offset
  double jitter_sd = 3e-4;    // m
  double jitter_phi = 0.9;    // per 1 ms sample
  double transient_v0 = -0.06;  // m/s
  double transient_tau = 0.2;   // s
  double x_walk = 1e-3;         // m / sqrt(s)
  // A DRIFT of the rate within a run (0: stationary, every law's default): block k advances
  // (U_bed + rate_slope t_k) T, t_k its mid time. Not a law of the paper: the input on which the
  // trend test (core/trajectory.h) is measured for its power.
  double rate_slope = 0;  // m/s^2
  // Everything off but the law's drift and the oscillation: the analysis must then give the law.
  static Noise None();
};

// A bed as the truth engine sees it: where it is (the smoke bed measured in core/scale.cc) and its
// effect, from (world, replicate). `world` stands for everything a real bed's pour draws at
// random: a calibration draws a new world per simulated campaign; the stand-in engine binary reads
// it from SANDSWIM_TRUTH_SEED.
struct Bed {
  int replicate = 0;
  uint64_t seed = 0;
  double surface = 0.329;  // m, highest grain centre: the scale's bed top less 0.011 m, as measured at smoke
  double z0 = -0.011;      // m, the SO at the drive's start (it sinks a little into the first layer)
  int64_t grains = 6682;
  double common = 0, offset = 0;  // drawn from the bed's seed with Noise
};
Bed MakeBed(uint64_t world, int replicate, const Noise& noise, const Scale& scale = *FindScale("smoke"));
// The bed's U_z at a point: LawUz scaled by the bed's factors.
double BedUz(const Law& law, const Noise& noise, const Bed& bed, const Point& p);

// Seeds: a stable hash of a point's drive (duration left out), and of a run (world, bed, point).
uint64_t PointHash(const Point& p);
uint64_t RunSeed(uint64_t world, int replicate, const Point& p);

// What the engine leaves for the analysis: the SO's samples and the log's markers.
struct EngineRun {
  std::vector<SoSample> samples;
  DriveStartMarker start;
  DriveStopMarker stop;
  double true_uz = 0;  // m/s, BedUz: what the run's U_z estimates
};
// Asked after every chunk with the samples so far; true: the worker asks the run to end, with
// `reason` "target" or "window".
using StopHook = std::function<bool(const std::vector<SoSample>& so_far, std::string* reason)>;
struct RunSpec {
  Point point;
  double duration_s = 0;  // the run's length if nothing stops it (PlannedRun::run_duration_s)
  double z_floor = -0.35;
  StopHook stop_hook;          // empty: nobody asks
  double hook_every_s = 0;     // ask the hook at most this often (0: after every chunk)
  double lag_s = 0.02;         // from the hook's request to the run's end
};
EngineRun GenerateRun(const Law& law, const Noise& noise, const Bed& bed, const RunSpec& spec, uint64_t seed);

}  // namespace sandswim::truth

#endif  // SANDSWIM_TESTS_TRUTH_TRUTH_LAW_H_
