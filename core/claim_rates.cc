#include "core/claim_rates.h"

#include <algorithm>
#include <cmath>

#include "core/embedded.h"
#include "core/keys.h"
#include "core/scale.h"
#include "core/text.h"

namespace sandswim {
namespace {

constexpr const char* kTableDir = "templates/calibration/";
// Below this power a verdict at the design says so and what would help ("power 12 % at
// this design: add replicates"): a rule that holds less often than not when its claim is true
// cannot tell a false claim from a true one by its "holds".
constexpr double kLowPower = 0.5;

std::string Pct(double x) {
  // One decimal below 10 %, whole percent above: the intervals are a few percent wide.
  return Num(100 * x, 100 * x < 10 ? 2 : 3);
}

std::optional<RateEstimate> Estimate(const nlohmann::json& cell, const char* kind, const std::string& law) {
  if (!cell.contains(kind) || !cell[kind].is_object()) return std::nullopt;
  RateEstimate e;
  e.count = cell[kind].value("count", int64_t{0});
  e.n = cell.value("n", int64_t{0});
  if (e.n <= 0) return std::nullopt;
  e.rate = static_cast<double>(e.count) / static_cast<double>(e.n);
  std::tie(e.lo, e.hi) = WilsonInterval(e.count, e.n);
  e.law = law;
  return e;
}

// The worse of two estimates of an error rate: the one with the larger upper bound.
void KeepWorst(std::optional<RateEstimate>& worst, const std::optional<RateEstimate>& e) {
  if (e && (!worst || e->hi > worst->hi)) worst = e;
}

}  // namespace

nlohmann::json DesignKeyToJson(const DesignKey& k) {
  return {{"campaign", k.campaign},         {"definition_hash", k.definition_hash},
          {"scale", k.scale},               {"beds", k.beds},
          {"rules_version", k.rules_version}, {"analysis_version", k.analysis_version},
          {"bed_sd_rel", k.bed_sd_rel}};
}

Result<DesignKey> DesignKeyFromJson(const nlohmann::json& j) {
  if (!j.is_object()) return Status::InvalidArgument("key", "must be an object");
  DesignKey k;
  try {
    k.campaign = j.at("campaign").get<std::string>();
    k.definition_hash = j.at("definition_hash").get<std::string>();
    k.scale = j.at("scale").get<std::string>();
    k.beds = j.at("beds").get<int>();
    k.rules_version = j.at("rules_version").get<int>();
    k.analysis_version = j.at("analysis_version").get<int>();
    k.bed_sd_rel = j.value("bed_sd_rel", 0.0);  // absent: a table made with no prior
  } catch (const nlohmann::json::exception& e) {
    return Status::InvalidArgument("key", e.what());
  }
  return k;
}

std::string DescribeDesign(const DesignKey& k) {
  return k.campaign + " at " + k.scale + ", K = " + std::to_string(k.beds) + (k.beds == 1 ? " bed" : " beds") +
         ", rules " + std::to_string(k.rules_version) + ", analysis " + std::to_string(k.analysis_version) +
         (k.bed_sd_rel > 0 ? ", bed prior " + Num(100 * k.bed_sd_rel, 3) + " %" : "");
}

std::string CampaignDefinitionHash(const nlohmann::json& definition, const std::optional<std::vector<Claim>>& claims) {
  nlohmann::json content = nlohmann::json::object();
  nlohmann::json sweeps = nlohmann::json::array();
  if (definition.contains("sweeps") && definition["sweeps"].is_array()) {
    for (nlohmann::json s : definition["sweeps"]) {
      if (s.is_object())
        for (const char* drop : {"description", "replicates", "snapshots"}) s.erase(drop);
      sweeps.push_back(std::move(s));
    }
  }
  content["sweeps"] = std::move(sweeps);
  nlohmann::json rules = nlohmann::json::array();
  if (claims) {
    for (const Claim& c : *claims) rules.push_back({{"id", c.id}, {"rule", c.rule}});
  } else if (definition.contains("claims") && definition["claims"].is_array()) {
    for (const nlohmann::json& c : definition["claims"])
      if (c.is_object()) rules.push_back({{"id", c.value("id", "")}, {"rule", c.value("rule", nlohmann::json())}});
  }
  content["claims"] = std::move(rules);
  content["precision"] = definition.is_object() ? definition.value("precision", nlohmann::json()) : nlohmann::json();
  // A campaign-wide step changes every run; absent (every design before steps could be set), the
  // hash is what it was.
  if (definition.is_object() && definition.contains("numerics")) content["numerics"] = definition["numerics"];
  // nlohmann::json keeps an object's keys sorted: the dump is canonical.
  return Sha256Hex(content.dump());
}

std::pair<double, double> WilsonInterval(int64_t k, int64_t n) {
  if (n <= 0) return {0, 1};
  const double z = 1.96, nn = static_cast<double>(n), p = static_cast<double>(k) / nn;
  const double den = 1 + z * z / nn, mid = (p + z * z / (2 * nn)) / den;
  const double half = z * std::sqrt(p * (1 - p) / nn + z * z / (4 * nn * nn)) / den;
  return {std::max(0.0, mid - half), std::min(1.0, mid + half)};
}

Result<CalibrationTable> ParseCalibrationTable(const std::string& file, const nlohmann::json& j) {
  if (!j.is_object() || !j.contains("design") || !j["design"].is_object() || !j["design"].contains("key"))
    return Status::InvalidArgument("design.key", "a calibration table names its design's key");
  Result<DesignKey> key = DesignKeyFromJson(j["design"]["key"]);
  if (!key.ok()) return key.status().WithFieldPrefix("design");
  if (!j.contains("laws") || !j["laws"].is_array()) return Status::InvalidArgument("laws", "must be an array");
  return CalibrationTable{file, *key, j["laws"]};
}

const std::vector<CalibrationTable>& CommittedCalibrations() {
  static const std::vector<CalibrationTable> kTables = [] {
    std::vector<CalibrationTable> out;
    for (std::string_view name : EmbeddedFileNames()) {
      if (!StartsWith(name, kTableDir)) continue;
      std::optional<std::string_view> bytes = EmbeddedFile(name);
      if (!bytes) continue;
      nlohmann::json j = nlohmann::json::parse(*bytes, nullptr, false);
      if (j.is_discarded()) continue;
      Result<CalibrationTable> t = ParseCalibrationTable(std::string(name), j);
      if (t.ok()) out.push_back(std::move(*t));
    }
    return out;
  }();
  return kTables;
}

std::string CalibrateCommand(const DesignKey& k) {
  return "build/bin/bench_claims_calibration --campaign " + k.campaign + " --scale " + k.scale + " --beds " +
         std::to_string(k.beds) + " --campaigns 300 --json " + kTableDir + k.campaign + "." + k.scale + ".K" +
         std::to_string(k.beds) + ".json (tests/truth/regenerate_calibration.sh remakes every committed table), "
         "then rebuild";
}

ClaimRates RatesFor(const std::string& claim_id, const std::string& part, const DesignKey& key,
                    const std::vector<CalibrationTable>& tables) {
  ClaimRates r;
  r.design = DescribeDesign(key);
  const CalibrationTable* table = nullptr;
  for (const CalibrationTable& t : tables)
    if (t.key == key) table = &t;
  if (table == nullptr) {
    std::string why;
    for (const CalibrationTable& t : tables) {
      if (t.key.definition_hash != key.definition_hash || t.key.scale != key.scale) continue;
      // The same campaign at the same scale: say what differs, so a stale table is told from none.
      if (t.key.beds != key.beds) why = "calibrated at K = " + std::to_string(t.key.beds) + ", not " + std::to_string(key.beds);
      if (t.key.beds == key.beds && t.key.bed_sd_rel != key.bed_sd_rel)
        why = "calibrated with a bed prior of " + Num(100 * t.key.bed_sd_rel, 3) + " %: stale";
      if (t.key.rules_version != key.rules_version || t.key.analysis_version != key.analysis_version) {
        why = "the calibration was made with rules " + std::to_string(t.key.rules_version) + ", analysis " +
              std::to_string(t.key.analysis_version) + ": stale";
        break;
      }
    }
    r.text = "not calibrated at this design (" + r.design + (why.empty() ? "" : "; " + why) + ")";
    r.advice = "calibrate it on the truth engine: " + CalibrateCommand(key);
    return r;
  }
  r.calibrated = true;
  r.table = table->file;
  int64_t campaigns = 0;
  for (const nlohmann::json& law : table->laws) {
    const std::string name = law.value("law", "");
    campaigns = std::max(campaigns, law.value("campaigns", int64_t{0}));
    for (const nlohmann::json& cell : law.value("cells", nlohmann::json::array())) {
      if (cell.value("claim", "") != claim_id || cell.value("part", "") != part) continue;
      const nlohmann::json truth = cell.value("true", nlohmann::json());
      if (!truth.is_boolean()) continue;
      if (truth.get<bool>()) {
        KeepWorst(r.false_differs, Estimate(cell, "differs", name));
        if (name == "paper") r.power = Estimate(cell, "holds", name);
      } else {
        KeepWorst(r.false_holds, Estimate(cell, "holds", name));
      }
    }
  }
  if (!r.false_holds && !r.false_differs && !r.power) {
    r.text = "no error rate: no law of the truth engine decides this " + std::string(part.empty() ? "claim" : "part") +
             " (" + r.design + ")";
    return r;
  }
  std::vector<std::string> said;
  if (r.false_holds) said.push_back("false holds <= " + Pct(r.false_holds->hi) + " %");
  if (r.false_differs) said.push_back("false differs <= " + Pct(r.false_differs->hi) + " %");
  if (r.power) {
    said.push_back("power " + Pct(r.power->rate) + " % [" + Pct(r.power->lo) + ", " + Pct(r.power->hi) + "]");
    r.low_power = r.power->rate < kLowPower;
  }
  std::string text;
  for (const std::string& s : said) text += (text.empty() ? "" : ", ") + s;
  r.text = text + " at this design (" + r.design + "; " + std::to_string(campaigns) + " simulated campaigns a law)";
  if (r.low_power) {
    // What would help, from what was measured: the same rule's power at the other calibrated beds
    // of this campaign and scale (more beds do not always add power: a point counts only when all
    // its beds are measured, and its error then rests on K - 1 dof).
    std::string other;
    for (const CalibrationTable& t : tables) {
      if (&t == table || t.key.definition_hash != key.definition_hash || t.key.scale != key.scale ||
          t.key.rules_version != key.rules_version || t.key.analysis_version != key.analysis_version)
        continue;
      DesignKey at = key;
      at.beds = t.key.beds;
      const ClaimRates there = RatesFor(claim_id, part, at, {t});
      if (there.power)
        other += (other.empty() ? "" : ", ") + std::string("K = ") + std::to_string(t.key.beds) + ": " +
                 Pct(there.power->rate) + " %";
    }
    r.advice = "power " + Pct(r.power->rate) + " % at this design: longer runs (a larger scale, a longer " +
               "max_duration_s) or more replicate beds (\"replicates\") may add power" +
               (other.empty() ? std::string(", not measured here") : "; measured at " + other);
  }
  return r;
}

void AttachClaimRates(std::vector<ClaimVerdict>& verdicts, const DesignKey& key,
                      const std::vector<CalibrationTable>& tables) {
  for (ClaimVerdict& v : verdicts) {
    v.rates = RatesFor(v.claim.id, "", key, tables);
    for (ClaimPart& p : v.parts) p.rates = RatesFor(v.claim.id, p.name, key, tables);
  }
}

}  // namespace sandswim
