// ctest's `smoke_bed` fixture: prepares the shared smoke bed (replicate 0) into the test cache
// (on RANKS ranks, default 1), so that no test holds a slot while it waits on the bed's lock. The
// physics and Slurm tests require the fixture; the end-to-end test starts beside it (its worker
// prepares replicate 1 meanwhile) and waits on the lock only when it hands this bed in
// (tests/engine_fixture.h PrepareBed, tests/service_fixture.h BedHandIn). The surface-stop test
// pours its own bed beside them. Usage: prepare_beds [RANKS]
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>

#include "core/scale.h"
#include "tests/engine_fixture.h"

int main(int argc, char** argv) {
  const int ranks = argc > 1 ? std::atoi(argv[1]) : 1;
  if (ranks < 1) {
    std::fprintf(stderr, "prepare_beds: RANKS must be a positive integer, got '%s'\n", argv[1]);
    return 2;
  }
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const std::string restart = sandswim::testing::PrepareBed(*sandswim::FindScale("smoke"), 0, ranks);
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("smoke bed (replicate 0) ready in %.1f s on %d rank(s): %s (%ju bytes)\n", s, ranks, restart.c_str(),
                static_cast<uintmax_t>(std::filesystem::file_size(restart)));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "prepare_beds: %s\n", e.what());
    return 1;
  }
  return 0;
}
