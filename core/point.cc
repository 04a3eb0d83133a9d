#include "core/point.h"
#include "core/text.h"

#include <cmath>

namespace sandswim {
namespace {

struct ModeEntry {
  Mode mode;
  std::string_view name;
};
constexpr ModeEntry kModes[] = {
    {Mode::kVibration, "vibration"},
    {Mode::kRotation, "rotation"},
    {Mode::kVibrationRotation, "vibration+rotation"},
    {Mode::kOscillatory, "oscillatory"},
};

struct AxisEntry {
  RotationAxis axis;
  std::string_view name;
};
constexpr AxisEntry kAxes[] = {
    {RotationAxis::kX, "x"}, {RotationAxis::kY, "y"}, {RotationAxis::kZ, "z"}, {RotationAxis::kXZ, "xz"}};

Status CheckPositive(const char* field, double v, double cap, const char* unit) {
  if (!std::isfinite(v)) return Status::InvalidArgument(field, "must be a finite number");
  if (v <= 0) return Status::InvalidArgument(field, "must be > 0 " + std::string(unit) + ", got " + Num(v));
  if (v > cap) return Status::InvalidArgument(field, "must be <= " + Num(cap) + " " + unit + ", got " + Num(v));
  return Status::Ok();
}

// As CheckPositive, with a lower bound above 0 (said with its reason).
Status CheckAtLeast(const char* field, double v, double least, double cap, const char* unit, const char* why) {
  SANDSWIM_RETURN_IF_ERROR(CheckPositive(field, v, cap, unit));
  if (v < least)
    return Status::InvalidArgument(field,
                                   "must be >= " + Num(least) + " " + unit + " (" + why + "), got " + Num(v));
  return Status::Ok();
}

Status CheckSigned(const char* field, double v, double cap, const char* unit) {
  if (!std::isfinite(v)) return Status::InvalidArgument(field, "must be a finite number");
  if (std::fabs(v) > cap)
    return Status::InvalidArgument(
        field, "|" + std::string(field) + "| must be <= " + Num(cap) + " " + unit + ", got " + Num(v));
  return Status::Ok();
}

Status CheckUnused(const char* field, double v, Mode mode) {
  if (v != 0.0) return Status::InvalidArgument(field, "is not used by mode \"" + std::string(ModeName(mode)) + "\"");
  return Status::Ok();
}

}  // namespace

std::string_view ModeName(Mode mode) {
  for (const auto& e : kModes)
    if (e.mode == mode) return e.name;
  return "?";
}

std::optional<Mode> ParseMode(std::string_view name) {
  for (const auto& e : kModes)
    if (e.name == name) return e.mode;
  return std::nullopt;
}

std::string_view AxisName(RotationAxis axis) {
  for (const auto& e : kAxes)
    if (e.axis == axis) return e.name;
  return "?";
}

std::optional<RotationAxis> ParseAxis(std::string_view name) {
  for (const auto& e : kAxes)
    if (e.name == name) return e.axis;
  return std::nullopt;
}

std::array<double, 3> AxisVector(RotationAxis axis) {
  switch (axis) {
    case RotationAxis::kX:
      return {1, 0, 0};
    case RotationAxis::kY:
      return {0, 1, 0};
    case RotationAxis::kZ:
      return {0, 0, 1};
    case RotationAxis::kXZ:
      return {M_SQRT1_2, 0, M_SQRT1_2};
  }
  return {1, 0, 0};
}

Point OscillatoryPoint(double A, double f, double Omega, double duration_s) {
  Point p;
  p.mode = Mode::kOscillatory;
  p.A = A;
  p.f = f;
  p.Omega = Omega;
  p.duration_s = duration_s;
  return p;
}

Status Validate(const Point& p) {
  if (p.has_vibration()) {
    SANDSWIM_RETURN_IF_ERROR(CheckPositive("A", p.A, kMaxAmplitudeM, "m"));
    SANDSWIM_RETURN_IF_ERROR(CheckAtLeast("f", p.f, kMinFrequencyHz, kMaxFrequencyHz, "Hz",
                                          "one period must fit in the longest run, a day"));
  } else {
    SANDSWIM_RETURN_IF_ERROR(CheckUnused("A", p.A, p.mode));
    SANDSWIM_RETURN_IF_ERROR(CheckUnused("f", p.f, p.mode));
  }
  if (p.mode == Mode::kOscillatory) {
    SANDSWIM_RETURN_IF_ERROR(CheckSigned("Omega", p.Omega, kMaxAngularVelocity, "rad/s"));
  } else {
    SANDSWIM_RETURN_IF_ERROR(CheckUnused("Omega", p.Omega, p.mode));
  }
  if (p.has_constant_rotation()) {
    SANDSWIM_RETURN_IF_ERROR(CheckSigned("omega", p.omega, kMaxAngularVelocity, "rad/s"));
  } else {
    SANDSWIM_RETURN_IF_ERROR(CheckUnused("omega", p.omega, p.mode));
  }
  SANDSWIM_RETURN_IF_ERROR(CheckAtLeast("duration_s", p.duration_s, kMinDurationS, kMaxDurationS, "s",
                                        "the deck's shortest loop, 100 steps of 1e-5 s"));
  return ValidateMaterials(p.materials);
}

bool SameDrive(const Point& a, const Point& b) {
  return a.mode == b.mode && a.A == b.A && a.f == b.f && a.Omega == b.Omega && a.omega == b.omega &&
         (!a.has_constant_rotation() || a.axis == b.axis) && a.materials == b.materials &&
         DriveStep(a) == DriveStep(b);
}

DriveId DriveIdOf(const Point& p) {
  std::array<double, kMaterialFieldCount> materials{};
  for (size_t i = 0; i < kMaterialFieldCount; ++i) materials[i] = p.materials.*MaterialFields()[i].member;
  return {static_cast<int>(p.mode), p.A,   p.f, p.Omega, p.omega, p.has_constant_rotation() ? static_cast<int>(p.axis) : -1,
          materials, DriveStep(p)};
}

double DriveStep(const Point& p) { return p.dt_s ? *p.dt_s : TimeStep(p.materials); }

Result<Point> StoredPoint(std::string_view mode, std::string_view axis, double A, double f, double Omega, double omega,
                          double duration_s, const std::optional<std::string>& materials,
                          std::optional<double> dt_s) {
  std::optional<Mode> m = ParseMode(mode);
  if (!m)
    return Status(StatusCode::kCorruption, "stored mode \"" + std::string(mode) + "\" is not one of ours", "mode");
  std::optional<RotationAxis> a = ParseAxis(axis);
  if (!a)
    return Status(StatusCode::kCorruption, "stored axis \"" + std::string(axis) + "\" is not one of ours", "axis");
  Point p;
  p.mode = *m;
  p.axis = *a;
  p.A = A;
  p.f = f;
  p.Omega = Omega;
  p.omega = omega;
  p.duration_s = duration_s;
  Result<Materials> stored = StoredMaterials(materials);
  if (!stored.ok()) return stored.status();
  p.materials = *stored;
  if (dt_s) {
    if (!std::isfinite(*dt_s) || !(*dt_s > 0))
      return Status(StatusCode::kCorruption, "stored time step " + std::to_string(*dt_s) + " is not a step", "dt_s");
    if (*dt_s != TimeStep(p.materials)) p.dt_s = dt_s;
  }
  return p;
}

}  // namespace sandswim
