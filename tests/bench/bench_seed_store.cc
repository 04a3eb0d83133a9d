// bench_seed_store: writes DIR/sandswim.db and DIR/var/data holding the 10,000-run campaign with
// SYNTHETIC results of tests/bench/synthetic_campaign.h, for a benchmark that then starts
// sandswimd on them (bench_python_results.py: `sandswimd --db DIR/sandswim.db --data DIR/var/data`).
//
//   bench_seed_store DIR [--runs-done 10000]
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "tests/bench/synthetic_campaign.h"

int main(int argc, char** argv) {
  if (argc < 2 || (argc != 2 && argc != 4) || (argc == 4 && std::string(argv[2]) != "--runs-done")) {
    std::fprintf(stderr, "usage: bench_seed_store DIR [--runs-done N]\n");
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  const int runs_done = argc == 4 ? std::atoi(argv[3]) : 10000;
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  auto seeded = sandswim::bench::SeedTenThousandRunCampaign((dir / "sandswim.db").string(),
                                                            (dir / "var" / "data").string(), runs_done,
                                                            "LIGGGHTS (SYNTHETIC, bench_seed_store)");
  if (!seeded.ok()) {
    std::fprintf(stderr, "bench_seed_store: %s\n", seeded.status().ToString().c_str());
    return 1;
  }
  std::printf("%s: campaign big-10k, %d runs, %d completed with SYNTHETIC results in %.1f s\n", dir.c_str(),
              seeded->runs, seeded->runs_done, seeded->seconds);
  return 0;
}
