#include "core/deck.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "core/embedded.h"
#include "core/numerics.h"

namespace sandswim {
namespace {

using Values = std::map<std::string, std::string>;

// The grain insertion of the bed deck (templates/README.md explains these choices):
// fix insert/pack saturates near a volume fraction of 0.30 here, so grains are inserted at 0.25
// into a region tall enough that, packed at about 0.6 after settling, they fill the layer.
constexpr double kInsertFraction = 0.25;
constexpr double kPackedFraction = 0.60;
constexpr double kSampleS = 0.01;             // kinetic-energy sampling period (1000 steps of 1e-5 s)
constexpr double kViscousGamma = 0.2;         // N s/m for Table 1's grain: damping time m_grain / gamma ~ 50 ms
constexpr double kViscousS = 0.2;             // s of damping (20000 steps of 1e-5 s)
constexpr int kCheckSamples = 100;            // at most 1 s of undamped checking
constexpr double kKineticEnergyRatio = 1e-4;  // Sec. 2.3
constexpr double kSkin = 0.01;                // m; fastest measured here
constexpr double kThermoS = 0.01;              // thermo output (1000 steps of 1e-5 s; MillisecondSteps' rule)

std::string Fmt(double v) { return FormatNumber(v); }
// Lengths the renderer derives (box, regions) are rounded to a nanometre, so that the deck reads
// "0.07" and not "0.06999999999999999". User values are never rounded: they go through Fmt.
std::string Length(double v) { return FormatNumber(std::round(v * 1e9) / 1e9); }
std::string Fmt(long long v) { return std::to_string(v); }

// Replaces every {{name}} with its value. A placeholder without a value, or a value without a
// placeholder, is a programming error: it throws, and the golden tests catch it.
std::string Render(std::string_view tpl, const Values& values) {
  std::string out;
  out.reserve(tpl.size() + 256);
  std::map<std::string, bool> used;
  size_t pos = 0;
  while (true) {
    size_t open = tpl.find("{{", pos);
    if (open == std::string_view::npos) break;
    size_t close = tpl.find("}}", open);
    if (close == std::string_view::npos) throw std::logic_error("unterminated placeholder in template");
    out.append(tpl.substr(pos, open - pos));
    std::string name(tpl.substr(open + 2, close - open - 2));
    auto it = values.find(name);
    if (it == values.end()) throw std::logic_error("template placeholder without a value: " + name);
    out += it->second;
    used[name] = true;
    pos = close + 2;
  }
  out.append(tpl.substr(pos));
  for (const auto& [name, value] : values)
    if (!used.count(name)) throw std::logic_error("value without a placeholder: " + name);
  return out;
}

std::string_view Template(const char* name) {
  auto t = EmbeddedFile(name);
  if (!t) throw std::logic_error(std::string("template not compiled in: ") + name);
  return *t;
}

// Values both decks share: the materials (Table 1's unless the point sets others), the step and
// the floor.
Values CommonValues(const Box& box, const Materials& m, double dt) {
  return {
      {"template_version", Fmt(static_cast<long long>(kTemplateVersion))},
      {"skin", Fmt(kSkin)},
      {"youngs", Fmt(m.youngs)},
      {"poisson", Fmt(m.poisson)},
      {"youngs_so", Fmt(kMaterials.youngs_so)},
      {"poisson_so", Fmt(kMaterials.poisson_so)},
      {"e_gg", Fmt(m.e_grain_grain)},
      {"e_gs", Fmt(m.e_so_grain)},
      {"mu_gg", Fmt(m.mu_grain_grain)},
      {"mu_gs", Fmt(m.mu_so_grain)},
      {"dt", Fmt(dt)},  // DriveFacts' dt
      {"gravity", Fmt(kMaterials.gravity)},
      {"z_floor", Length(box.z_floor)},
  };
}

// The lines a deck of other materials than Table 1's carries after its first line: which
// parameters are not Table 1's (the bed's only, in a bed deck) and the step with its rule. A
// Table 1 deck has none, so its bytes and key are what they were before materials could be set.
std::string MaterialsHeader(const Materials& m, MaterialRole only_role, bool all_roles) {
  std::string set;
  for (const MaterialField& f : MaterialFields()) {
    if (!all_roles && f.role != only_role) continue;
    if (m.*f.member == kTable1.*f.member) continue;
    set += (set.empty() ? "" : ", ") + std::string(f.name) + " " + FormatNumber(m.*f.member) +
           (f.unit.empty() ? "" : " " + std::string(f.unit)) + (f.role == MaterialRole::kBed ? " (bed)" : " (drive)");
  }
  if (set.empty()) return "";
  return "# Materials not Table 1's: " + set + ".\n# Time step " + FormatNumber(TimeStep(m)) + " s: " +
         kTimeStepRule + ".\n";
}

// The lines a drive deck whose step is not its materials' rule carries (none otherwise: a Table 1
// deck's bytes and key stay what they were before steps could be set): the step and its criteria
// (core/numerics.h), and where the evidence for it is.
std::string StepHeader(const Point& p) {
  if (!p.dt_s) return "";
  const StepCriteria c = JudgeStep(p, *p.dt_s);
  std::string out = "# Time step " + FormatNumber(*p.dt_s) + " s, not Table 1's rule (" +
                    FormatNumber(TimeStep(p.materials)) + " s): numerics.dt or its scale's default, core/numerics.h;\n" +
                    "#   convergence evidence: docs/explanation/convergence.md. Criteria: " +
                    FormatNumber(std::round(1000 * c.grain_rayleigh_fraction) / 10) +
                    " % of the grain's Rayleigh time, " + FormatNumber(std::round(c.contact_steps)) +
                    " steps a Hertz contact and " + FormatNumber(std::round(c.pass_steps)) +
                    " to pass a grain at " + FormatNumber(std::round(c.speed_mps * 100) / 100) + " m/s.\n";
  for (const std::string& w : c.warnings) out += "#   warned: " + w + "\n";
  return out;
}

// Inserts `lines` after the deck's first line (its title).
std::string AfterTitle(std::string deck, const std::string& lines) {
  if (lines.empty()) return deck;
  const size_t eol = deck.find('\n');
  if (eol == std::string::npos) throw std::logic_error("a deck without a title line");
  deck.insert(eol + 1, lines);
  return deck;
}

// Steps of `dt` in `seconds`, clamped before the conversion to an integer: Validate() keeps a
// point's durations in [kMinDurationS, kMaxDurationS] (4.32e10 steps at most, at the shortest
// step), and a value outside that (NaN included) must not reach llround, whose result is undefined
// past long long.
long long StepsFor(double seconds, double dt) {
  const double steps = seconds / dt;
  if (!(steps > 0)) return 0;
  return std::llround(std::min(steps, kMaxDurationS / dt));
}

}  // namespace

std::string FormatNumber(double v) {
  if (v == 0) return "0";  // also folds -0
  char buf[64];
  auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

namespace {

bool IsPrime(long long n) {
  if (n < 2) return false;
  for (long long d = 2; d * d <= n; ++d)
    if (n % d == 0) return false;
  return true;
}

// The `index`-th prime after `base` (index 0: base itself, which is prime).
long long PrimeAfter(long long base, int index) {
  long long p = base;
  for (int i = 0; i < index; ++i) {
    do {
      ++p;
    } while (!IsPrime(p));
  }
  return p;
}

}  // namespace

BedSeeds BedSeedsFor(int replicate) {
  if (replicate < 0 || replicate >= kMaxReplicates)
    throw std::logic_error("replicate index out of range: " + std::to_string(replicate));
  // Replicate 0 keeps the seeds every bed had before replicates existed; replicate r takes the
  // r-th primes after them (the engine asks for primes > 10000).
  return BedSeeds{PrimeAfter(49979693, replicate), PrimeAfter(86028121, replicate)};
}

std::string RenderBedDeck(const Scale& scale, int replicate, const Materials& materials) {
  const Materials m = BedMaterials(materials);
  const Box s = BoxFor(scale, m);
  const double dt = TimeStep(m);
  const long long sample_steps = StepsFor(kSampleS, dt);
  const BedSeeds seeds = BedSeedsFor(replicate);
  const double r = m.d_grain / 2;
  // The drag keeps its 50 ms damping time for a grain of another mass.
  const double grain_mass_ratio = m.rho_grain / kTable1.rho_grain * std::pow(m.d_grain / kTable1.d_grain, 3);
  Values v = CommonValues(s, m, dt);
  const double h1 = 0.0 - s.z_floor;    // first layer: floor to z = 0
  const double h2 = s.z_bed_top - 0.0;  // second layer: z = 0 to the top
  const double stretch = kPackedFraction / kInsertFraction;
  const double pour1_lo = s.z_floor + r;
  const double pour1_hi = pour1_lo + h1 * stretch;
  const double pour2_lo = m.d_so / 2 + r;  // above the SO placed at z = 0
  const double pour2_hi = pour2_lo + h2 * stretch;
  // Fall time from the top of a pour region to its layer, plus as long again to settle.
  auto settle_steps = [&](double drop) {
    long long steps = StepsFor(2 * std::sqrt(2 * drop / kMaterials.gravity), dt);
    return (steps + sample_steps - 1) / sample_steps * sample_steps;
  };
  v.insert({
      {"z_bed_top", Length(s.z_bed_top)},
      {"x_lo", Length(-s.x_len / 2)},
      {"x_hi", Length(s.x_len / 2)},
      {"y_lo", Length(-s.y_len / 2)},
      {"y_hi", Length(s.y_len / 2)},
      // insert/pack refuses a region outside the box: the box holds both pour regions.
      {"z_box_top", Length(std::max(pour1_hi, pour2_hi) + 2 * m.d_grain)},
      {"rho_grain", Fmt(m.rho_grain)},
      {"r_grain", Fmt(r)},
      {"insert_fraction", Fmt(kInsertFraction)},
      {"pour1_lo", Length(pour1_lo)},
      {"pour1_hi", Length(pour1_hi)},
      {"pour1_steps", Fmt(settle_steps(pour1_hi - s.z_floor))},
      {"clear_radius", Length(m.d_so / 2 + r)},
      {"d_so", Fmt(m.d_so)},
      {"rho_so", Fmt(m.rho_so)},
      {"pour2_lo", Length(pour2_lo)},
      {"pour2_hi", Length(pour2_hi)},
      {"pour2_samples", Fmt(settle_steps(pour2_hi - s.z_floor) / sample_steps)},
      {"sample_steps", Fmt(sample_steps)},
      {"viscous_gamma", Fmt(kViscousGamma * grain_mass_ratio)},
      {"viscous_steps", Fmt(StepsFor(kViscousS, dt))},
      {"check_samples", Fmt(static_cast<long long>(kCheckSamples))},
      {"check_steps", Fmt(static_cast<long long>(kCheckSamples) * sample_steps)},
      {"ke_ratio", Fmt(kKineticEnergyRatio)},
      {"restart_file", kBedRestartFile},
      {"bed_dump_file", kBedDumpFile},
      {"replicate", Fmt(static_cast<long long>(replicate))},
      {"seed_pour1", Fmt(seeds.pour1)},
      {"seed_pour2", Fmt(seeds.pour2)},
  });
  return AfterTitle(Render(Template("templates/bed.in"), v), MaterialsHeader(m, MaterialRole::kBed, false));
}

namespace {
// Steps in kOmegaUpdateS (at least one) at the point's set step; a step from its materials' rule
// (no dt_s) keeps the 100 steps its deck always had, so its bytes and key are unchanged.
long long MillisecondSteps(const Point& p) {
  return std::max(1LL, std::llround(kOmegaUpdateS / p.dt_s.value_or(kMaterials.dt)));
}
}  // namespace

int DumpEverySteps(const Point& p) { return static_cast<int>(MillisecondSteps(p)); }

int OmegaUpdateSteps(const Point& p) {
  const long long ms = MillisecondSteps(p);
  if (!p.has_vibration()) return static_cast<int>(ms);
  const double period_steps = 1.0 / (p.f * DriveStep(p));
  // Clamped as a double first: a tiny f makes period_steps past long long (or inf), and the cast
  // of such a value is undefined.
  const double most = std::floor(period_steps / kMinOmegaUpdatesPerPeriod);
  if (!(most >= 1)) return 1;
  return static_cast<int>(std::min(most, static_cast<double>(ms)));
}

long long DriveSteps(const Point& p, const std::optional<PrecisionTarget>& target) {
  const long long chunk = OmegaUpdateSteps(p);
  const long long steps = std::max(1LL, StepsFor(RunDuration(p, target), DriveStep(p)));  // never 0 steps
  return (steps + chunk - 1) / chunk * chunk;
}

std::string ControlFileText(StopVerdict verdict) {
  const int code = verdict == StopVerdict::kTargetMet ? 1 : verdict == StopVerdict::kWindowClosed ? 2 : 0;
  return "variable sandswim_stop equal " + std::to_string(code) + "\n";
}

DriveInfo DriveFacts(const Point& p, const Scale& s) {
  DriveInfo d;
  d.dt = DriveStep(p);
  d.f = p.has_vibration() ? p.f : 0.0;
  d.A = p.has_vibration() ? p.A : 0.0;
  d.z_floor = std::round(BoxFor(s, p.materials).z_floor * 1e9) / 1e9;  // as the deck's Length()
  d.so_radius = p.materials.d_so / 2;                                 // as the deck's r_so
  return d;
}

Result<SnapshotFractions> CheckSnapshotFractions(std::vector<double> fractions) {
  if (fractions.size() > kMaxSnapshots)
    return Status::InvalidArgument("snapshots", "at most " + std::to_string(kMaxSnapshots) + " snapshots a run, got " +
                                                    std::to_string(fractions.size()));
  for (size_t i = 0; i < fractions.size(); ++i) {
    const double v = fractions[i];
    if (!std::isfinite(v) || v < 0 || v > 1)
      return Status::InvalidArgument("snapshots[" + std::to_string(i) + "]",
                                     "a snapshot is a fraction of the run's length, from 0 (its start) to 1 (its end)");
  }
  std::sort(fractions.begin(), fractions.end());
  if (std::adjacent_find(fractions.begin(), fractions.end()) != fractions.end())
    return Status::InvalidArgument("snapshots", "names one fraction twice");
  return fractions;
}

std::optional<std::string> SnapshotFractionsText(const SnapshotFractions& fractions) {
  if (fractions.empty()) return std::nullopt;
  return nlohmann::json(fractions).dump();
}

Result<SnapshotFractions> StoredSnapshotFractions(const std::optional<std::string>& text) {
  if (!text) return SnapshotFractions{};
  const nlohmann::json j = nlohmann::json::parse(*text, nullptr, /*allow_exceptions=*/false);
  SnapshotFractions out;
  if (j.is_array()) {
    for (const auto& v : j) {
      if (!v.is_number()) break;
      out.push_back(v.get<double>());
    }
  }
  if (!j.is_array() || out.size() != j.size() || !std::is_sorted(out.begin(), out.end()))
    return Status::Corruption("runs.snapshots: not an ascending JSON array of fractions: " + *text);
  return out;
}

long long SnapshotEverySteps(const Point& p, const std::optional<PrecisionTarget>& target) {
  const long long chunk = OmegaUpdateSteps(p);
  const long long chunks = DriveSteps(p, target) / chunk;
  return std::max(1LL, chunks / kSnapshotFramesPerRun) * chunk;
}

std::string RenderDriveDeck(const Point& p, const Scale& s, const std::optional<PrecisionTarget>& target,
                            const SnapshotFractions& snapshots) {
  const Materials& m = p.materials;
  const Box box = BoxFor(s, m);
  const DriveInfo drive = DriveFacts(p, s);
  Values v = CommonValues(box, m, drive.dt);
  // omega(t) = w0 + w1 cos(2 pi f t), along the mode's axis (core/point.h).
  std::array<double, 3> w0{0, 0, 0}, w1{0, 0, 0};
  if (p.has_constant_rotation()) {
    auto a = AxisVector(p.axis);
    for (int i = 0; i < 3; ++i) w0[i] = p.omega * a[i];
  }
  if (p.mode == Mode::kOscillatory) w1[0] = p.Omega;
  const long long steps = DriveSteps(p, target);
  const long long chunk = OmegaUpdateSteps(p);
  std::string precision = "none: the run lasts its whole duration";
  if (target) {
    precision = "95 % interval of U_z within max(" + Fmt(target->uz_rel) + " |U_z|, " + Fmt(target->uz_abs) +
                " m/s) after at least " + Fmt(static_cast<long long>(target->min_periods)) +
                " whole periods, at most " + Fmt(RunDuration(p, target)) + " s";
  }
  v.insert({
      {"A", Fmt(drive.A)},
      {"f", Fmt(drive.f)},
      {"w0x", Fmt(w0[0])},
      {"w0y", Fmt(w0[1])},
      {"w0z", Fmt(w0[2])},
      {"w1x", Fmt(w1[0])},
      {"w1y", Fmt(w1[1])},
      {"w1z", Fmt(w1[2])},
      {"omega_every", Fmt(chunk)},
      {"dump_every", Fmt(static_cast<long long>(DumpEverySteps(p)))},
      {"thermo_every", Fmt(std::max(1LL, StepsFor(kThermoS, p.dt_s.value_or(kMaterials.dt))))},
      {"chunks", Fmt(steps / chunk)},
      {"total_steps", Fmt(steps)},
      {"r_so", Fmt(m.d_so / 2)},
      // The SO's centre when its bottom is one grain diameter above the floor: it is at the floor.
      {"z_floor_stop", Length(box.z_floor + m.d_so / 2 + m.d_grain)},
      {"control_file", kControlFile},
      {"precision", precision},
  });
  std::string deck = AfterTitle(Render(Template("templates/drive.in"), v),
                                MaterialsHeader(m, MaterialRole::kDrive, true) + StepHeader(p));
  if (m.rho_so != kTable1.rho_so) {
    // A drive-only parameter: the bed was poured with Table 1's SO, which now takes its density.
    const std::string anchor = "group so type 2\n";
    const size_t at = deck.find(anchor);
    if (at == std::string::npos) throw std::logic_error("templates/drive.in lost its 'group so' line");
    deck.insert(at + anchor.size(), "set group so density " + Fmt(m.rho_so) + "\n");
  }
  if (snapshots.empty()) return deck;
  // The frames' dump goes right after the trajectory's, before the first run; the last frame is
  // written where every way of ending meets.
  std::string fractions;
  for (double fraction : snapshots) fractions += (fractions.empty() ? "" : ", ") + Fmt(fraction);
  const std::string every = Fmt(SnapshotEverySteps(p, target));
  const std::string frames = Render(Template("templates/drive_snapshots.in"),
                                    {{"snapshot_fractions", fractions},
                                     {"snapshot_every", every},
                                     {"snapshot_frames", kSnapshotFramePattern}});
  const std::string anchor = "dump_modify traj sort id\n";
  const size_t at = deck.find(anchor);
  if (at == std::string::npos || deck.compare(deck.size() - 13, 13, "label finish\n") != 0)
    throw std::logic_error("templates/drive.in lost the lines snapshots are placed after");
  deck.insert(at + anchor.size(), frames);
  deck += Render(Template("templates/drive_snapshot_last.in"), {{"snapshot_last", kSnapshotLastFile}});
  return deck;
}

}  // namespace sandswim
