// bench_claims_calibration: the error rates of the claims' rules, measured on the truth engine
// (tests/truth/truth_law.h) through the project's real analysis and claims code
// (tests/truth/calibration.h): per law, claim and claim part, the rates of holds / differs /
// inconclusive over simulated campaigns with their 95 % (Wilson) intervals; "false holds" where the
// law makes the part false, "power" and "false differs" where it is true. Then the coverage of the
// runs' 95 % intervals (all, stopped early at a precision target, not), the simulated time of the
// design, and the nightly drift report's false alarms (two nights of one law on the same beds).
//
//   bench_claims_calibration [--campaign NAME] [--scale S] [--campaigns N] [--beds K] [--duration-multiplier M] [--no-precision] [--no-follow]
//                            [--laws a,b,...] [--threads T] [--world W] [--drift-campaigns N]
//                            [--json FILE] [--show W] [--bed-common S] [--bed-point S] [--no-transient]
//
// --show W prints one campaign of world W instead (each law's verdicts with their reasons, and
// every run's true U_z against its result): what a table's row is made of. --bed-common and
// --bed-point change the bed effect's two relative standard deviations (0.10 and 0.15),
// --no-transient removes the start-up transient: how the rates depend on the noise model.
//
// Defaults: 1,000 campaigns per law (rates within +-3.1 %; 2,500 for +-2 %), the campaign's
// design (paper-58 at smoke, one bed), every law, all cores. A program to run on demand: it
// asserts nothing.
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/trajectory.h"
#include "tests/truth/calibration.h"

namespace sandswim::truth {
namespace {

int Main(int argc, char** argv) {
  Design design;
  int64_t campaigns = 1000, drift_campaigns = 300;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  uint64_t world = 1;
  std::string json_file, law_list;
  std::optional<uint64_t> show;
  Noise noise;
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
      design.campaign = value();
    } else if (a == "--scale") {
      design.scale = value();
    } else if (a == "--campaigns") {
      campaigns = std::atoll(value());
    } else if (a == "--beds") {
      design.beds = std::atoi(value());
    } else if (a == "--duration-multiplier") {
      design.duration_multiplier = std::atof(value());
    } else if (a == "--no-precision") {
      design.precision = false;
    } else if (a == "--no-follow") {
      design.follow = false;
    } else if (a == "--laws") {
      law_list = value();
    } else if (a == "--threads") {
      threads = std::atoi(value());
    } else if (a == "--world") {
      world = std::strtoull(value(), nullptr, 10);
    } else if (a == "--drift-campaigns") {
      drift_campaigns = std::atoll(value());
    } else if (a == "--bed-common") {
      noise.bed_common = std::atof(value());
    } else if (a == "--bed-point") {
      noise.bed_point = std::atof(value());
    } else if (a == "--no-transient") {
      noise.transient_v0 = 0;
    } else if (a == "--show") {
      show = std::strtoull(value(), nullptr, 10);
    } else if (a == "--json") {
      json_file = value();
    } else {
      std::fprintf(stderr,
                   "usage: bench_claims_calibration [--campaign NAME] [--scale S] [--campaigns N] [--beds K] [--duration-multiplier M] "
                   "[--no-precision] [--no-follow] [--laws a,b] [--threads T] [--world W] [--drift-campaigns N] [--json FILE] "
                   "[--show W] [--bed-common S] [--bed-point S] [--no-transient]\n");
      return 2;
    }
  }
  Result<Calibrator> cal = Calibrator::Make(design);
  if (!cal.ok()) {
    std::fprintf(stderr, "%s\n", cal.status().ToString().c_str());
    return 1;
  }
  std::vector<const Law*> laws;
  if (law_list.empty()) {
    for (const Law& l : AllLaws()) laws.push_back(&l);
  } else {
    std::stringstream ss(law_list);
    for (std::string name; std::getline(ss, name, ',');) {
      const Law* l = FindLaw(name);
      if (l == nullptr) {
        std::fprintf(stderr, "unknown law '%s'\n", name.c_str());
        return 2;
      }
      laws.push_back(l);
    }
  }
  if (show) {
    for (const Law* law : laws) {
      const SimCampaign c = cal->Simulate(*law, noise, *show);
      std::printf("## law %s, world %llu\n\n", law->name.c_str(), static_cast<unsigned long long>(*show));
      for (const ClaimVerdict& v : c.verdicts) {
        std::printf("%s %s: %s\n", v.claim.id.c_str(), VerdictName(v.verdict), v.reason.c_str());
        for (const ClaimPart& p : v.parts)
          std::printf("  [%s] %s: %s\n", VerdictName(p.verdict), p.name.c_str(), p.reason.c_str());
      }
      std::printf("\n");
      for (const SimRun& r : c.runs) {
        std::printf("%s bed %d: true %.4f m/s, %s, stop %s at %.3f of %.3f s\n", PointToJson(r.point).dump().c_str(),
                    r.replicate, r.true_uz, r.result ? DescribeUz(*r.result).c_str() : r.failure.c_str(),
                    r.stop_reason.c_str(), r.simulated_s, r.planned_s);
      }
      std::printf("\n");
    }
    return 0;
  }
  std::printf("%zu runs per campaign on %zu bed(s); planned simulated time %.1f s per campaign; %d thread(s)\n\n",
              cal->plan().runs.size(), cal->plan().beds.size(), cal->PlannedSimSeconds(), threads);
  std::vector<LawTally> tallies;
  for (const Law* law : laws) {
    tallies.push_back(RunLaw(*cal, *law, noise, campaigns, world, threads));
    std::fprintf(stderr, "%s: %lld campaigns in %.1f s\n", law->name.c_str(), static_cast<long long>(campaigns),
                 tallies.back().seconds);
  }
  std::printf("%s\n", CalibrationMarkdown(tallies, design).c_str());
  nlohmann::json j = CalibrationJson(tallies, *cal, noise);
  if (drift_campaigns > 0) {
    const DriftAlarms d = MeasureDriftAlarms(*cal, *FindLaw("paper"), noise, drift_campaigns, world + 1000000, threads);
    auto pct = [](int64_t k, int64_t n) { return n ? 100.0 * static_cast<double>(k) / static_cast<double>(n) : 0.0; };
    auto [lo, hi] = WilsonInterval(d.runs_drifted, d.runs_compared);
    std::printf(
        "Drift report, law paper, two nights on the same beds (%lld campaigns): %lld of %lld runs flagged "
        "drifted = %.1f %% [%.1f, %.1f] per run",
        static_cast<long long>(drift_campaigns), static_cast<long long>(d.runs_drifted),
        static_cast<long long>(d.runs_compared), pct(d.runs_drifted, d.runs_compared), 100 * lo, 100 * hi);
    if (d.points_compared > 0)
      std::printf("; points over their beds: %lld of %lld = %.1f %%", static_cast<long long>(d.points_drifted),
                  static_cast<long long>(d.points_compared), pct(d.points_drifted, d.points_compared));
    std::printf("\n");
    j["drift"] = {{"law", "paper"},
                  {"campaigns", drift_campaigns},
                  {"runs_compared", d.runs_compared},
                  {"runs_drifted", d.runs_drifted},
                  {"points_compared", d.points_compared},
                  {"points_drifted", d.points_drifted}};
  }
  if (!json_file.empty()) {
    std::ofstream(json_file) << j.dump(1) << "\n";
    std::printf("wrote %s\n", json_file.c_str());
  }
  return 0;
}

}  // namespace
}  // namespace sandswim::truth

int main(int argc, char** argv) { return sandswim::truth::Main(argc, argv); }
