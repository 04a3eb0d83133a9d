// Claim rates: what a verdict is worth at the design it was decided at. The error rates of each
// claim's rule (and each part of it) as the truth engine measured them (tests/truth/,
// bench_claims_calibration --json), committed as data under templates/calibration/ and compiled
// in, and quoted beside every verdict: "false holds <= x %, false differs <= y %, power z % at
// this design".
//
// A design is what the rates depend on (DesignKey): the campaign's definition as far as the
// analysis sees it (a content hash of its sweeps, claims' ids and rules and precision target; not
// its name, descriptions, schedule, snapshots or replicates), the scale, K (replicate beds per
// point), the claims' rules version (core/claims.h kClaimRulesVersion), the run analysis's
// version (core/api.h kAnalysisVersion) and the scale's bed-to-bed prior (core/scale.h
// Scale::bed_sd_rel) that one-bed points' errors and, at any K, censored points' spread include. A verdict is quoted the rates of a table whose key is
// equal in every field, never another design's: without one it says "not calibrated at this
// design" and how to calibrate it.
//
// A table is the benchmark's JSON: {"design":{...,"key":DesignKeyToJson},"laws":[{"law",
// "campaigns","cells":[{"claim","part","true","n","holds":{"count"},"differs":{"count"},...}]}]}.
// For a part: false holds = the holds rate under each law that makes the part false ("true":
// false), the largest upper bound quoted; false differs = the differs rate under each law that
// makes it true, the largest upper bound quoted; power = the holds rate under the law "paper" (every
// claim true), its estimate and interval quoted. Intervals are 95 % Wilson intervals of the counts.
//
// Thread safety: pure functions; the committed tables are parsed once, on first use.
#ifndef SANDSWIM_CORE_CLAIM_RATES_H_
#define SANDSWIM_CORE_CLAIM_RATES_H_

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/claims.h"
#include "core/status.h"

namespace sandswim {

struct DesignKey {
  std::string campaign;         // its name: shown, not compared (the hash is)
  std::string definition_hash;  // CampaignDefinitionHash
  std::string scale;
  int beds = 1;  // K
  int rules_version = kClaimRulesVersion;
  int analysis_version = api::kAnalysisVersion;
  // The scale's bed-to-bed prior (core/scale.h BedPriorOf): a one-bed point's error includes it,
  // and at every K a censored point's lower estimate is spread by it (F5's "fastest").
  double bed_sd_rel = 0;
  bool operator==(const DesignKey& o) const {
    return definition_hash == o.definition_hash && scale == o.scale && beds == o.beds &&
           rules_version == o.rules_version && analysis_version == o.analysis_version && bed_sd_rel == o.bed_sd_rel;
  }
};
nlohmann::json DesignKeyToJson(const DesignKey& k);
Result<DesignKey> DesignKeyFromJson(const nlohmann::json& j);
// "paper-58 at smoke, K = 1 bed, rules 2, analysis 3"
std::string DescribeDesign(const DesignKey& k);

// Lower-case hex SHA-256 of the definition's analysis-relevant content: "sweeps" (each without
// "description", "replicates", "snapshots"), "claims" (each's "id" and "rule") and "precision".
// `claims`, when given, replace the definition's (the claims a campaign run was judged by).
std::string CampaignDefinitionHash(const nlohmann::json& definition,
                                   const std::optional<std::vector<Claim>>& claims = std::nullopt);

// A 95 % Wilson interval of k successes in n ({0, 1} for n = 0).
std::pair<double, double> WilsonInterval(int64_t k, int64_t n);

struct CalibrationTable {
  std::string file;  // "templates/calibration/paper-58.smoke.K1.json"
  DesignKey key;
  nlohmann::json laws;  // the benchmark's "laws"
};
// Parses a benchmark JSON (its "design" must hold a "key").
Result<CalibrationTable> ParseCalibrationTable(const std::string& file, const nlohmann::json& j);
// The compiled-in tables (templates/calibration/*.json); a file that does not parse is skipped
// (the currency test in tests/truth/ fails on it).
const std::vector<CalibrationTable>& CommittedCalibrations();

// The benchmark command that calibrates a design (what "not calibrated" tells one to run).
std::string CalibrateCommand(const DesignKey& k);

// The rates of one claim (`part` "" the whole claim) at `key` from `tables` (the committed ones by
// default): the table whose key equals `key`, else not calibrated.
ClaimRates RatesFor(const std::string& claim_id, const std::string& part, const DesignKey& key,
                    const std::vector<CalibrationTable>& tables);
// Sets every verdict's and part's `rates`.
void AttachClaimRates(std::vector<ClaimVerdict>& verdicts, const DesignKey& key,
                      const std::vector<CalibrationTable>& tables = CommittedCalibrations());

}  // namespace sandswim

#endif  // SANDSWIM_CORE_CLAIM_RATES_H_
