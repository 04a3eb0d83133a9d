#include "core/materials.h"

#include <cmath>
#include <cstdlib>
#include <string>

#include "core/text.h"

#include <nlohmann/json.hpp>

namespace sandswim {
namespace {

using Bound = MaterialField::Bound;
constexpr std::array<MaterialField, kMaterialFieldCount> kMaterialFields = {{
    {"so_density", &Materials::rho_so, "kg/m^3", MaterialRole::kDrive, Bound::kPositive, 1e5},
    {"so_diameter", &Materials::d_so, "m", MaterialRole::kBed, Bound::kPositive, 1.0},
    {"so_friction", &Materials::mu_so_grain, "", MaterialRole::kDrive, Bound::kFriction, 10.0},
    {"so_restitution", &Materials::e_so_grain, "", MaterialRole::kDrive, Bound::kRestitution, 1.0},
    {"grain_diameter", &Materials::d_grain, "m", MaterialRole::kBed, Bound::kPositive, 0.1},
    {"grain_density", &Materials::rho_grain, "kg/m^3", MaterialRole::kBed, Bound::kPositive, 1e5},
    {"grain_friction", &Materials::mu_grain_grain, "", MaterialRole::kBed, Bound::kFriction, 10.0},
    {"grain_restitution", &Materials::e_grain_grain, "", MaterialRole::kBed, Bound::kRestitution, 1.0},
    {"grain_youngs", &Materials::youngs, "Pa", MaterialRole::kBed, Bound::kPositive, 1e12},
    {"grain_poisson", &Materials::poisson, "", MaterialRole::kBed, Bound::kPoisson, 0.5},
}};

Status CheckMaterial(const MaterialField& field, double v) {
  const std::string name(field.name);
  const std::string unit = field.unit.empty() ? "" : " " + std::string(field.unit);
  if (!std::isfinite(v)) return Status::InvalidArgument(name, "must be a finite number");
  switch (field.bound) {
    case Bound::kPositive:
      if (v <= 0) return Status::InvalidArgument(name, "must be > 0" + unit + ", got " + Num(v));
      if (v > field.cap) return Status::InvalidArgument(name, "must be <= " + Num(field.cap) + unit + ", got " + Num(v));
      return Status::Ok();
    case Bound::kRestitution:
      if (v <= 0 || v > 1)
        return Status::InvalidArgument(name, "a coefficient of restitution must be in (0, 1], got " + Num(v));
      return Status::Ok();
    case Bound::kFriction:
      if (v < 0 || v > field.cap)
        return Status::InvalidArgument(
            name, "a coefficient of friction must be in [0, " + Num(field.cap) + "], got " + Num(v));
      return Status::Ok();
    case Bound::kPoisson:
      if (v <= 0 || v >= 0.5)
        return Status::InvalidArgument(name, "a Poisson ratio must be in (0, 0.5), got " + Num(v) + unit);
      return Status::Ok();
  }
  return Status::Ok();
}

}  // namespace

bool operator==(const Materials& a, const Materials& b) {
  for (const MaterialField& f : kMaterialFields)
    if (a.*f.member != b.*f.member) return false;
  return true;
}

const std::array<MaterialField, kMaterialFieldCount>& MaterialFields() { return kMaterialFields; }

const MaterialField* FindMaterialField(std::string_view name) {
  for (const MaterialField& f : kMaterialFields)
    if (f.name == name) return &f;
  return nullptr;
}

Materials BedMaterials(const Materials& m) {
  Materials bed = m;
  for (const MaterialField& f : kMaterialFields)
    if (f.role == MaterialRole::kDrive) bed.*f.member = kTable1.*f.member;
  return bed;
}

Status ValidateMaterials(const Materials& m) {
  for (const MaterialField& f : kMaterialFields) SANDSWIM_RETURN_IF_ERROR(CheckMaterial(f, m.*f.member));
  if (m.d_so < m.d_grain)
    return Status::InvalidArgument("so_diameter", "the SO must be at least a grain across: " + Num(m.d_so) +
                                                      " m < grain_diameter " + Num(m.d_grain) + " m");
  return Status::Ok();
}

std::optional<std::string> MaterialsText(const Materials& m) {
  nlohmann::json j = nlohmann::json::object();
  for (const MaterialField& f : kMaterialFields)
    if (m.*f.member != kTable1.*f.member) j[std::string(f.name)] = m.*f.member;
  if (j.empty()) return std::nullopt;
  return j.dump();
}

std::string MaterialsLabel(const Materials& m, std::string_view except) {
  std::string out;
  for (const MaterialField& f : kMaterialFields) {
    if (m.*f.member == kTable1.*f.member || f.name == except) continue;
    out += (out.empty() ? "" : ", ") + std::string(f.name) + " = " + Num(m.*f.member, 4) + (f.unit.empty() ? "" : " ") +
           std::string(f.unit);
  }
  return out;
}

nlohmann::json MaterialFieldsJson() {
  nlohmann::json out = nlohmann::json::array();
  for (const MaterialField& f : kMaterialFields)
    out.push_back({{"name", std::string(f.name)},
                   {"unit", std::string(f.unit)},
                   {"role", f.role == MaterialRole::kBed ? "bed" : "drive"},
                   {"table1", kTable1.*f.member}});
  return out;
}

Result<Materials> StoredMaterials(const std::optional<std::string>& text) {
  Materials m;
  if (!text) return m;
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  bool ok = j.is_object();
  if (ok) {
    for (const auto& [key, value] : j.items()) {
      const MaterialField* f = FindMaterialField(key);
      if (f == nullptr || !value.is_number()) {
        ok = false;
        break;
      }
      m.*f->member = value.get<double>();
    }
  }
  if (!ok) return Status::Corruption("runs.materials: not an object of material parameters: " + *text);
  return m;
}

double RayleighTime(double diameter, double density, double youngs, double poisson) {
  const double shear = youngs / (2 * (1 + poisson));
  return M_PI * (diameter / 2) * std::sqrt(density / shear) / (0.1631 * poisson + 0.8766);
}

double TimeStep(const Materials& m) {
  const double table1 = RayleighTime(kTable1.d_grain, kTable1.rho_grain, kTable1.youngs, kTable1.poisson);
  const double grain = RayleighTime(m.d_grain, m.rho_grain, m.youngs, m.poisson);
  const double so = RayleighTime(m.d_so, m.rho_so, kMaterials.youngs_so, kMaterials.poisson_so);
  const double ratio = std::min(grain, so) / table1;
  if (!(ratio < 1)) return kMaterials.dt;  // Table 1 itself lands here: exactly 1e-5 s
  return RoundStepDown(kMaterials.dt * ratio);
}

double RoundStepDown(double step) {
  const double unit = std::pow(10.0, std::floor(std::log10(step)) - 1);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.0fe%d", std::floor(step / unit * (1 + 1e-12)), static_cast<int>(std::lround(std::log10(unit))));
  return std::strtod(buf, nullptr);
}

}  // namespace sandswim
