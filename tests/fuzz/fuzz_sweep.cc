// Fuzz target: the JSON a user submits -- a sweep, a campaign, the body of POST /api/v1/sweeps --
// through the parsers that guard every deck (core/sweep.h), planned at smoke when it parses.
// tests/fuzz/run.sh builds and runs it.
#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "core/sweep.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const nlohmann::json j =
      nlohmann::json::parse(reinterpret_cast<const char*>(data), reinterpret_cast<const char*>(data) + size, nullptr,
                            /*allow_exceptions=*/false);
  if (j.is_discarded()) return 0;
  auto sweep = sandswim::ParseSweep(j);
  if (sweep.ok()) {
    sandswim::PlanOptions options;
    options.max_runs = 2000;  // a fuzz input may ask for 100,000 runs: plan a bounded number
    options.keep_decks = false;
    (void)sandswim::PlanSweeps({*sweep}, *sandswim::FindScale("smoke"), "fuzz", options);
  }
  (void)sandswim::ParseCampaign(j);
  return 0;
}
