#include "core/scale.h"

#include <algorithm>
#include <cstdio>
#include <string>

namespace sandswim {
namespace {

// The paper's box (Sec. 2.3); `mini`, a smaller box around the SO for one machine overnight;
// `smoke`, the smallest box that still holds A = 0.10 m (the A sweep's largest) and keeps at
// least 0.12 m of grains above and below the SO (SPEC.md), for tests and the demo.
const std::vector<Scale> kScales = {
    {"paper", "the paper's geometry (about 7e4 grains), 4-5 s runs: a cluster or a big node", 0.50, 1.00, -0.50, 0.50,
     0.0},
    {"mini", "a smaller periodic box around the SO (about 1.5e4 grains), full durations: one machine overnight", 0.32,
     0.40, -0.40, 0.40, 0.0},
    {"smoke", "about 5e3 grains and a fraction of a second (at least two drive periods): tests and demos", 0.20, 0.38,
     -0.25, 0.22, 0.25},
};

double NeededYLen(double A) { return 2 * A + kMaterials.d_so + 3 * kMaterials.d_grain; }
double NeededXLen() { return kMaterials.d_so + 3 * kMaterials.d_grain; }

std::string Num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

}  // namespace

double Scale::max_amplitude() const { return (y_len - kMaterials.d_so - 3 * kMaterials.d_grain) / 2; }

const std::vector<Scale>& AllScales() { return kScales; }

const Scale* FindScale(std::string_view name) {
  for (const auto& s : kScales)
    if (s.name == name) return &s;
  return nullptr;
}

Status FitsScale(const Point& p, const Scale& scale) {
  if (scale.x_len < NeededXLen())
    return Status::Internal("scale '" + std::string(scale.name) + "' is narrower than d_SO + 3 d_grain");
  // A tiny tolerance so that A = 0.10 fits a box built for exactly 0.10.
  if (p.has_vibration() && p.A > scale.max_amplitude() + 1e-12) {
    std::string reason = "A = " + Num(p.A) + " m needs L_y >= " + Num(NeededYLen(p.A)) +
                         " m (2A + d_SO + 3 d_grain); scale '" + std::string(scale.name) +
                         "' has L_y = " + Num(scale.y_len) + " m (A <= " + Num(scale.max_amplitude()) + " m)";
    for (auto it = kScales.rbegin(); it != kScales.rend(); ++it) {
      if (p.A <= it->max_amplitude() + 1e-12) {
        reason += "; scale '" + std::string(it->name) + "' takes it";
        break;
      }
    }
    return Status::FailedPrecondition("A", reason);
  }
  return Status::Ok();
}

double RunDuration(const Point& p, const Scale& scale) {
  double d = p.duration_s;
  if (scale.max_duration_s > 0) {
    double floor_s = p.has_vibration() ? 2.0 / p.f : 0.0;
    d = std::min(d, std::max(scale.max_duration_s, floor_s));
  }
  return d;
}

}  // namespace sandswim
