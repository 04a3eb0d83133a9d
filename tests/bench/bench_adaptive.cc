// bench_adaptive: claim-driven rounds (core/adaptive.h) against the fixed designs, on the truth
// engine (tests/truth/adaptive_campaign.h), paper-58 at smoke: per design, under the `paper` law
// (F1-F5 true) the simulated time and core-hours a campaign spends and how often each claim and
// all of F1-F5 are decided; under every law, each claim's false holds (holds where the law makes
// the claim false: the worst law) and false differs (differs where it makes it true), with the
// upper 95 % Wilson bound. Designs: "fixed1" (the campaign's default: one bed), "fixed3" (three
// replicate beds) and "adaptive" (round 1 = fixed1, then rounds planned by PlanNextRound within
// --budget core-hours, at most --max-rounds rounds, verdicts frozen at the look that decides them).
//
//   bench_adaptive [--campaigns N] [--laws a,b] [--designs fixed1,fixed3,adaptive] [--threads T]
//                  [--budget CORE_H] [--max-rounds R] [--draws D] [--world W] [--show W]
//
// --show W prints one adaptive campaign of world W under each law: its rounds, what each added
// and why, and the claims' states after each. A program to run on demand: it asserts nothing.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/claim_rates.h"
#include "core/text.h"
#include "tests/truth/adaptive_campaign.h"

namespace sandswim::truth {
namespace {

const std::vector<std::string> kClaims = {"F1", "F2", "F3", "F4", "F5"};

struct Tally {
  int64_t campaigns = 0, all_decided = 0;
  double sim_s = 0, core_h = 0, rounds = 0;
  std::map<std::string, int64_t> holds, differs;
};

struct DesignRun {
  std::string name;
  std::map<std::string, Tally> by_law;
};

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream in(s);
  for (std::string x; std::getline(in, x, ',');)
    if (!x.empty()) out.push_back(x);
  return out;
}

std::string Pct(int64_t k, int64_t n) {
  if (n == 0) return "–";
  auto [lo, hi] = WilsonInterval(k, n);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f (≤ %.1f)", 100.0 * static_cast<double>(k) / static_cast<double>(n), 100 * hi);
  return buf;
}

void Record(Tally& t, const std::map<std::string, Verdict>& verdicts, double sim_s, double core_h, int rounds) {
  ++t.campaigns;
  t.sim_s += sim_s;
  t.core_h += core_h;
  t.rounds += rounds;
  bool all = true;
  for (const std::string& id : kClaims) {
    auto it = verdicts.find(id);
    const Verdict v = it == verdicts.end() ? Verdict::kInconclusive : it->second;
    if (v == Verdict::kHolds) ++t.holds[id];
    if (v == Verdict::kDiffers) ++t.differs[id];
    all = all && v != Verdict::kInconclusive;
  }
  if (all) ++t.all_decided;
}

int Main(int argc, char** argv) {
  int64_t campaigns = 200;
  int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  double budget = 30;
  uint64_t world = 1;
  std::optional<uint64_t> show;
  AdaptiveOptions options;
  std::vector<std::string> laws, designs = {"fixed1", "fixed3", "adaptive"};
  for (const Law& l : AllLaws()) laws.push_back(l.name);
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> const char* {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--campaigns") campaigns = std::atoll(value());
    else if (a == "--threads") threads = std::max(1, std::atoi(value()));
    else if (a == "--budget") budget = std::atof(value());
    else if (a == "--max-rounds") options.max_rounds = std::atoi(value());
    else if (a == "--draws") options.draws = std::atoi(value());
    else if (a == "--world") world = std::strtoull(value(), nullptr, 10);
    else if (a == "--show") show = std::strtoull(value(), nullptr, 10);
    else if (a == "--laws") laws = Split(value());
    else if (a == "--designs") designs = Split(value());
    else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  const Noise noise;
  Design d1;
  d1.beds = 1;
  Design d3;
  d3.beds = 3;
  Result<Calibrator> cal1 = Calibrator::Make(d1), cal3 = Calibrator::Make(d3);
  if (!cal1.ok() || !cal3.ok()) {
    std::fprintf(stderr, "%s\n", (cal1.ok() ? cal3.status() : cal1.status()).ToString().c_str());
    return 1;
  }
  AdaptiveCost cost;
  cost.scale = &cal1->scale();
  const AdaptiveRound first = FirstRound(DeclaredSweeps(*cal1), cost);
  if (Status s = ValidateAdaptiveBudget(budget, first); !s.ok()) {
    std::fprintf(stderr, "%s\n", s.ToString().c_str());
    return 2;
  }
  if (show) {
    for (const std::string& name : laws) {
      const Law* law = FindLaw(name);
      if (!law) continue;
      AdaptiveOutcome o = SimulateAdaptive(*cal1, *law, noise, *show, budget, options);
      std::printf("\n## law %s, world %llu: %.1f s simulated, %.2f core-h spent (planned at most %.2f), %d runs, %d beds\n",
                  name.c_str(), static_cast<unsigned long long>(*show), o.sim_s, o.core_h, o.planned_core_h, o.runs, o.beds);
      double planned = 0;
      for (const AdaptiveRound& r : o.rounds) {
        std::printf("- %s\n", DescribeRound(r, budget - planned).c_str());
        for (const AdaptiveAction& a : r.considered)
          std::printf("    considered: %s (gain %.2f, %.2f core-h)\n", a.reason.c_str(), a.gain, a.core_h);
        planned += r.stop ? 0 : r.core_h;
        for (const auto& [id, round] : o.decided_at)
          if (round == r.round && !r.stop) std::printf("    %s decided after it: %s\n", id.c_str(), VerdictName(o.frozen[id]));
      }
      for (const ClaimVerdict& v : o.last)
        if (!o.frozen.count(v.claim.id)) {
          std::printf("  %s open at the last look: %s\n", v.claim.id.c_str(), v.reason.c_str());
          for (const ClaimPart& p : v.parts)
            std::printf("    %s: %s: %s\n", p.name.c_str(), VerdictName(p.verdict), p.reason.substr(0, 300).c_str());
        }
    }
    return 0;
  }
  std::vector<DesignRun> results;
  for (const std::string& design : designs) {
    DesignRun dr;
    dr.name = design;
    for (const std::string& name : laws) {
      const Law* law = FindLaw(name);
      if (!law) {
        std::fprintf(stderr, "unknown law %s\n", name.c_str());
        return 2;
      }
      std::atomic<int64_t> next{0};
      std::mutex mu;
      Tally total;
      const auto t0 = std::chrono::steady_clock::now();
      auto work = [&] {
        for (int64_t i; (i = next++) < campaigns;) {
          const uint64_t w = world + static_cast<uint64_t>(i);
          std::map<std::string, Verdict> v;
          double sim = 0, core_h = 0;
          int rounds = 1;
          if (design == "adaptive") {
            AdaptiveOutcome o = SimulateAdaptive(*cal1, *law, noise, w, budget, options);
            v = o.frozen;
            sim = o.sim_s;
            core_h = o.core_h;
            rounds = static_cast<int>(o.rounds.size()) - 1;
          } else {
            const Calibrator& cal = design == "fixed3" ? *cal3 : *cal1;
            SimCampaign c = cal.Simulate(*law, noise, w);
            for (const ClaimVerdict& cv : c.verdicts) v[cv.claim.id] = cv.verdict;
            for (const SimRun& r : c.runs) sim += r.simulated_s;
            core_h = SpentCoreHours(c, cost);
          }
          std::lock_guard<std::mutex> lock(mu);
          Record(total, v, sim, core_h, rounds);
        }
      };
      std::vector<std::thread> pool;
      for (int t = 1; t < threads; ++t) pool.emplace_back(work);
      work();
      for (std::thread& t : pool) t.join();
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::fprintf(stderr, "%s %s: %lld campaigns in %.0f s\n", design.c_str(), name.c_str(),
                   static_cast<long long>(total.campaigns), wall);
      dr.by_law[name] = total;
    }
    results.push_back(std::move(dr));
  }
  std::printf("paper-58 at smoke on the truth engine, %lld campaigns a law and design; adaptive: budget %.1f core-h, "
              "at most %d rounds, %d draws a candidate; core-h at %.2g s a particle-step\n\n",
              static_cast<long long>(campaigns), budget, options.max_rounds, options.draws,
              cost.run_rate.s_per_unit);
  std::printf("Under `paper` (F1-F5 true):\n\n| design | simulated s / campaign | core-h / campaign | rounds | F1 | F2 | F3 | F4 | F5 "
              "decided %% | all F1-F5 decided %% |\n|---|---:|---:|---:|---|---|---|---|---|---|\n");
  for (const DesignRun& dr : results) {
    auto it = dr.by_law.find("paper");
    if (it == dr.by_law.end()) continue;
    const Tally& t = it->second;
    const double n = static_cast<double>(std::max<int64_t>(1, t.campaigns));
    std::printf("| %s | %.1f | %.2f | %.2f |", dr.name.c_str(), t.sim_s / n, t.core_h / n, t.rounds / n);
    for (const std::string& id : kClaims) {
      const int64_t dec = (t.holds.count(id) ? t.holds.at(id) : 0) + (t.differs.count(id) ? t.differs.at(id) : 0);
      std::printf(" %.1f (holds %.1f) |", 100.0 * static_cast<double>(dec) / n,
                  100.0 * static_cast<double>(t.holds.count(id) ? t.holds.at(id) : 0) / n);
    }
    std::printf(" %s |\n", Pct(t.all_decided, t.campaigns).c_str());
  }
  std::printf("\nFalse holds (the worst law that makes the claim false) and false differs (the worst law that makes it "
              "true), %% (upper 95 %% bound):\n\n| design | claim | false holds | law | false differs | law |\n"
              "|---|---|---|---|---|---|\n");
  for (const DesignRun& dr : results) {
    for (const std::string& id : kClaims) {
      int64_t fh = -1, fhn = 0, fd = -1, fdn = 0;
      std::string fh_law = "–", fd_law = "–";
      for (const auto& [name, t] : dr.by_law) {
        const Law* law = FindLaw(name);
        std::optional<bool> truth = TruthOf(*law, id, "");
        if (!truth) continue;
        const int64_t h = t.holds.count(id) ? t.holds.at(id) : 0, d = t.differs.count(id) ? t.differs.at(id) : 0;
        if (!*truth && h > fh) fh = h, fhn = t.campaigns, fh_law = name;
        if (*truth && d > fd) fd = d, fdn = t.campaigns, fd_law = name;
      }
      std::printf("| %s | %s | %s | %s | %s | %s |\n", dr.name.c_str(), id.c_str(), fh >= 0 ? Pct(fh, fhn).c_str() : "–",
                  fh_law.c_str(), fd >= 0 ? Pct(fd, fdn).c_str() : "–", fd_law.c_str());
    }
  }
  return 0;
}

}  // namespace
}  // namespace sandswim::truth

int main(int argc, char** argv) { return sandswim::truth::Main(argc, argv); }
