// A store holding a campaign of 10,000 runs with SYNTHETIC results, for benchmarks that need a
// large finished study without running one: bench_dashboard (the page's first render) and
// bench_python_results.py (a notebook's results frame, through bench_seed_store).
//
// The campaign "big-10k" is one 100 x 100 sweep (Omega x A) at smoke; its beds are completed with
// a synthetic restart and its first `runs_done` runs with a synthetic U_z (0.05 ± 0.004 m/s, a
// fixed seed) and a 50-point trajectory, through the daemon's own LeaseQueue, so every row is
// stored as a worker's completion would be. The rest stay queued.
//
// Thread safety: opens and writes `db`; call from one thread, with no daemon on the file.
#ifndef SANDSWIM_TESTS_BENCH_SYNTHETIC_CAMPAIGN_H_
#define SANDSWIM_TESTS_BENCH_SYNTHETIC_CAMPAIGN_H_

#include <string>

#include "core/status.h"

namespace sandswim::bench {

struct SeededCampaign {
  int runs = 0;       // in the campaign (10,000)
  int runs_done = 0;  // completed with synthetic results
  double seconds = 0; // to complete them
};

// Creates `db` (with the daemon's migrations) and `data_dir`, and seeds them as above;
// `engine` is the engine_version every result states (name it SYNTHETIC). `with_claim`: the
// campaign states one claim (a sign rule over its sweep), so its run has a verdict to evaluate
// (bench_load --claims).
Result<SeededCampaign> SeedTenThousandRunCampaign(const std::string& db, const std::string& data_dir, int runs_done,
                                                  const std::string& engine, bool with_claim = false);

}  // namespace sandswim::bench

#endif  // SANDSWIM_TESTS_BENCH_SYNTHETIC_CAMPAIGN_H_
