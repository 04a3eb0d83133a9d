// bench_drift_alarms: the nightly drift report's false alarms and power on the truth engine
// (tests/truth/calibration.h MeasureDriftAlarms), in process through the daemon's own
// CompareWithPrevious and core/drift.h. Two nights of one campaign on the same beds: under one law
// (nothing changed: every flag is a false alarm), and with the second night's U_z times a factor
// (the power to see that change). Per run, per point over its beds, and per campaign (some point
// at 5 % per point; the campaign's Holm verdict at family-wise 5 %); rule 1 (a normal quantile per
// run) beside the current rule on the same runs.
//
//   bench_drift_alarms [--campaign NAME] [--scale S] [--beds 1,3] [--campaigns N] [--changes 1.1,1.2,1.34]
//                      [--power-campaigns M] [--law paper] [--threads T] [--world W]
//
// Prints a markdown table with 95 % Wilson intervals, and the counts core/drift.cc's kMeasured
// commits (the rates a drift report quotes).
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/api.h"
#include "core/claim_rates.h"
#include "core/drift.h"
#include "tests/truth/calibration.h"

namespace sandswim::truth {
namespace {

std::string Rate(int64_t k, int64_t n) {
  if (n == 0) return "–";
  auto [lo, hi] = WilsonInterval(k, n);
  char buf[96];
  std::snprintf(buf, sizeof buf, "%.1f [%.1f, %.1f] (%lld/%lld)", 100.0 * static_cast<double>(k) / static_cast<double>(n),
                100 * lo, 100 * hi, static_cast<long long>(k), static_cast<long long>(n));
  return buf;
}

std::vector<double> Numbers(const std::string& list) {
  std::vector<double> out;
  std::stringstream ss(list);
  for (std::string v; std::getline(ss, v, ',');)
    if (!v.empty()) out.push_back(std::atof(v.c_str()));
  return out;
}

int Main(int argc, char** argv) {
  std::string campaign = "paper-58", scale = "smoke", law_name = "paper";
  std::vector<double> beds = {1, 3}, changes = {1.1, 1.2, 1.34};
  int64_t campaigns = 300, power_campaigns = 100;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  uint64_t world = 2000001;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--campaign") {
      campaign = value();
    } else if (a == "--scale") {
      scale = value();
    } else if (a == "--beds") {
      beds = Numbers(value());
    } else if (a == "--campaigns") {
      campaigns = std::atoll(value());
    } else if (a == "--changes") {
      changes = Numbers(value());
    } else if (a == "--power-campaigns") {
      power_campaigns = std::atoll(value());
    } else if (a == "--law") {
      law_name = value();
    } else if (a == "--threads") {
      threads = std::atoi(value());
    } else if (a == "--world") {
      world = std::strtoull(value(), nullptr, 10);
    } else {
      std::fprintf(stderr,
                   "usage: bench_drift_alarms [--campaign NAME] [--scale S] [--beds 1,3] [--campaigns N] "
                   "[--changes 1.1,1.2,1.34] [--power-campaigns M] [--law paper] [--threads T] [--world W]\n");
      return 2;
    }
  }
  const Law* law = FindLaw(law_name);
  if (law == nullptr) {
    std::fprintf(stderr, "unknown law '%s'\n", law_name.c_str());
    return 2;
  }
  const Noise noise;
  std::printf("Drift report on the truth engine: %s at %s, law %s, two nights on the same beds; drift rule %d, "
              "analysis %d\n\n",
              campaign.c_str(), scale.c_str(), law->name.c_str(), kDriftRuleVersion, api::kAnalysisVersion);
  std::printf("| K | change | night pairs | runs: rule %d | runs: rule 1 | points: rule %d | campaigns, some point "
              "(5 %% each) | campaigns, Holm (family-wise 5 %%) | campaigns, some run: rule 1 |\n",
              kDriftRuleVersion, kDriftRuleVersion);
  std::printf("| ---: | ---: | ---: | --- | --- | --- | --- | --- | --- |\n");
  std::vector<std::string> committed;
  for (double k : beds) {
    Design design;
    design.campaign = campaign;
    design.scale = scale;
    design.beds = static_cast<int>(k);
    Result<Calibrator> cal = Calibrator::Make(design);
    if (!cal.ok()) {
      std::fprintf(stderr, "%s\n", cal.status().ToString().c_str());
      return 1;
    }
    std::vector<double> factors = {1};
    factors.insert(factors.end(), changes.begin(), changes.end());
    for (double change : factors) {
      const int64_t n = change == 1 ? campaigns : power_campaigns;
      if (n <= 0) continue;
      const auto start = std::chrono::steady_clock::now();
      const DriftAlarms d = MeasureDriftAlarms(*cal, *law, noise, n, world, threads, change);
      const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      std::fprintf(stderr, "K = %d, change x%.2f: %lld night pairs in %.1f s\n", design.beds, change,
                   static_cast<long long>(n), s);
      char head[96];
      if (change == 1) {
        std::snprintf(head, sizeof head, "| %d | none | %lld ", design.beds, static_cast<long long>(d.campaigns));
      } else {
        std::snprintf(head, sizeof head, "| %d | U_z x %.2f | %lld ", design.beds, change,
                      static_cast<long long>(d.campaigns));
      }
      std::printf("%s| %s | %s | %s | %s | %s | %s |\n", head, Rate(d.runs_drifted, d.runs_compared).c_str(),
                  Rate(d.runs_drifted_rule1, d.runs_compared).c_str(), Rate(d.points_drifted, d.points_compared).c_str(),
                  Rate(d.campaigns_any_point, d.campaigns).c_str(), Rate(d.campaigns_drifted, d.campaigns).c_str(),
                  Rate(d.campaigns_any_run_rule1, d.campaigns).c_str());
      std::fflush(stdout);
      if (change == 1) {
        char line[256];
        std::snprintf(line, sizeof line, "    {\"%s\", \"%s\", %d, %d, %d, %lld, %lld, %lld, %lld, %lld},",
                      campaign.c_str(), scale.c_str(), design.beds, kDriftRuleVersion, api::kAnalysisVersion,
                      static_cast<long long>(d.campaigns), static_cast<long long>(d.points_compared),
                      static_cast<long long>(d.points_drifted), static_cast<long long>(d.campaigns_drifted),
                      static_cast<long long>(d.campaigns_any_point));
        committed.push_back(line);
      }
    }
  }
  std::printf("\n(\"change\": the second night's U_z times that factor; none: nothing changed, every flag a false "
              "alarm. Rates in %%, 95 %% Wilson intervals, counts in brackets.)\n\ncore/drift.cc kMeasured:\n");
  for (const std::string& line : committed) std::printf("%s\n", line.c_str());
  return 0;
}

}  // namespace
}  // namespace sandswim::truth

int main(int argc, char** argv) { return sandswim::truth::Main(argc, argv); }
