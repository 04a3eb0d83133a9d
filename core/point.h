// Point: one set of drive parameters for the self-excited object (SO), and its validation.
//
// A Point is what a user asks for (SPEC.md "point"): a drive mode and its numbers in SI units.
// Validation is pure and names the offending field; a Point that passed Validate() is the only
// thing the deck renderer accepts, so user text never reaches a deck.
//
// A point also carries its materials (Materials below): Table 1 of the paper unless a sweep sets
// them. A point whose materials are Table 1's renders the decks, keys and JSON it always did.
//
// Modes (SPEC.md, paper Sec. 3):
//   vibration           y = A sin(2 pi f t); omega = 0.
//   rotation            constant omega about `axis`; y held at its start.
//   vibration+rotation  both of the above at once.
//   oscillatory         y = A sin(2 pi f t) and omega_x = Omega cos(2 pi f t) (paper eq. 6).
// Signs of omega and Omega: right-hand rule about the axis (about +x for oscillatory).
//
// Thread safety: values.
#ifndef SANDSWIM_CORE_POINT_H_
#define SANDSWIM_CORE_POINT_H_

#include <array>
#include <optional>
#include <string>
#include <string_view>
#include <tuple>

#include "core/materials.h"
#include "core/status.h"

namespace sandswim {

enum class Mode { kVibration, kRotation, kVibrationRotation, kOscillatory };
enum class RotationAxis { kX, kY, kZ, kXZ };

std::string_view ModeName(Mode mode);  // "vibration", ..., "oscillatory"
std::optional<Mode> ParseMode(std::string_view name);
std::string_view AxisName(RotationAxis axis);  // "x", "y", "z", "xz"
std::optional<RotationAxis> ParseAxis(std::string_view name);
// Unit vector of the axis; xz is (1, 0, 1)/sqrt(2).
std::array<double, 3> AxisVector(RotationAxis axis);

// Caps that keep a point inside what the engine and this service can sensibly run. They are
// stated in the API description and in every refusal.
inline constexpr double kMaxAmplitudeM = 1.0;          // A
inline constexpr double kMaxFrequencyHz = 1000.0;      // f
inline constexpr double kMaxAngularVelocity = 5000.0;  // |Omega|, |omega| in rad/s
inline constexpr double kMaxDurationS = 86400.0;       // a day of physical time
// Lower bounds, from what a deck must hold. A run needs at least one whole drive period (U_z is
// taken over whole periods), so a period may be at most the longest run: f >= 1 / kMaxDurationS.
// A run needs at least one step; the deck advances in chunks of the 1 ms omega-update loop
// (kOmegaUpdateSteps steps of dt = 1e-5 s), so anything shorter than 1 ms renders the same deck
// as 1 ms: duration_s >= 1 ms. Both keep every step count the deck converts to an integer finite
// and far inside long long (f = 1e-300 once made a 5e303-step period).
inline constexpr double kMinFrequencyHz = 1.0 / kMaxDurationS;  // ~1.16e-5 Hz
inline constexpr double kMinDurationS = 1e-3;

struct Point {
  Mode mode = Mode::kOscillatory;
  double A = 0.0;                        // m; vibration, vibration+rotation, oscillatory
  double f = 0.0;                        // Hz; vibration, vibration+rotation, oscillatory
  double Omega = 0.0;                    // rad/s; oscillatory only (eq. 6 amplitude)
  double omega = 0.0;                    // rad/s; rotation, vibration+rotation (constant)
  RotationAxis axis = RotationAxis::kX;  // rotation, vibration+rotation
  double duration_s = 0.0;               // physical time the user asks for
  Materials materials;                   // Table 1 unless a sweep sets them
  // The drive's time step when it is not the materials' rule (core/materials.h TimeStep): set by
  // planning (core/numerics.h ResolveDriveStep), never by a sweep's "base". Absent: TimeStep.
  std::optional<double> dt_s;

  bool has_vibration() const { return mode != Mode::kRotation; }
  bool has_constant_rotation() const { return mode == Mode::kRotation || mode == Mode::kVibrationRotation; }
};

// The step the point's drive deck runs at: dt_s, else its materials' TimeStep.
double DriveStep(const Point& p);

// A point as the database stores it (mode and axis by name): the one decoding the daemon's reads
// and its lease queue share. Corruption naming the column when a name is not one of ours.
// `materials` is the runs.materials column (core/materials.h StoredMaterials: NULL is Table 1's),
// `dt_s` the runs.dt_s column (NULL: the materials' TimeStep; a non-positive or non-finite step is
// Corruption naming "dt_s").
Result<Point> StoredPoint(std::string_view mode, std::string_view axis, double A, double f, double Omega, double omega,
                          double duration_s, const std::optional<std::string>& materials,
                          std::optional<double> dt_s = std::nullopt);

// The paper's Sec. 3.2 drive (eq. 6): y = A sin(2 pi f t), omega_x = Omega cos(2 pi f t).
Point OscillatoryPoint(double A, double f, double Omega, double duration_s);

// Checks finiteness, signs and caps of the fields the mode uses. Fields the mode does not use
// must be zero (the parser never sets them). Errors name the field ("A", "f", "Omega", ...).
// Materials: ValidateMaterials (core/materials.h).
Status Validate(const Point& p);

// Two points drive the SO the same way (everything but duration equal, materials and step included).
bool SameDrive(const Point& a, const Point& b);
// An ordered identity of the drive: equal exactly when SameDrive (axis only where it matters).
using DriveId =
    std::tuple<int, double, double, double, double, int, std::array<double, kMaterialFieldCount>, double>;
DriveId DriveIdOf(const Point& p);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_POINT_H_
