#include "core/numerics.h"

#include <cmath>
#include <limits>

#include "core/text.h"

namespace sandswim {
namespace {

// The point's fastest speed and where it comes from.
std::pair<double, std::string> FastestSpeed(const Point& p) {
  const double r_so = p.materials.d_so / 2;
  double v = 0;
  std::string from = "none";
  if (p.has_vibration()) {
    v = 2 * M_PI * p.f * p.A;
    from = "vibration";
  }
  if (p.has_constant_rotation() && std::abs(p.omega) * r_so > v) {
    v = std::abs(p.omega) * r_so;
    from = "rotation";
  }
  if (p.mode == Mode::kOscillatory && std::abs(p.Omega) * r_so > v) {
    v = std::abs(p.Omega) * r_so;
    from = "oscillatory rotation";
  }
  return {v, from};
}

// Hertz contact duration of two of the point's grains meeting at speed v (s; inf at v = 0).
double HertzContactTime(const Materials& m, double v) {
  if (!(v > 0)) return std::numeric_limits<double>::infinity();
  const double mass = m.rho_grain * M_PI / 6 * m.d_grain * m.d_grain * m.d_grain;
  const double m_eff = mass / 2, r_eff = m.d_grain / 4;
  const double e_eff = m.youngs / (2 * (1 - m.poisson * m.poisson));
  return 2.87 * std::pow(m_eff * m_eff / (r_eff * e_eff * e_eff * v), 0.2);
}

}  // namespace

Result<Numerics> ParseNumerics(const nlohmann::json& j) {
  if (!j.is_object()) return Status::InvalidArgument("", "must be an object such as {\"dt\": 5e-5}");
  Numerics n;
  for (const auto& [key, value] : j.items()) {
    if (key != "dt") return Status::InvalidArgument(key, "is not a numerical setting (the one there is: dt)");
    if (!value.is_number())
      return Status::InvalidArgument("dt", "must be a number of seconds, got " + value.dump());
    const double dt = value.get<double>();
    if (!std::isfinite(dt) || !(dt > 0)) return Status::InvalidArgument("dt", "must be a finite step > 0 s");
    if (dt < kMinTimeStepS || dt > kMaxTimeStepS)
      return Status::InvalidArgument("dt", "must be from " + Num(kMinTimeStepS) + " to " + Num(kMaxTimeStepS) +
                                               " s, got " + Num(dt));
    n.dt_s = dt;
  }
  return n;
}

nlohmann::json NumericsToJson(const Numerics& n) {
  nlohmann::json j = nlohmann::json::object();
  if (n.dt_s) j["dt"] = *n.dt_s;
  return j;
}

StepCriteria JudgeStep(const Point& p, double dt) {
  const Materials& m = p.materials;
  StepCriteria c;
  c.dt_s = dt;
  c.grain_rayleigh_fraction = dt / RayleighTime(m.d_grain, m.rho_grain, m.youngs, m.poisson);
  c.so_rayleigh_fraction = dt / RayleighTime(m.d_so, m.rho_so, kMaterials.youngs_so, kMaterials.poisson_so);
  std::tie(c.speed_mps, c.speed_from) = FastestSpeed(p);
  c.contact_steps = HertzContactTime(m, c.speed_mps) / dt;
  c.pass_steps = c.speed_mps > 0 ? m.d_grain / (c.speed_mps * dt) : std::numeric_limits<double>::infinity();
  c.skin_fraction = c.speed_mps * dt / (kSkinM / 2);
  auto judge = [&](bool past_bound, bool past_warning, const std::string& what) {
    if (past_bound) {
      if (c.refusal.empty()) c.refusal = what;
      c.level = StepLevel::kRefused;
    } else if (past_warning) {
      c.warnings.push_back(what);
      if (c.level == StepLevel::kOk) c.level = StepLevel::kWarned;
    }
  };
  const double rayleigh = std::max(c.grain_rayleigh_fraction, c.so_rayleigh_fraction);
  judge(rayleigh > kRayleighBound, rayleigh > kRayleighWarn,
        Num(100 * rayleigh, 3) + " % of the Rayleigh time (bound " + Num(100 * kRayleighBound) + " %, warned past " +
            Num(100 * kRayleighWarn) + " %)");
  const std::string at = " at " + Num(c.speed_mps, 3) + " m/s (" + c.speed_from + ")";
  judge(c.contact_steps < kContactStepsBound, c.contact_steps < kContactStepsWarn,
        Num(c.contact_steps, 3) + " steps a grain-grain Hertz contact" + at + " (at least " + Num(kContactStepsBound) +
            ", warned below " + Num(kContactStepsWarn) + ")");
  judge(c.pass_steps < kContactStepsBound, c.pass_steps < kContactStepsWarn,
        Num(c.pass_steps, 3) + " steps for the fastest surface to pass a grain diameter" + at + " (at least " +
            Num(kContactStepsBound) + ", warned below " + Num(kContactStepsWarn) + ")");
  judge(c.skin_fraction >= 1, c.skin_fraction > kSkinWarn,
        Num(c.skin_fraction, 3) + " of half the neighbour skin travelled a step" + at + " (below 1, warned past " +
            Num(kSkinWarn) + ")");
  return c;
}

double LargestAcceptedStep(const Point& p) {
  // Every criterion is monotone in dt: bisect in log dt between the shortest and longest steps.
  double lo = kMinTimeStepS / 1000, hi = kMaxTimeStepS;
  if (JudgeStep(p, hi).level != StepLevel::kRefused) return hi;
  for (int i = 0; i < 80; ++i) {
    const double mid = std::sqrt(lo * hi);
    (JudgeStep(p, mid).level == StepLevel::kRefused ? hi : lo) = mid;
  }
  return RoundStepDown(lo);
}

Status ResolveDriveStep(Point& p, const Scale& scale, const Numerics& numerics) {
  const double rule = TimeStep(p.materials);
  if (numerics.dt_s) {
    const StepCriteria c = JudgeStep(p, *numerics.dt_s);
    if (c.level == StepLevel::kRefused)
      return Status::InvalidArgument("numerics.dt", Num(*numerics.dt_s) + " s gives " + c.refusal + "; this point (" +
                                                        std::string(ModeName(p.mode)) + ") takes at most " +
                                                        Num(LargestAcceptedStep(p)) + " s");
    p.dt_s = *numerics.dt_s;
  } else {
    double dt = rule * (scale.default_dt_s / kMaterials.dt);
    if (JudgeStep(p, dt).level == StepLevel::kRefused) {
      const double bound = LargestAcceptedStep(p);
      double shrunk = 0;
      for (double rung : kStepLadder)
        if (rung < dt && rung <= bound) {
          shrunk = rung;
          break;
        }
      dt = shrunk > 0 ? shrunk : bound;
    }
    p.dt_s = dt;
  }
  if (*p.dt_s == rule) p.dt_s.reset();
  if (DriveStep(p) < kMinTimeStepS)
    return Status::FailedPrecondition("numerics.dt", "this point needs a time step of " + Num(DriveStep(p), 3) +
                                                         " s; no scale runs steps shorter than " +
                                                         Num(kMinTimeStepS) + " s");
  return Status::Ok();
}

nlohmann::json StepCriteriaToJson(const StepCriteria& c) {
  auto finite_or_null = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  return {{"dt_s", c.dt_s},
          {"source", c.source},
          {"grain_rayleigh_fraction", c.grain_rayleigh_fraction},
          {"so_rayleigh_fraction", c.so_rayleigh_fraction},
          {"speed_mps", c.speed_mps},
          {"speed_from", c.speed_from},
          {"contact_steps", finite_or_null(c.contact_steps)},
          {"pass_steps", finite_or_null(c.pass_steps)},
          {"skin_fraction", c.skin_fraction},
          {"level", c.level == StepLevel::kOk ? "ok" : c.level == StepLevel::kWarned ? "warned" : "refused"},
          {"warnings", c.warnings}};
}

}  // namespace sandswim
