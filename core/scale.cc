#include "core/scale.h"
#include "core/text.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

namespace sandswim {
namespace {

// The paper's box (Sec. 2.3); `mini`, a smaller box around the SO for one machine overnight;
// `smoke`, the smallest box for tests and the demo. Each box keeps the same room above and below
// the SO: the SO's steady window ends when it comes within WindowRule::clearance_m (0.12 m,
// SPEC.md) of the bed surface or the floor (core/trajectory.h), so the travel a run has before the
// boundary's influence is, up and down,
//   up   = surface - r_SO - 0.12 - z_SO        down = z_SO - r_SO - 0.12 - floor
// with z_SO where the SO settles (about -0.01 m: it sinks a little into the first layer).
//   - paper and mini: the floor and the top are symmetric about the SO; up = down = 0.32 m (paper)
//     and 0.22 m (mini).
//   - smoke: 0.18 m x 0.38 m, floor -0.35, poured to +0.34. L_y = 0.38 m holds A = 0.10 m (the A
//     sweep's largest: 2A + d_SO + 3 d_grain); L_x = 0.18 m = d_SO + 3 d_grain, the least the rule
//     allows, since every centimetre of box costs grains. The height gives the SO about 0.15 m of
//     travel each way: the baseline Omega = -80 rose at 0.12 m/s and +80 sank at 0.09 m/s on the
//     earlier 0.20 x 0.38 m smoke box (Δz over the whole run,
//     docs/measurements.md#the-earlier-smoke-box), so
//     0.15 m holds the one-period transient and three whole periods at f = 3 Hz (1.33 s) for the
//     baseline pair; faster points end their window at the boundary and say so. Measured here
//     (tests/bench/bench_physics, 2026-11-25): 6,682 grains, the SO settled at z = -0.011 m, the
//     surface (highest grain centre) at +0.329 m: 0.160 m of travel up and 0.159 m down; the bed
//     took 228 s to prepare and a run 147 s of one core per second of physical time. With the
//     other core busy the same bed (208,001 steps) took 577-686 s in the test suite's runs and a
//     run up to four times longer (2026-11-25, tests/prepare_beds and the e2e).
//     That bed's room replaced a box whose floor stop ended every sinking run at dz = -0.059 m
//     while rising runs had 0.17 m.
// The smoke target: a run ends once its 95 % interval is within 20 % of |U_z| or 5 mm/s (the
// smallest change the nightly drift report flags), after at least three whole periods, or at 2 s
// of physical time (f = 1 Hz still gets its transient and three periods: core/precision.h
// RunDuration). It is a cost choice for a test scale, not a physics one: a sweep may set its own.
// The smoke bed-to-bed prior, 0.17: the baseline pair on three replicate smoke beds on the real
// engine (2026-11; docs/measurements.md#the-baseline-on-three-replicate-beds-the-current-smoke-box):
// between-bed sd 0.0088 m/s of
// -0.0530 sinking (17 %), 0.0038 of 0.0973 rising (4 %); the larger is taken for every point, since
// three beds fix neither well. paper and mini have no replicate measurement: none.
// Why a prior and not K = 3 beds by default for paper-58, measured on the truth
// engine (bench_claims_calibration, 300 campaigns a law): one-bed point intervals covered the true
// U_z 71 %, 90 % with this prior, 97 % on three beds; but three beds triple the engine time (86.5 ->
// 258.5 s simulated a campaign, the demo's ~6 h -> ~18 h at smoke). Since rules 3 (a point over its
// beds by core/aggregate.h's stated rule, censored beds counted) three beds no longer cost the sign
// and growth rules power (F1 96 -> 100 %, F2 rising grows 99.7 -> 100 %, sinking saturates 49 ->
// 60 %), but the rules that need a rate at fast points still lose it (rising saturates 39 -> 17 %,
// F4 4 -> 0 %: all three beds must be measured). A study that wants them sets "replicates": 3.
// Grain caps (max_grains, what a scale's purpose can run): smoke 2e4, three times its Table 1 bed,
// a run of it still minutes on one core; mini 5e4, about three times its bed, still one machine
// overnight; paper 1e6, the paper's own bed (8e5 grains, Sec. 2.3) with room.
const std::vector<Scale> kScales = {
    {"paper", "the paper's geometry (about 7e4 grains), 4-5 s runs: a cluster or a big node", 0.50, 1.00, -0.50, 0.50,
     std::nullopt, std::nullopt, 1e6},
    {"mini", "a smaller periodic box around the SO (about 1.5e4 grains), full durations: one machine overnight", 0.32,
     0.40, -0.40, 0.40, std::nullopt, std::nullopt, 5e4},
    {"smoke",
     "about 6.7e3 grains, 0.15 m of travel up and down, runs that end at a precision target (at most 2 s): tests and "
     "demos",
     0.18, 0.38, -0.35, 0.34, PrecisionTarget{0.2, 0.005, 3, 2.0}, 0.17, 2e4},
};

// Smoke's bed as prepared on this project's machine (docs/measurements.md): its grains.
constexpr double kSmokeGrains = 6682;

double Span(const Materials& m) { return m.d_so + 3 * m.d_grain; }
double NeededYLen(double A, const Materials& m) { return 2 * A + Span(m); }

double SphereVolume(double d) { return M_PI / 6 * d * d * d; }
double BedVolume(const Box& b, const Materials& m) {
  return b.x_len * b.y_len * (b.z_bed_top - b.z_floor) - SphereVolume(m.d_so);
}

std::string Quoted(std::string_view name) { return "'" + std::string(name) + "'"; }

// The first scale, smallest first, that takes the point, as "; scale 'mini' takes it", or
// "; no scale runs it".
template <typename Takes>
std::string ScaleThatTakes(Takes takes) {
  for (auto it = kScales.rbegin(); it != kScales.rend(); ++it)
    if (takes(*it)) return "; scale " + Quoted(it->name) + " takes it";
  return "; no scale runs it";
}

}  // namespace

double Scale::max_amplitude() const { return BoxFor(*this, kTable1).max_amplitude; }

Box BoxFor(const Scale& s, const Materials& m) {
  // Only growth: a smaller SO or smaller grains keep the scale's box (and so its bed's volume).
  const double wider = std::max(0.0, Span(m) - Span(kTable1));
  const double deeper = std::max(0.0, (m.d_so - kTable1.d_so) / 2);
  Box b;
  b.x_len = s.x_len + wider;
  b.y_len = s.y_len + wider;
  b.z_floor = s.z_floor - deeper;
  b.z_bed_top = s.z_bed_top + deeper;
  b.max_amplitude = (b.y_len - Span(m)) / 2;
  return b;
}

double EstimatedGrains(const Scale& scale, const Materials& m) {
  const Scale& smoke = *FindScale("smoke");
  const double per_volume = kSmokeGrains / BedVolume(BoxFor(smoke, kTable1), kTable1);
  const double grain_ratio = SphereVolume(kTable1.d_grain) / SphereVolume(m.d_grain);
  return std::round(per_volume * BedVolume(BoxFor(scale, m), m) * grain_ratio);
}

const std::vector<Scale>& AllScales() { return kScales; }

const Scale* FindScale(std::string_view name) {
  for (const auto& s : kScales)
    if (s.name == name) return &s;
  return nullptr;
}

double BedPriorOf(std::string_view scale) {
  const Scale* s = FindScale(scale);
  return s != nullptr && s->bed_sd_rel ? *s->bed_sd_rel : 0.0;
}

Status FitsScale(const Point& p, const Scale& scale) {
  const Materials& m = p.materials;
  const Box box = BoxFor(scale, m);
  if (box.x_len < Span(m) - 1e-12)
    return Status::Internal("scale '" + std::string(scale.name) + "' is narrower than d_SO + 3 d_grain");
  // A tiny tolerance so that A = 0.10 fits a box built for exactly 0.10.
  if (p.has_vibration() && p.A > box.max_amplitude + 1e-12) {
    std::string reason = "A = " + Num(p.A) + " m needs L_y >= " + Num(NeededYLen(p.A, m)) +
                         " m (2A + d_SO + 3 d_grain); scale '" + std::string(scale.name) +
                         "' has L_y = " + Num(box.y_len) + " m (A <= " + Num(box.max_amplitude) + " m)";
    return Status::FailedPrecondition(
        "A", reason + ScaleThatTakes([&](const Scale& s) { return p.A <= BoxFor(s, m).max_amplitude + 1e-12; }));
  }
  const Materials bed = BedMaterials(m);
  const double grains = EstimatedGrains(scale, bed);
  if (grains > scale.max_grains) {
    const char* field = m.d_grain < kTable1.d_grain || m.d_so <= kTable1.d_so ? "grain_diameter" : "so_diameter";
    return Status::FailedPrecondition(
        field, "its bed would hold about " + std::to_string(std::llround(grains)) + " grains; scale " +
                   Quoted(scale.name) + " runs at most " + std::to_string(std::llround(scale.max_grains)) +
                   ScaleThatTakes([&](const Scale& s) { return EstimatedGrains(s, bed) <= s.max_grains; }));
  }
  const double dt = TimeStep(m);
  if (dt < kMinTimeStepS) {
    // Name the parameter whose return to Table 1's value lengthens the step most.
    const MaterialField* worst = nullptr;
    double best_dt = dt;
    for (const MaterialField& f : MaterialFields()) {
      Materials back = m;
      back.*f.member = kTable1.*f.member;
      const double t = TimeStep(back);
      if (t > best_dt) best_dt = t, worst = &f;
    }
    return Status::FailedPrecondition(worst ? std::string(worst->name) : "grain_youngs",
                                      "these materials need a time step of " + Num(dt, 3) + " s (" + kTimeStepRule +
                                          "); no scale runs steps shorter than " + Num(kMinTimeStepS) + " s");
  }
  return Status::Ok();
}

}  // namespace sandswim
