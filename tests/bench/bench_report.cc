// bench_report: how long a finished campaign's claims and its full HTML
// report take. paper-58 at smoke on K replicate beds (default 3: 174 runs) is submitted to an
// in-process store and every job is completed with SYNTHETIC results (eq. 8 shaped rates with
// noise, 2 s trajectories of 400 samples: for this measurement only, no physics); then it times
//   claims        CheckClaims (every sweep analysed, every claim evaluated), 5 times;
//   report cold   CampaignReport with an empty figure cache: every figure drawn by sandswim-render
//                 in a process of its own, as the daemon does;
//   report warm   the same again, every figure read from the cache.
//
// Usage: bench_report [--replicates K] [--renderer PATH] [--dir DIR]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>

#include "core/keys.h"
#include "core/sweep.h"
#include "platform/clock.h"
#include "platform/subprocess.h"
#include "server/analysis/claim_check.h"
#include "server/jobs/lease_queue.h"
#include "server/analysis/plot_renderer.h"
#include "server/analysis/report.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"
#include "server/store/campaigns.h"

namespace {

using namespace sandswim;
using Steady = std::chrono::steady_clock;

[[noreturn]] void Die(const std::string& what) {
  std::fprintf(stderr, "bench_report: %s\n", what.c_str());
  std::exit(1);
}

double Seconds(Steady::time_point since) { return std::chrono::duration<double>(Steady::now() - since).count(); }

}  // namespace

int main(int argc, char** argv) {
  int replicates = 3;
  std::string renderer_path = std::filesystem::path(argv[0]).parent_path() / "sandswim-render";
  std::filesystem::path dir = std::filesystem::temp_directory_path() / "sandswim-bench-report";
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string flag = argv[i];
    if (flag == "--replicates")
      replicates = std::atoi(argv[i + 1]);
    else if (flag == "--renderer")
      renderer_path = argv[i + 1];
    else if (flag == "--dir")
      dir = argv[i + 1];
    else
      Die("unknown flag " + flag + "; usage: bench_report [--replicates K] [--renderer PATH] [--dir DIR]");
  }
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string engine = "LIGGGHTS (SYNTHETIC, bench_report)";

  auto store = Store::Open((dir / "bench.db").string());
  if (!store.ok()) Die(store.status().ToString());
  FakeClock clock;
  clock.Set(1.7e9);
  LeaseQueue leases(store->get(), &clock, LeaseQueueOptions{});
  auto definition = BuiltinCampaignDefinition("paper-58");
  if (!definition.ok()) Die(definition.status().ToString());
  (*definition)["replicates"] = replicates;
  StoredCampaign campaign;
  campaign.name = "paper-58";
  campaign.definition = *definition;
  if (!PutCampaign(**store, campaign).ok()) Die("cannot store the campaign");
  SubmitRequest request;
  request.campaign = "paper-58";
  request.scale = "smoke";
  auto submitted = Submit(**store, request, engine, clock.Now());
  if (!submitted.ok()) Die(submitted.status().ToString());
  const int64_t campaign_run = *submitted->campaign_run_id;

  std::mt19937 rng(58);
  std::normal_distribution<double> noise(0.0, 1.0);
  int runs = 0, beds = 0;
  while (true) {
    auto grant = leases.Lease(api::LeaseRequest{"bench:1", "bench", 1});
    if (!grant.ok()) Die(grant.status().ToString());
    if (!grant->has_value()) break;
    const api::LeaseGrant& g = **grant;
    api::Completion c;
    c.ok = true;
    c.execution.engine_version = engine;
    if (g.kind == api::JobKind::kBed) {
      const std::string restart = "a synthetic bed " + std::to_string(g.id);
      if (!leases.PutBedRestart(g.token, restart, Sha256Hex(restart), (dir / "data").string()).ok())
        Die("cannot hand in a bed");
      c.bed_result = api::BedResult{6682, -0.011, 0.329, true, 1e-4, Sha256Hex(restart), 5, 0.68, 0.28, 0.55, 154};
      ++beds;
    } else {
      auto run = (*store)->GetRun(g.id);
      if (!run.ok()) Die(run.status().ToString());
      const Point& p = run->summary.point;
      const double w = std::fabs(p.Omega);
      const double law = p.mode != Mode::kOscillatory ? 0.01
                         : p.Omega < 0                ? 0.10 * (1 - std::exp(-0.02 * w))
                                                      : -0.05 * (1 - std::exp(-0.02 * w));
      api::RunResult r;
      r.uz = law + 0.004 * noise(rng);
      r.uz_stderr = 0.004;
      r.uz_ci95 = 3.18 * 0.004;
      r.uz_blocks = 4;
      r.block_s = 1.0 / std::max(p.f, 1.0);
      r.block_kind = "period";
      r.conclusive = true;
      r.stop_reason = "target";
      c.result = r;
      api::Trajectory t;
      for (int i = 0; i < 400; ++i) {
        const double time = 2.0 * i / 399;
        t.t.push_back(time);
        t.x.push_back(0.002 * std::sin(2 * M_PI * p.f * time));
        t.y.push_back(0);
        t.z.push_back(*r.uz * time + 0.003 * std::sin(2 * M_PI * p.f * time));
      }
      c.trajectory = t;
      ++runs;
    }
    auto reply = leases.Complete(g.token, c);
    if (!reply.ok()) Die(reply.status().ToString());
  }
  std::printf("paper-58 at smoke, %d replicate bed(s): %d beds and %d runs completed with SYNTHETIC results\n",
              replicates, beds, runs);

  Steady::time_point start = Steady::now();
  Result<CampaignRunClaims> claims = Status::Internal("not run");
  constexpr int kClaimRounds = 5;
  for (int i = 0; i < kClaimRounds; ++i) claims = CheckClaims(**store, campaign_run);
  if (!claims.ok()) Die(claims.status().ToString());
  std::printf("claims: %zu verdicts in %.3f s each (mean of %d)\n", claims->verdicts.size(),
              Seconds(start) / kClaimRounds, kClaimRounds);

  PosixSubprocesses processes;
  SubprocessRenderer renderer(&processes, renderer_path);
  FigureCache figures((dir / "data" / "figures").string(), &renderer);
  for (const char* pass : {"cold (every figure drawn by sandswim-render)", "warm (every figure from the cache)"}) {
    start = Steady::now();
    auto html = CampaignReport(**store, figures, campaign_run, clock.Now());
    if (!html.ok()) Die(html.status().ToString());
    size_t svgs = 0;
    for (size_t at = html->find("<svg"); at != std::string::npos; at = html->find("<svg", at + 1)) ++svgs;
    std::printf("report %s: %.2f s, %zu figures, %.1f MB of HTML%s\n", pass, Seconds(start), svgs, html->size() / 1e6,
                html->find("could not be made") != std::string::npos ? " (WITH PROBLEMS)" : "");
  }
  std::filesystem::remove_all(dir);
  return 0;
}
