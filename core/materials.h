// Materials: the sweepable material and size parameters of a point (paper Table 1), which of them
// change the poured bed and which only the drive, their physical bounds, and the time step they
// need.
//
// Thread safety: values and pure functions.
#ifndef SANDSWIM_CORE_MATERIALS_H_
#define SANDSWIM_CORE_MATERIALS_H_

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

#include <nlohmann/json_fwd.hpp>

#include "core/status.h"

namespace sandswim {

// The materials of a point: the sweepable parameters, each Table 1's unless set (paper Table 1 and
// Sec. 2.3; nothing here is tuned). Which deck a parameter enters decides what it costs to change:
//   bed   (part of the bed's deck, hence of its key: a point with other values pours a bed of its
//         own, and points that share these values share their bed):
//           d_grain, rho_grain, youngs, poisson (the grains'), e_grain_grain, mu_grain_grain,
//           d_so (the poured bed holds the SO's hole, and its box follows the SO's size).
//   drive (set in the drive deck after read_restart: the bed poured with Table 1's values is kept):
//           rho_so (`set group so density`), e_so_grain and mu_so_grain (the SO-grain pair of the
//           restitution and friction matrices the drive deck re-specifies).
// The SO's Young's modulus and Poisson ratio stay Table 1's (Table1Materials): the issue and the
// paper vary the bed's stiffness, not the SO's.
struct Materials {
  double d_grain = 0.02;         // m                grain diameter          bed
  double rho_grain = 2500;       // kg/m^3           grain density           bed
  double d_so = 0.12;            // m                SO diameter             bed
  double rho_so = 2500;          // kg/m^3           SO density              drive
  double youngs = 1e7;           // Pa               grains' Young's modulus bed
  double poisson = 0.25;         //                  grains' Poisson ratio   bed
  double e_grain_grain = 0.9;    // restitution, grain-grain                 bed
  double e_so_grain = 0.5;       // restitution, SO-grain                    drive
  double mu_grain_grain = 0.45;  // friction, grain-grain                    bed
  double mu_so_grain = 0.5;      // friction, SO-grain                       drive
};
bool operator==(const Materials& a, const Materials& b);
inline bool operator!=(const Materials& a, const Materials& b) { return !(a == b); }

// Table 1 with what a point does not set: the SO's stiffness, gravity, and the paper's time step,
// which is the longest step any point takes (core/deck.h TimeStep).
struct Table1Materials : Materials {
  double youngs_so = 1e7;  // Pa
  double poisson_so = 0.25;
  double gravity = 9.81;  // m/s^2, along -z
  double dt = 1e-5;       // s
};
inline constexpr Table1Materials kMaterials{};
inline constexpr Materials kTable1{};

enum class MaterialRole { kBed, kDrive };
// One sweepable material parameter: its name (the JSON key and axis param), where it lives in
// Materials, its unit, its role, and its physical bounds. The one list the parser, the validation,
// the JSON and the decks' bed/drive split read.
struct MaterialField {
  enum class Bound { kPositive, kRestitution, kFriction, kPoisson };
  std::string_view name;
  double Materials::*member;
  std::string_view unit;  // "" when dimensionless
  MaterialRole role;
  Bound bound;
  double cap;  // the largest value taken (finiteness, and what a deck can sensibly hold)
};
inline constexpr size_t kMaterialFieldCount = 10;
const std::array<MaterialField, kMaterialFieldCount>& MaterialFields();
const MaterialField* FindMaterialField(std::string_view name);
// The bed's materials: `m` with its drive-only parameters set back to Table 1's.
Materials BedMaterials(const Materials& m);

// Physical bounds of every field (MaterialField::bound and cap) and the SO at least a grain
// across. InvalidArgument naming the field ("so_density", "grain_poisson", ...).
Status ValidateMaterials(const Materials& m);

// The database's form (runs.materials): a JSON object of the fields that are not Table 1's, by
// name ({"so_density":5000}); nullopt (NULL) when all are Table 1's, so a Table 1 run's row is
// what it was before materials could be set. And back: Corruption naming the column when the
// text is not such an object.
std::optional<std::string> MaterialsText(const Materials& m);
Result<Materials> StoredMaterials(const std::optional<std::string>& text);

// For people: the fields that are not Table 1's, "so_density = 5000 kg/m^3, grain_friction = 0.3"
// (in MaterialFields' order; "" when all are Table 1's; `except` left out), so that points which
// differ only in their materials do not read alike in a table or a legend.
std::string MaterialsLabel(const Materials& m, std::string_view except = {});
// Every field as the API lists it for a client that shows them (the results' `material_fields`):
// [{"name", "unit", "role": "bed"|"drive", "table1"}], in MaterialFields' order. A row or point
// carries only the fields that are not Table 1's: a client shows `table1` where a row has none.
nlohmann::json MaterialFieldsJson();

// ---- Time step ---------------------------------------------------------------------------------
// The rule: the paper's step (Table1Materials::dt, 1e-5 s) scaled by the Rayleigh time of the
// particle that needs the shortest step relative to Table 1's grain, and never longer than the
// paper's:
//   T_R = pi r sqrt(rho / G) / (0.1631 nu + 0.8766),  G = Y / (2 (1 + nu))
//   dt  = 1e-5 s x min(1, min over {grain, SO} of T_R / T_R(Table 1 grain)), rounded down to two
//         significant digits.
// The Rayleigh time bounds how fast a contact's elastic wave crosses a particle; the paper's 1e-5 s
// is 1.2 % of its grain's (8.6e-4 s), and the rule keeps that fraction for the stiffest, smallest,
// lightest particle of the point. With Table 1 it gives 1e-5 s exactly; softer, larger or heavier
// particles keep 1e-5 s (the ceiling: never a longer step than the paper's).
double RayleighTime(double diameter, double density, double youngs, double poisson);
double TimeStep(const Materials& m);
// A step rounded down to two significant digits (7.3e-06): a deck never states a 17-digit step.
double RoundStepDown(double step);
// The rule in words, for the deck's header and the run's record.
inline constexpr char kTimeStepRule[] =
    "1e-5 s x min(1, T_R / T_R of Table 1's grain) over grain and SO, T_R the Rayleigh time, rounded down";

}  // namespace sandswim

#endif  // SANDSWIM_CORE_MATERIALS_H_
