// ClaimCheck: the verdicts of a campaign's claims (core/claims.h) for one campaign run, read from the
// Store: the claims of the campaign as the catalogue has it (server/store/campaigns.h), each sweep's
// analysis (AnalyzeSweep: its samples over replicate beds and its fits), every run of each sweep
// with its state, result and last error, and the beds those runs use. Served by
// GET /api/v1/campaign-runs/{id}/claims, `sandswim check cr:ID` and the first section of the
// report.
//
// Where the claims come from: the campaign's stored definition; a built-in campaign recorded
// before its file stated claims (the stored copy has no "claims") takes the built-in file's claims,
// and says so in `claims_source`. A campaign that is gone states none.
//
// Every verdict of a fixed-design run carries its rule's error rates at the campaign run's design
// (DesignOf, core/claim_rates.h AttachClaimRates), or says it is not calibrated there.
//
// An adaptive campaign run (its definition has "adaptive": the daemon runs it in rounds,
// server/jobs/rounds.h) shows each claim decided at a look as it was FROZEN there
// (server/store/rounds.h FrozenVerdicts): a later evaluation, with later rounds' runs, never
// replaces it -- deciding at the first deciding look and never again is what keeps the verdicts'
// error rates for the whole sequence of looks. A claim still open is inconclusive until a look
// decides it, whatever the runs so far read (`current_verdict` says what they read). Its verdicts'
// error rates are the whole procedure's, which bench_adaptive measures (core/adaptive.h), not the
// single-look tables': every verdict and part carries AdaptiveClaimRates, uncalibrated, saying so,
// and the design is described as adaptive (DescribeAdaptiveDesign). A fixed-design run shows the
// current evaluation of every claim.
//
// Thread safety: free functions over a thread-safe Store.
#ifndef SANDSWIM_SERVER_ANALYSIS_CLAIM_CHECK_H_
#define SANDSWIM_SERVER_ANALYSIS_CLAIM_CHECK_H_

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/adaptive.h"
#include "core/claim_rates.h"
#include "core/claims.h"
#include "core/status.h"
#include "server/analysis/sweep_analysis.h"
#include "server/store/rounds.h"
#include "server/store/store.h"

namespace sandswim {

// Where an adaptive run's rounds are (from its rounds::ListRounds rows).
struct RoundsSoFar {
  int rounds = 1;                // rounds planned so far (round 1 before its row is written)
  std::optional<int> next_look;  // the round whose look comes next; none once the rounds stopped
  int stopped_after = 0;         // the round they stopped after (next_look none)
};
RoundsSoFar RoundsSoFarOf(const std::vector<rounds::RoundRow>& rows);

struct CampaignRunClaims {
  CampaignRunInfo campaign_run;
  std::string claims_source;  // "stored" | "builtin" | "none"
  std::string note;           // e.g. why the claims come from the built-in file
  std::vector<ClaimVerdict> verdicts;
  DesignKey design;  // what the verdicts' error rates are looked up by (core/claim_rates.h)
  // Whether the campaign run runs in rounds, and its verdicts frozen so far, by claim id (already
  // applied to `verdicts` by ShowFrozenVerdicts).
  bool adaptive = false;
  std::map<std::string, rounds::FrozenVerdict> frozen;
  // Adaptive only: each claim's current evaluation with every round's runs so far (what it reads,
  // frozen or open), and where the rounds are.
  std::map<std::string, Verdict> current;
  RoundsSoFar rounds_so_far;
  std::string design_text;  // DescribeDesign, or DescribeAdaptiveDesign for an adaptive run
};
// {"campaign_run_id","campaign","scale","claims_source","note","adaptive","counts":{"holds",
//  "differs","inconclusive"},"design":DesignKeyToJson (+ "adaptive": true for an adaptive run),
//  "design_text","claims":[ClaimVerdictToJson ..., and for an adaptive run "frozen_at_round" (null
//  while open), "frozen_at" (unix s, null while open), "decided_by" (the
//  deciding look's ClaimVerdictToJson as stored when it froze the claim; null while open or when
//  frozen before migration 18), "verdict_text" "holds at smoke (frozen at
//  round 2)", "current_verdict" (what every round's runs so far read)]}
nlohmann::json CampaignRunClaimsToJson(const CampaignRunClaims& c);

// NotFound for an unknown campaign run.
Result<CampaignRunClaims> CheckClaims(Store& store, int64_t campaign_run_id);
// The same with the run's sweeps already analysed (`analyses`, one per sweep of the campaign run,
// as AnalyzeSweep made them): the report has them at hand.
Result<CampaignRunClaims> CheckClaims(Store& store, const CampaignRunInfo& campaign_run,
                                      const std::vector<SweepAnalysis>& analyses);

// What CheckClaims evaluates, before it does: the claims the campaign run is judged by (none: an
// empty look) and its runs and beds as the claims read them. The daemon's rounds
// (server/jobs/rounds.h) look through this, so that a round is planned from the same data the
// verdicts shown are decided on.
Result<ClaimLook> LookAtClaims(Store& store, const CampaignRunInfo& campaign_run);


// The pure part of showing an adaptive run's verdicts; returns each claim's current evaluation.
// A claim in `frozen` takes its frozen verdict: when the current evaluation agrees, its reason,
// parts and figures stay, labelled as the current evaluation with every round's runs (not the
// deciding look's numbers); when it differs, they go, and the reason says which look decided it
// and what the runs now read, which does not count. A claim not in `frozen` that the current
// evaluation decides is shown inconclusive ("reads holds with the runs so far; only the look after
// a round decides (the next look: after round N)"): a look, not a read between looks, decides.
// Rates are left as they are.
std::map<std::string, Verdict> ShowFrozenVerdicts(std::vector<ClaimVerdict>& verdicts,
                                                  const std::map<std::string, rounds::FrozenVerdict>& frozen,
                                                  const RoundsSoFar& so_far);

// What an adaptive run's verdicts are quoted instead of the single-look tables' rates.
inline constexpr const char* kAdaptiveRatesText =
    "the adaptive procedure's error rates are measured by tests/bench/bench_adaptive (docs/measurements.md, "
    "\"Adaptive rounds on the truth engine\"), not the single-look tables";
// Uncalibrated rates at `design_text`, text kAdaptiveRatesText.
ClaimRates AdaptiveClaimRates(const std::string& design_text);
// Sets every verdict's and part's rates to AdaptiveClaimRates(design_text).
void AttachAdaptiveRates(std::vector<ClaimVerdict>& verdicts, const std::string& design_text);
// "tiny-rounds at smoke, adaptive: in rounds (2 rounds so far), beds vary by point (1 to 2 beds a
// point), rules 4, analysis 3".
std::string DescribeAdaptiveDesign(const DesignKey& key, const ClaimInput& input, const RoundsSoFar& so_far);
// "holds at smoke (frozen at round 2)"; VerdictAtScale for a claim not frozen.
std::string FrozenVerdictText(const ClaimVerdict& v, const std::map<std::string, rounds::FrozenVerdict>& frozen);

// The pure part: what the claims see of one sweep -- its analysis's samples and fits, and every
// run of its result rows with its state, result and last error (`failures`: run id -> "kind:
// message" of its failed runs). The truth engine's calibration (tests/truth/) assembles its
// ClaimInput with it, as CheckClaims does.
// The design a campaign run's verdicts were decided at: its campaign's definition (with the
// claims it was judged by), its scale, and K, the most replicate beds a point of it ran on.
DesignKey DesignOf(const std::string& campaign, const nlohmann::json& definition, const std::vector<Claim>& claims,
                   const ClaimInput& input);

ClaimSweep ClaimSweepOf(const SweepAnalysis& analysis, const std::vector<ResultRow>& rows,
                        const std::map<int64_t, std::string>& failures);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_CLAIM_CHECK_H_
