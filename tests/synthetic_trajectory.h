// Test support: synthetic SO trajectories with a known drift, for checking the U_z estimator
// (core/trajectory.h) against a known answer.
//
//   z(t) = z0 + drift t + sum_h a_h sin(2 pi h f t + phi_h)      harmonics h = 1, 2, 3
//          + e(t)                                                  stationary AR(1) noise in z
//          + w(t)                                                  a wandering term: the integral of
//                                                                  AR(1) noise in the velocity
// sampled every `dt_sample`. e models a jitter about the drift line that never accumulates; w a
// deviation that accumulates from period to period, as the SO's does in real runs (each period's
// advance varies with the grains it meets). Both have lag-1 autocorrelations near 1 at 1 ms, as
// real trajectories do. The phases phi_h are fixed (a drive fixes them in a real run); the noise
// comes from `seed`.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_TESTS_SYNTHETIC_TRAJECTORY_H_
#define SANDSWIM_TESTS_SYNTHETIC_TRAJECTORY_H_

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/trajectory.h"

namespace sandswim::testing {

struct SyntheticSo {
  double drift = 0.05;                            // m/s, the true U_z
  double f = 3;                                   // Hz
  double amplitudes[3] = {0.002, 0.006, 0.0015};  // m at f, 2f, 3f (2f dominates, as in real runs)
  double phases[3] = {0.3, 1.9, 4.0};             // rad
  double z_noise_sd = 0.001;                      // m, stationary sd of e
  double z_noise_phi = 0.99;                      // lag-1 autocorrelation of e per sample
  double v_noise_sd = 0;                          // m/s, stationary sd of the velocity noise behind w
  double v_noise_phi = 0.99;                      // its lag-1 autocorrelation per sample
  double duration = 1;                            // s
  double dt_sample = 1e-3;                        // s
};

inline std::vector<SoSample> MakeSyntheticSo(const SyntheticSo& p, uint64_t seed) {
  constexpr double kTwoPi = 6.28318530717958647692;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  double e = p.z_noise_sd * normal(rng), v = p.v_noise_sd * normal(rng), w = 0;
  const double ez = p.z_noise_sd * std::sqrt(1 - p.z_noise_phi * p.z_noise_phi);
  const double ev = p.v_noise_sd * std::sqrt(1 - p.v_noise_phi * p.v_noise_phi);
  const int64_t steps_per_sample = static_cast<int64_t>(std::llround(p.dt_sample / 1e-5));
  std::vector<SoSample> out;
  for (int64_t i = 0; i * p.dt_sample <= p.duration + 1e-12; ++i) {
    SoSample s;
    s.step = i * steps_per_sample;
    s.t = i * p.dt_sample;
    double z = p.drift * s.t + e + w;
    for (int h = 0; h < 3; ++h) z += p.amplitudes[h] * std::sin(kTwoPi * (h + 1) * p.f * s.t + p.phases[h]);
    s.z = z;
    out.push_back(s);
    e = p.z_noise_phi * e + ez * normal(rng);
    w += v * p.dt_sample;
    v = p.v_noise_phi * v + ev * normal(rng);
  }
  return out;
}

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_SYNTHETIC_TRAJECTORY_H_
