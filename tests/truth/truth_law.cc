#include "tests/truth/truth_law.h"

#include <cmath>
#include <random>

namespace sandswim::truth {
namespace {

constexpr double kTwoPi = 6.28318530717958647692;

uint64_t SplitMix(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}
uint64_t Mix(uint64_t a, uint64_t b) { return SplitMix(a ^ SplitMix(b + 0x632be59bd9b4e019ULL)); }
// A standard normal number from a seed, without a generator's state.
double NormalFrom(uint64_t seed) {
  std::mt19937_64 rng(seed);
  return std::normal_distribution<double>()(rng);
}

bool HasXComponent(const Point& p) {
  if (p.mode == Mode::kOscillatory) return true;
  return p.has_constant_rotation() && (p.axis == RotationAxis::kX || p.axis == RotationAxis::kXZ);
}
bool HasZComponent(const Point& p) {
  return p.has_constant_rotation() && (p.axis == RotationAxis::kZ || p.axis == RotationAxis::kXZ);
}

double OmegaFactor(const Law& law, double abs_omega, double u80) {
  switch (law.omega_shape) {
    case OmegaShape::kFlat:
      return u80;
    case OmegaShape::kLog:
      return u80 * std::log1p(abs_omega / law.log_omega0) / std::log1p(80 / law.log_omega0);
    case OmegaShape::kSaturating:
      break;
  }
  return u80 * (1 - std::exp(-law.c2 * abs_omega)) / (1 - std::exp(-law.c2 * 80));
}

double FFactor(const Law& law, double f) {
  if (law.f_shape == FShape::kMonotone) return (1 - std::exp(-f / law.f_mono)) / (1 - std::exp(-3 / law.f_mono));
  auto h = [&](double x) { return (x / law.f_peak) * std::exp(1 - x / law.f_peak); };
  return h(f) / h(3);
}

std::vector<Law> MakeLaws() {
  std::vector<Law> laws;
  Law paper;
  paper.name = "paper";
  laws.push_back(paper);
  Law flat = paper;
  flat.name = "flat_Omega";
  flat.breaks = "F2 grows";
  flat.omega_shape = OmegaShape::kFlat;
  laws.push_back(flat);
  Law nosat = paper;
  nosat.name = "no_saturation";
  nosat.breaks = "F2 saturates";
  nosat.omega_shape = OmegaShape::kLog;
  laws.push_back(nosat);
  Law affine = paper;
  affine.name = "affine_A";
  affine.breaks = "F3 rising";
  affine.affine_intercept = 0.04;
  laws.push_back(affine);
  Law nopeak = paper;
  nopeak.name = "no_peak_f";
  nopeak.breaks = "F4";
  nopeak.f_shape = FShape::kMonotone;
  laws.push_back(nopeak);
  Law equal = paper;
  equal.name = "modes_equal";
  equal.breaks = "F5 fastest, z and x oscillation";
  equal.modes_equal = true;
  laws.push_back(equal);
  Law sign = paper;
  sign.name = "sign_wrong";
  sign.breaks = "F1";
  sign.sign_wrong_below = 20;
  laws.push_back(sign);
  return laws;
}

}  // namespace

const std::vector<Law>& AllLaws() {
  static const std::vector<Law> laws = MakeLaws();
  return laws;
}

const std::vector<Law>& StepLaws() {
  static const std::vector<Law> laws = [] {
    Law at = MakeLaws().front();
    at.name = "dt_at_margin";
    at.breaks = "converges at 1e-4 s (at the margin)";
    at.dt_bias = 0.10;
    Law past = at;
    past.name = "dt_past_margin";
    past.breaks = "converges at 1e-4 s";
    past.dt_bias = 0.25;
    return std::vector<Law>{at, past};
  }();
  return laws;
}

const Law* FindLaw(const std::string& name) {
  for (const Law& l : AllLaws())
    if (l.name == name) return &l;
  for (const Law& l : StepLaws())
    if (l.name == name) return &l;
  return nullptr;
}

namespace {
double UnchangedUz(const Law& law, const Point& p) {
  if (p.mode != Mode::kOscillatory) {
    double u = 0.005;  // rotation only
    if (p.has_vibration()) {
      if (law.modes_equal) {
        u = 0.055;
      } else if (p.mode == Mode::kVibration) {
        u = 0.030;
      } else {
        switch (p.axis) {
          case RotationAxis::kX:
            u = 0.090;
            break;
          case RotationAxis::kY:
            u = 0.040;
            break;
          case RotationAxis::kZ:
            u = 0.045;
            break;
          case RotationAxis::kXZ:
            u = 0.065;
            break;
        }
      }
      u *= (p.A / 0.03) * FFactor(law, p.f);
    }
    return u;
  }
  if (p.Omega == 0) return 0;
  const bool rising = p.Omega < 0;
  const double abs_omega = std::fabs(p.Omega);
  double u;
  if (rising) {
    const double s = OmegaFactor(law, abs_omega, law.u80_rise) * FFactor(law, p.f);
    const double a0 = law.affine_intercept / law.u80_rise;
    u = s * (a0 + (1 - a0) * p.A / 0.03);
  } else {
    u = -OmegaFactor(law, abs_omega, law.u80_sink) * std::min(p.A, law.sink_break_A) / 0.03;
  }
  if (abs_omega <= law.sign_wrong_below) u = -u;
  return u;
}
}  // namespace

double LawUz(const Law& law, const Point& p) {
  return law.uz_factor * UnchangedUz(law, p) * (1 + law.dt_bias * (DriveStep(p) - kMaterials.dt) / 9e-5);
}

double LawZAmplitude(const Law& law, const Point& p) {
  if (!p.has_vibration()) return 0;
  const double a = law.modes_equal && p.mode != Mode::kOscillatory ? 0.002 : HasXComponent(p) ? 0.004 : 0.0008;
  return a * p.A / 0.03;
}

double LawXAmplitude(const Law& law, const Point& p) {
  if (!p.has_vibration()) return 0;  // no period: the x motion is a drift
  if (law.modes_equal && p.mode != Mode::kOscillatory) return 0.002;
  return HasZComponent(p) ? 0.004 : 0.0003;
}

double LawXDriftRate(const Law&, const Point& p) {
  if (p.mode == Mode::kOscillatory) return 0;
  if (p.mode == Mode::kVibration) return 0.010;
  if (p.mode == Mode::kRotation) return 0.005;
  switch (p.axis) {
    case RotationAxis::kX:
      return 0;
    case RotationAxis::kY:
    case RotationAxis::kZ:
      return 0.020;
    case RotationAxis::kXZ:
      return 0.015;
  }
  return 0;
}

Noise Noise::None() {
  Noise n;
  n.period_rel = n.diffusion = n.bed_common = n.bed_point = n.bed_offset = 0;
  n.jitter_sd = n.transient_v0 = n.x_walk = 0;
  return n;
}

Bed MakeBed(uint64_t world, int replicate, const Noise& noise, const Scale& scale) {
  Bed b;
  b.surface = scale.z_bed_top - 0.011;
  b.replicate = replicate;
  b.seed = Mix(world, static_cast<uint64_t>(replicate) + 1);
  b.common = noise.bed_common * NormalFrom(Mix(b.seed, 1));
  b.offset = noise.bed_offset * NormalFrom(Mix(b.seed, 2));
  return b;
}

double BedUz(const Law& law, const Noise& noise, const Bed& bed, const Point& p) {
  const double own = noise.bed_point * NormalFrom(Mix(bed.seed, PointHash(p)));
  return LawUz(law, p) * (1 + bed.common + own) + bed.offset;
}

uint64_t PointHash(const Point& p) {
  // Only what the mode uses, each to 1e-9: the stand-in binary reads the drive back out of a
  // deck's numbers (omega about xz from its two components).
  auto q = [](double v) { return static_cast<uint64_t>(std::llround(v * 1e9)); };
  uint64_t h = Mix(0x7275746800000000ULL, static_cast<uint64_t>(p.mode));
  if (p.has_vibration()) h = Mix(Mix(h, q(p.A)), q(p.f));
  if (p.mode == Mode::kOscillatory) h = Mix(h, q(p.Omega));
  if (p.has_constant_rotation()) h = Mix(Mix(h, q(p.omega)), static_cast<uint64_t>(p.axis));
  return h;
}

uint64_t RunSeed(uint64_t world, int replicate, const Point& p) {
  // The step enters the run's noise, not the bed's effect (PointHash): a run at another step is
  // another realisation on the same bed, as chaos makes it on the real engine.
  const uint64_t seed = Mix(Mix(world, static_cast<uint64_t>(replicate) + 101), PointHash(p));
  return p.dt_s ? Mix(seed, static_cast<uint64_t>(std::llround(*p.dt_s * 1e12))) : seed;
}

EngineRun GenerateRun(const Law& law, const Noise& noise, const Bed& bed, const RunSpec& spec, uint64_t seed) {
  const Point& p = spec.point;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  EngineRun out;
  out.true_uz = BedUz(law, noise, bed, p);
  out.start = {bed.grains, bed.z0, bed.surface};
  const double dt = DriveStep(p);
  const int64_t every = DumpEverySteps(p);
  const double sample_dt = every * dt;
  const double f = p.has_vibration() ? p.f : 0;
  const double block = f > 0 ? 1 / f : WindowRule{}.undriven_block_s;
  const double u = out.true_uz;
  const double block_sd = std::sqrt(noise.diffusion * block + std::pow(noise.period_rel * std::fabs(u) * block, 2));
  const double ma_norm = 1 / std::sqrt(1 + noise.ma_theta * noise.ma_theta);
  // Harmonics: 2f dominates in the oscillatory mode; phases fixed per mode, as a drive fixes them.
  const double scale_a = p.has_vibration() ? p.A / 0.03 : 0;
  const double amp[3] = {LawZAmplitude(law, p), (p.mode == Mode::kOscillatory ? 0.003 : 0.002) * scale_a,
                         0.0008 * scale_a};
  const double phase0 = 0.37 * static_cast<int>(p.mode);
  const double phases[3] = {0.3 + phase0, 1.9 + phase0, 4.0 + phase0};
  const double x_amp = LawXAmplitude(law, p), x_rate = LawXDriftRate(law, p);
  const double r_so = kMaterials.d_so / 2;
  const double floor_stop = spec.z_floor + r_so + kMaterials.d_grain;
  const int64_t last_step = static_cast<int64_t>(std::llround(spec.duration_s / dt));

  double w_prev = normal(rng);
  // The rate of block k (its mid time (k + 1/2) T): U_bed, plus the drift when one is asked for.
  auto block_rate = [&](int64_t k) { return u + noise.rate_slope * (k + 0.5) * block; };
  double block_start_z = 0,
         block_advance = block_rate(0) * block + block_sd * ma_norm * (normal(rng) + noise.ma_theta * w_prev);
  int64_t block_index = 0;
  double e = noise.jitter_sd * normal(rng), x_walk = 0;
  const double e_sd = noise.jitter_sd * std::sqrt(1 - noise.jitter_phi * noise.jitter_phi);
  std::optional<double> stop_at;  // s: the worker's request takes effect at the first chunk after this
  std::string stop_reason = "duration";
  for (int64_t step = 0;; step += every) {
    const double t = step * dt;
    // The block the time is in: advance the drift path block by block.
    while (t >= (block_index + 1) * block - 1e-12) {
      block_start_z += block_advance;
      ++block_index;
      const double w = normal(rng);
      block_advance = block_rate(block_index) * block + block_sd * ma_norm * (w + noise.ma_theta * w_prev);
      w_prev = w;
    }
    double z = bed.z0 + block_start_z + (t - block_index * block) / block * block_advance;
    if (noise.transient_tau > 0) z += noise.transient_v0 * noise.transient_tau * (1 - std::exp(-t / noise.transient_tau));
    for (int h = 0; h < 3; ++h)
      if (f > 0) z += amp[h] * std::sin(kTwoPi * (h + 1) * f * t + phases[h]);
    z += e;
    SoSample s;
    s.step = step;
    s.t = t;
    s.z = z;
    s.y = p.has_vibration() ? p.A * std::sin(kTwoPi * f * t) : 0;
    s.x = x_rate * t + x_walk + (f > 0 ? x_amp * std::sin(kTwoPi * f * t + 0.7) : 0);
    out.samples.push_back(s);
    e = noise.jitter_phi * e + e_sd * normal(rng);
    x_walk += noise.x_walk * std::sqrt(sample_dt) * normal(rng);
    if (step == 0) continue;  // the first chunk runs before any check
    // The deck's checks after a chunk, in its order: the surface, the floor, the control file.
    if (z + r_so - bed.surface >= 0) {
      stop_reason = "surface";
      break;
    }
    if (z - floor_stop <= 0) {
      stop_reason = "floor";
      break;
    }
    if (stop_at && t >= *stop_at - 1e-12) break;
    if (step >= last_step) {
      stop_reason = "duration";
      break;
    }
    if (!stop_at && spec.stop_hook) {
      std::string reason;
      if (spec.stop_hook(out.samples, &reason)) {
        stop_reason = reason;
        if (spec.lag_s <= 0) break;  // the deck's own check of its control file: this chunk
        stop_at = t + spec.lag_s;
      }
    }
  }
  const SoSample& last = out.samples.back();
  out.stop = {stop_reason, last.step, last.t, last.z};
  return out;
}

}  // namespace sandswim::truth
