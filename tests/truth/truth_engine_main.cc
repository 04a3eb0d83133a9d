// sandswim-truth-engine: a STAND-IN for LIGGGHTS whose SO follows a KNOWN LAW (tests/truth/
// truth_law.h), for measuring the analysis and the claims' rules through the real daemon and worker.
// It simulates no grain; its log's version line says what it is, so no result it produces can
// pass for a real one. Like the orchestration stand-in (tests/bench/stand_in_engine.cc) it takes
// LIGGGHTS's command line (-in DECK -log LOG [-screen X] [-var N V]) and reads the rendered deck:
//   - a bed deck (no read_restart): writes bed.restart naming the replicate its comment states
//     ("Replicate R of this scale's bed"), and the log's bed markers (6,682 grains, the measured
//     smoke bed of core/scale.cc);
//   - a drive deck: its drive (variable A, f, wx/wy/wz: mode, Omega or omega and axis), its steps
//     (chunks x steps per chunk), timestep, floor stop and control file; the bed from bed.restart;
//     then writes the SO's dump every 100 steps (so.dump) and the log's drive markers, stopping as
//     the deck does: at the surface, at the floor, or when the control file asks.
// The SO's motion comes from GenerateRun with the law named by SANDSWIM_TRUTH_LAW (default
// "paper"), the world SANDSWIM_TRUTH_SEED (default 1) and the default noise: the in-process
// calibration (tests/truth/calibration.h) with the same law and world gives the same samples.
// SANDSWIM_TRUTH_PACE (wall seconds per simulated second, default 0) writes the dump at that pace,
// one chunk at a time, and reads the control file after every chunk, so that a worker following a
// precision target can end the run; at 0 the run is written at once.
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include "core/deck.h"
#include "core/scale.h"
#include "tests/truth/truth_law.h"

namespace sandswim::truth {
namespace {

// The number after `key` on the first line that starts (after blanks) with it.
std::optional<double> After(const std::string& deck, const std::string& key) {
  size_t pos = 0;
  while ((pos = deck.find(key, pos)) != std::string::npos) {
    size_t bol = deck.rfind('\n', pos);
    bol = bol == std::string::npos ? 0 : bol + 1;
    if (deck.find_first_not_of(" \t", bol) == pos) return std::strtod(deck.c_str() + pos + key.size(), nullptr);
    pos += key.size();
  }
  return std::nullopt;
}

bool ReadAll(const std::string& path, std::string* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  std::stringstream ss;
  ss << in.rdbuf();
  *out = ss.str();
  return true;
}

bool WriteAll(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
  return static_cast<bool>(out);
}

// The drive a deck renders (templates/drive.in): y = A sin(2 pi f t), omega = w0 + W1 cos(2 pi f t).
Point DriveOf(const std::string& deck, double duration_s) {
  const double A = After(deck, "variable A equal ").value_or(0);
  const double f = After(deck, "variable f equal ").value_or(0);
  double w0[3] = {0, 0, 0}, w1[3] = {0, 0, 0};
  const char* keys[3] = {"variable wx equal ", "variable wy equal ", "variable wz equal "};
  for (int i = 0; i < 3; ++i) {
    size_t at = deck.find(keys[i]);
    if (at == std::string::npos) continue;
    char* end = nullptr;
    const char* text = deck.c_str() + at + std::strlen(keys[i]);
    w0[i] = std::strtod(text, &end);
    if (end != nullptr && *end == '+') w1[i] = std::strtod(end + 1, nullptr);
  }
  Point p;
  p.duration_s = duration_s;
  if (w1[0] != 0 || w1[1] != 0 || w1[2] != 0) {
    p.mode = Mode::kOscillatory;
    p.A = A;
    p.f = f;
    p.Omega = w1[0];
    return p;
  }
  const double omega = std::sqrt(w0[0] * w0[0] + w0[1] * w0[1] + w0[2] * w0[2]);
  if (omega == 0) {
    p.mode = Mode::kVibration;
    p.A = A;
    p.f = f;
    return p;
  }
  p.mode = A > 0 ? Mode::kVibrationRotation : Mode::kRotation;
  p.A = A;
  p.f = f;
  p.omega = std::round(omega * 1e9) / 1e9;
  const bool x = w0[0] != 0, z = w0[2] != 0;
  p.axis = x && z ? RotationAxis::kXZ : x ? RotationAxis::kX : z ? RotationAxis::kZ : RotationAxis::kY;
  return p;
}

// The scale whose floor the deck renders (its "zplane"), smoke when none matches.
const Scale& ScaleOf(const std::string& deck) {
  size_t at = deck.find("zplane ");
  if (at != std::string::npos) {
    const double z = std::strtod(deck.c_str() + at + 7, nullptr);
    for (const Scale& s : AllScales())
      if (std::fabs(s.z_floor - z) < 1e-9) return s;
  }
  return *FindScale("smoke");
}

int Main(int argc, char** argv) {
  std::string deck_file, log_file = "log.lammps";
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], "-in") == 0)
      deck_file = argv[++i];
    else if (std::strcmp(argv[i], "-log") == 0)
      log_file = argv[++i];
    else if (std::strcmp(argv[i], "-screen") == 0 || std::strcmp(argv[i], "-var") == 0)
      ++i;
  }
  std::string deck;
  if (deck_file.empty() || !ReadAll(deck_file, &deck)) {
    std::fprintf(stderr, "ERROR: Cannot open input script %s\n", deck_file.empty() ? "(none)" : deck_file.c_str());
    return 1;
  }
  const char* law_name = std::getenv("SANDSWIM_TRUTH_LAW");
  const Law* law = FindLaw(law_name != nullptr ? law_name : "paper");
  if (law == nullptr) {
    std::fprintf(stderr, "ERROR: unknown SANDSWIM_TRUTH_LAW '%s'\n", law_name);
    return 1;
  }
  const char* seed_text = std::getenv("SANDSWIM_TRUTH_SEED");
  const uint64_t world = seed_text != nullptr ? std::strtoull(seed_text, nullptr, 10) : 1;
  const char* pace_text = std::getenv("SANDSWIM_TRUTH_PACE");
  const double pace = pace_text != nullptr ? std::max(0.0, std::strtod(pace_text, nullptr)) : 0;
  const Noise noise;
  std::string log = "LIGGGHTS (Version sandswim-truth-engine 0, NOT LIGGGHTS: a stand-in whose SO follows the law '" +
                    law->name + "', world " + std::to_string(world) + ")\n";

  if (deck.find("read_restart") == std::string::npos) {  // a bed deck
    size_t at = deck.find("Replicate ");
    const int replicate = at == std::string::npos ? 0 : std::atoi(deck.c_str() + at + 10);
    const Bed bed = MakeBed(world, replicate, noise, ScaleOf(deck));
    if (!WriteAll(kBedRestartFile, "sandswim-truth-engine bed replicate " + std::to_string(replicate) + "\n")) return 1;
    char line[256];
    std::snprintf(line, sizeof line,
                  "SANDSWIM bed equilibrated ke 1e-06 ke_peak 1\n"
                  "SANDSWIM bed grains %lld so_z %.17g grain_top %.17g step 1\n"
                  "SANDSWIM bed done\n",
                  static_cast<long long>(bed.grains), bed.z0, bed.surface);
    log += line;
    return WriteAll(log_file, log) ? 0 : 1;
  }

  std::string restart;
  int replicate = 0;
  if (ReadAll(kBedRestartFile, &restart)) {
    size_t at = restart.find("replicate ");
    if (at != std::string::npos) replicate = std::atoi(restart.c_str() + at + 10);
  }
  const Bed bed = MakeBed(world, replicate, noise, ScaleOf(deck));
  const long long chunks = static_cast<long long>(After(deck, "variable c loop ").value_or(1));
  long long per_chunk = 1;
  size_t at = deck.find(" pre no post no");
  if (at != std::string::npos) {
    size_t run = deck.rfind("run ", at);
    if (run != std::string::npos) per_chunk = std::atoll(deck.c_str() + run + 4);
  }
  const double dt = After(deck, "timestep").value_or(kMaterials.dt);
  const double duration = static_cast<double>(chunks * per_chunk) * dt;
  Point point = DriveOf(deck, duration);
  if (dt != TimeStep(point.materials)) point.dt_s = dt;  // as planning set it (core/numerics.h)
  RunSpec spec;
  spec.point = point;
  spec.duration_s = duration;
  // The floor stop the deck renders is floor + r_SO + d_grain.
  if (auto stop = After(deck, "variable z_floor_stop equal ")) spec.z_floor = *stop - kMaterials.d_so / 2 - kMaterials.d_grain;
  // The control file, read after every chunk (with a pace, as the run goes; at once, it says 0).
  spec.lag_s = 0;
  if (pace > 0) {
    spec.stop_hook = [pace](const std::vector<SoSample>& so_far, std::string* reason) {
      usleep(static_cast<useconds_t>(pace * 1e-3 * 1e6));
      std::string control;
      if (!ReadAll(kControlFile, &control)) return false;
      if (control.find("equal 1") != std::string::npos) *reason = "target";
      else if (control.find("equal 2") != std::string::npos) *reason = "window";
      else return false;
      (void)so_far;
      return true;
    };
  }
  WriteAll(kControlFile, "variable sandswim_stop equal 0\n");
  char line[512];
  std::snprintf(line, sizeof line, "SANDSWIM drive start grains %lld so_z %.17g surface %.17g\n",
                static_cast<long long>(bed.grains), bed.z0, bed.surface);
  log += line;
  // With a pace the dump grows as the run goes: each frame is written when its chunk is done.
  FILE* dump = std::fopen(kTrajectoryDumpFile, "w");
  if (dump == nullptr) return 1;
  size_t written = 0;
  auto write_frames = [&](const std::vector<SoSample>& samples) {
    for (; written < samples.size(); ++written) {
      const SoSample& s = samples[written];
      std::fprintf(dump,
                   "ITEM: TIMESTEP\n%lld\nITEM: NUMBER OF ATOMS\n1\nITEM: BOX BOUNDS pp pp ff\n"
                   "-0.09 0.09\n-0.19 0.19\n-0.35 0.34\nITEM: ATOMS id x y z vx vy vz omegax omegay omegaz\n"
                   "2 %.17g %.17g %.17g 0 0 0 0 0 0\n",
                   static_cast<long long>(s.step), s.x, s.y, s.z);
    }
    std::fflush(dump);
  };
  if (pace > 0) {
    StopHook control = spec.stop_hook;
    spec.stop_hook = [&, control](const std::vector<SoSample>& so_far, std::string* reason) {
      write_frames(so_far);
      return control(so_far, reason);
    };
  }
  const EngineRun run = GenerateRun(*law, noise, bed, spec, RunSeed(world, replicate, point));
  write_frames(run.samples);
  std::fclose(dump);
  std::snprintf(line, sizeof line, "SANDSWIM drive stop %s step %lld t %.17g z %.17g\n", run.stop.reason.c_str(),
                static_cast<long long>(run.stop.step), run.stop.t, run.stop.z);
  log += line;
  return WriteAll(log_file, log) ? 0 : 1;
}

}  // namespace
}  // namespace sandswim::truth

int main(int argc, char** argv) { return sandswim::truth::Main(argc, argv); }
