// A claim-driven campaign (core/adaptive.h) simulated in process on the truth engine: round 1 is
// the calibrated one-bed design (Calibrator::Simulate at K = 1), each later round is planned by
// PlanNextRound from the claims still open and run on the truth engine through the worker's and
// the analysis's own code (Calibrator::RunOne), and every claim's verdict is frozen at the first
// look that decides it (FreezeDecisions). What the procedure spends is counted as the runs ran
// (their simulated time at the cost model's rate, and each bed poured), never more than planned.
//
// Thread safety: pure functions of their arguments; many may run at once.
#ifndef SANDSWIM_TESTS_TRUTH_ADAPTIVE_CAMPAIGN_H_
#define SANDSWIM_TESTS_TRUTH_ADAPTIVE_CAMPAIGN_H_

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "core/adaptive.h"
#include "tests/truth/calibration.h"

namespace sandswim::truth {

struct AdaptiveOutcome {
  std::vector<AdaptiveRound> rounds;      // as planned, the first included; a last one with stop = true
  std::map<std::string, Verdict> frozen;  // the procedure's verdicts (absent: inconclusive)
  std::map<std::string, int> decided_at;  // claim -> the round whose look decided it
  std::vector<ClaimVerdict> last;         // the last look's verdicts
  double sim_s = 0, core_h = 0;           // spent, as the runs ran
  double planned_core_h = 0;              // the rounds' planned maxima
  int beds = 0, runs = 0;
};

// The campaign's declared sweeps as the planner takes them.
std::vector<AdaptiveSweep> DeclaredSweeps(const Calibrator& cal);
// Core-hours a fixed campaign spent as it ran: its runs' simulated time and its beds.
double SpentCoreHours(const SimCampaign& c, const AdaptiveCost& cost);

// REQUIRES: `cal` plans one bed (Design::beds 1).
AdaptiveOutcome SimulateAdaptive(const Calibrator& cal, const Law& law, const Noise& noise, uint64_t world,
                                 double budget_core_h, const AdaptiveOptions& options);

}  // namespace sandswim::truth

#endif  // SANDSWIM_TESTS_TRUTH_ADAPTIVE_CAMPAIGN_H_
