// Test support: runs the real LIGGGHTS on rendered decks, and prepares beds once per content key.
//
// PrepareBed() renders the bed deck of a scale (and replicate) and runs it in <cache>/<bed key>/
// unless a finished restart is already there, under an exclusive file lock, so parallel test
// binaries share one prepared bed (the smoke bed takes about four minutes of one core). ctest's
// `smoke_bed` fixture (tests/prepare_beds.cc) prepares smoke's replicate 0 before the engine tests
// that use it start, so none of them holds a test slot while it waits on the lock. The cache is
// $SANDSWIM_TEST_CACHE or <build>/test-cache.
//
// Thread safety: PrepareBed is safe across processes (flock); RunDeck has no shared state.
#ifndef SANDSWIM_TESTS_ENGINE_FIXTURE_H_
#define SANDSWIM_TESTS_ENGINE_FIXTURE_H_

#include <string>
#include <vector>

#include "core/point.h"
#include "core/scale.h"

namespace sandswim::testing {

struct EngineRun {
  int exit_code = -1;
  std::string dir;  // the run directory
  std::string log;  // log.liggghts
};

// Runs `mpirun -np ranks liggghts -in deck` in `dir` (created; bed restart linked in if given).
EngineRun RunDeck(const std::string& dir, const std::string& deck, const std::string& bed_restart = "", int ranks = 1);

// Returns the path of a prepared bed restart for `scale` and `replicate` (core/deck.h
// RenderBedDeck); prepares it on first use, on `ranks` MPI ranks.
std::string PrepareBed(const Scale& scale, int replicate = 0, int ranks = 1);

// The SO's frames in a drive run's trajectory dump (core/deck.h kTrajectoryDumpFile), one per
// dump step; test failures where the dump is torn or holds more than the SO.
struct SoFrame {
  double t, x, y, z, vy, wx, wy, wz;
};
std::vector<SoFrame> ReadTrajectory(const std::string& run_dir);

// Drives point `p` on `scale`'s prepared bed in <cache>/physics/<name> (cleared first): the drive
// deck rendered as the daemon renders it, run under mpirun on one rank; test failures where the
// point is invalid or does not fit the scale, or the engine fails.
EngineRun Drive(const std::string& name, const Point& p, const Scale& scale);

// The engine version string (first line of a LIGGGHTS log).
std::string EngineVersion();

std::string ReadFile(const std::string& path);
std::string CacheDir();

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_ENGINE_FIXTURE_H_
