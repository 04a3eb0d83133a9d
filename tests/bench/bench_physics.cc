// bench_physics: the physics figures, measured with the real engine.
//
//   bench_physics [--mini]
//
// Prints, per scale (smoke; mini with --mini, which prepares a ~1.5e4-grain bed: ~10 min):
//   grain count and bed preparation wall time;
//   (the engine's rate on 1 and 2 ranks and the cost of the omega update: bench_engine_rate);
// and, at smoke, z(t) and U_z for Omega = -80 and +80 (A = 0.03 m, f = 3 Hz, two periods).
// A program to run on demand, not a test: it asserts nothing.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "core/deck.h"
#include "core/dump_reader.h"
#include "core/engine_log.h"
#include "core/trajectory.h"
#include "tests/engine_fixture.h"

namespace sandswim {
namespace {

using testing::EngineRun;

// The paper's baseline drive (A = 0.03 m, f = 3 Hz) at a given Omega.
Point Oscillatory(double Omega, double duration) { return OscillatoryPoint(0.03, 3, Omega, duration); }

void BenchScale(const Scale& scale, bool trajectories) {
  auto t0 = std::chrono::steady_clock::now();
  std::string bed = testing::PrepareBed(scale);
  double prep = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EngineLog bed_log = ParseEngineLog(testing::ReadFile(std::filesystem::path(bed).parent_path() / kLogFile));
  long long grains = bed_log.bed_grains ? bed_log.bed_grains->grains : 0;
  std::printf("\n== scale %s: box %.2f x %.2f m, floor %.2f m, bed top %.2f m\n", std::string(scale.name).c_str(),
              scale.x_len, scale.y_len, scale.z_floor, scale.z_bed_top);
  std::printf("grains                       %lld (SO settled at z = %.4f m; %s, KE ratio %.2g)\n", grains,
              bed_log.bed_grains ? bed_log.bed_grains->so_z : 0.0,
              bed_log.bed_equilibrium && bed_log.bed_equilibrium->equilibrated ? "equilibrated" : "NOT equilibrated",
              bed_log.bed_equilibrium ? bed_log.bed_equilibrium->ke / bed_log.bed_equilibrium->ke_peak : 0.0);
  std::printf("bed preparation wall time    %.1f s%s\n", prep,
              prep < 1 ? " (cached; delete the cache to re-measure)" : "");

  if (!trajectories) return;
  for (double Omega : {-80.0, 80.0}) {
    Point q = Oscillatory(Omega, 4);
    std::string dir = testing::CacheDir() + "/bench/" + std::string(scale.name) + "-omega" + std::to_string(int(Omega));
    std::filesystem::remove_all(dir);
    EngineRun r = testing::RunDeck(dir, RenderDriveDeck(q, scale, std::nullopt), bed, 1);
    auto samples = SamplesFromDump(testing::ReadFile(dir + "/" + kTrajectoryDumpFile), kMaterials.dt);
    EngineLog log = ParseEngineLog(r.log);
    if (!samples.ok()) {
      std::printf("Omega = %g: %s\n", Omega, samples.status().ToString().c_str());
      continue;
    }
    auto res =
        AnalyzeTrajectory(*samples, q.f, BedBounds{std::nullopt, scale.z_floor}, log.drive_start, log.drive_stop);
    if (!res.ok()) {
      std::printf("Omega = %g: %s\n", Omega, res.status().ToString().c_str());
      continue;
    }
    std::printf("\nOmega = %+g rad/s, A = 0.03 m, f = 3 Hz, %.3f s at %s:\n  t (s)   z (m)\n", Omega, res->sim_time_s,
                std::string(scale.name).c_str());
    for (size_t i = 0; i < samples->size(); i += 50) std::printf("  %.3f  %+.4f\n", (*samples)[i].t, (*samples)[i].z);
    std::printf(
        "  U_z = %s over [%.3f, %.3f] s (%d blocks, window end: %s)%s%s; dz = %+.4f m; z oscillation %.4f m; "
        "x drift %+.4f m; stop: %s\n",
        res->uz
            ? (std::to_string(*res->uz) + " +- " + (res->uz_stderr ? std::to_string(*res->uz_stderr) : "?") + " m/s")
                  .c_str()
            : "none",
        res->window_t0, res->window_t1, res->uz_blocks, res->window_end.c_str(),
        res->conclusive ? "" : "; inconclusive: ", res->inconclusive_reason.c_str(), res->dz, res->z_osc_amplitude,
        res->x_drift, res->stop_reason.c_str());
  }
}

}  // namespace
}  // namespace sandswim

int main(int argc, char** argv) {
  bool mini = argc > 1 && std::strcmp(argv[1], "--mini") == 0;
  std::printf("engine: %s\n", sandswim::testing::EngineVersion().c_str());
  sandswim::BenchScale(*sandswim::FindScale("smoke"), true);
  if (mini) sandswim::BenchScale(*sandswim::FindScale("mini"), false);
  return 0;
}
