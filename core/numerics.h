// Numerics: the drive's time step as a numerical choice apart from the physics, the criteria that
// judge a step for a point, and the bounds past which a step is refused.
//
// Table 1's step (1e-5 s) is 1.2 % of its grain's Rayleigh time. The step is not physics: any step
// that integrates the same contacts well enough gives the same U_z. Which steps do is decided by a
// study (the built-in `dt-convergence` campaign and its `converges` claim, core/claims.h), not
// assumed; until it decides, every scale's default is Table 1's.
//
// Where a step comes from (ResolveDriveStep), for a point of a sweep at a scale:
//   asked     the sweep's (else its campaign's) "numerics": {"dt": s}: taken as asked, or refused
//             (InvalidArgument "numerics.dt") when it passes a hard bound for any point of the sweep;
//   default   the scale's default_dt_s, scaled by the point's materials as core/materials.h
//             TimeStep scales Table 1's (a stiffer, smaller, lighter particle gets a shorter step);
//             a default never makes a point invalid: when the point's own criteria refuse it, the
//             point gets the largest step of kStepLadder below it that they accept (or, below the
//             ladder, the bound itself rounded down to two digits), stated in its deck and result.
// The resolved step is part of the point (Point::dt_s, set only when it is not the materials'
// TimeStep, so a Table 1 run's point, deck and key are what they were before steps could be set),
// hence of the rendered deck and of the run's content key; points at different steps never pool.
//
// The criteria (StepCriteria), for the point's fastest speed v: the largest of the vibration's
// 2 pi f A, the SO's surface speed |omega| r_SO (rotation) and |Omega| r_SO (oscillatory):
//   rayleigh    dt / T_R for the grain and the SO (T_R: core/materials.h RayleighTime). DEM
//               practice keeps dt at 10-20 % of T_R (the engine's own check warns past 10 %):
//               warned past kRayleighWarn, refused past kRayleighBound.
//   contact     the steps a Hertz contact between two grains lasts at speed v,
//               t_c = 2.87 (m*^2 / (R* E*^2 v))^(1/5), m* = m/2, R* = r/2, E* = Y / (2 (1 - nu^2)):
//               a collision must be resolved in at least kContactStepsBound steps (warned below
//               kContactStepsWarn). The grain pair is the shortest contact the SO drives (an SO-grain
//               contact at the same speed lasts longer: a larger m*^2 / R*).
//   pass        the steps the fastest surface takes to move one grain diameter, d / (v dt): a grain
//               swept by the SO's surface must meet it over as many steps as a contact needs
//               (the same bounds as `contact`).
//   skin        the travel per step v dt over half the neighbour skin (core/deck.h, 0.01 m): the
//               neighbour list is checked every step and rebuilt once a grain has moved half the
//               skin; a grain that moves that far in one step can pass a contact unseen: refused
//               at 1, warned past kSkinWarn.
// A step inside every bound but past a warning is run and flagged (StepCriteria::warnings).
//
// Thread safety: pure functions and immutable data.
#ifndef SANDSWIM_CORE_NUMERICS_H_
#define SANDSWIM_CORE_NUMERICS_H_

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/point.h"
#include "core/scale.h"
#include "core/status.h"

namespace sandswim {

inline constexpr double kRayleighWarn = 0.10;
inline constexpr double kRayleighBound = 0.20;
inline constexpr double kContactStepsWarn = 20;
inline constexpr double kContactStepsBound = 10;
inline constexpr double kSkinWarn = 0.5;
inline constexpr double kSkinM = 0.01;  // the decks' neighbour skin (core/deck.cc)
// The steps a default shrinks through, longest first, before the bound itself: the steps the
// convergence study runs, so that a point's shrunk step is one the study judged.
inline constexpr double kStepLadder[] = {1e-4, 5e-5, 2.5e-5, 1e-5};
// The longest step anyone may ask for: kRayleighBound of Table 1's grain's T_R is 1.7e-4 s.
inline constexpr double kMaxTimeStepS = 1e-3;

// What a sweep or campaign sets: "numerics": {"dt": s}. Absent: the scale's default.
struct Numerics {
  std::optional<double> dt_s;
};
// Parses {"dt": number}; unknown keys, a non-number, a non-finite or non-positive step, or one
// outside [kMinTimeStepS, kMaxTimeStepS] are InvalidArgument naming "dt" (callers prefix "numerics").
Result<Numerics> ParseNumerics(const nlohmann::json& j);
nlohmann::json NumericsToJson(const Numerics& n);  // {} when nothing is set

enum class StepLevel { kOk, kWarned, kRefused };

struct StepCriteria {
  double dt_s = 0;
  double grain_rayleigh_fraction = 0;  // dt / T_R(grain)
  double so_rayleigh_fraction = 0;     // dt / T_R(SO)
  double speed_mps = 0;                // the point's fastest speed
  std::string speed_from;              // "vibration", "rotation", "oscillatory rotation", "none"
  double contact_steps = 0;            // Hertz grain-grain contact at speed_mps, in steps (inf at v = 0)
  double pass_steps = 0;               // steps for the fastest surface to pass a grain diameter (inf at v = 0)
  double skin_fraction = 0;            // v dt / (skin / 2)
  StepLevel level = StepLevel::kOk;
  std::vector<std::string> warnings;  // one per criterion past its warning
  std::string refusal;                // the first criterion past its bound, in words ("" when none)
  std::string source;                 // "table1", "scale default", "asked", "shrunk for this point"
};

StepCriteria JudgeStep(const Point& p, double dt_s);
// The largest step the point's criteria accept, rounded down to two significant digits (the
// ceiling kMaxTimeStepS).
double LargestAcceptedStep(const Point& p);

// The step of a point of a sweep at `scale`: as the header says. On success, `p.dt_s` is set when
// the step is not the materials' TimeStep (and cleared when it is). InvalidArgument naming
// "numerics.dt" with the criterion and the point when an asked step passes a bound.
Status ResolveDriveStep(Point& p, const Scale& scale, const Numerics& numerics);

// The criteria as the API shows them with a planned run or a result:
// {"dt_s","source","grain_rayleigh_fraction","so_rayleigh_fraction","speed_mps","speed_from",
//  "contact_steps","pass_steps","skin_fraction","level":"ok"|"warned","warnings":[...]}.
nlohmann::json StepCriteriaToJson(const StepCriteria& c);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_NUMERICS_H_
