// Test support: runs the real LIGGGHTS on rendered decks, and prepares beds once per content key.
//
// PrepareBed() renders the bed deck of a scale and runs it in <cache>/<bed key>/ unless a finished
// restart is already there, under an exclusive file lock, so parallel test binaries share one
// prepared bed (the smoke bed takes about two minutes; CI prepares it once). The cache is
// $SANDSWIM_TEST_CACHE or <build>/test-cache.
//
// Thread safety: PrepareBed is safe across processes (flock); RunDeck has no shared state.
#ifndef SANDSWIM_TESTS_ENGINE_FIXTURE_H_
#define SANDSWIM_TESTS_ENGINE_FIXTURE_H_

#include <string>

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

// Returns the path of a prepared bed restart for `scale`; prepares it on first use.
std::string PrepareBed(const Scale& scale);

// The engine version string (first line of a LIGGGHTS log).
std::string EngineVersion();

std::string ReadFile(const std::string& path);
std::string CacheDir();

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_ENGINE_FIXTURE_H_
