#include "tests/bench/synthetic_campaign.h"

#include <chrono>
#include <filesystem>
#include <random>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/keys.h"
#include "server/jobs/lease_queue.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"
#include "server/store/campaigns.h"

namespace sandswim::bench {

Result<SeededCampaign> SeedTenThousandRunCampaign(const std::string& db, const std::string& data_dir, int runs_done,
                                                  const std::string& engine, bool with_claim) {
  using nlohmann::json;
  std::error_code ec;
  std::filesystem::create_directories(data_dir, ec);
  if (ec) return Status::Internal("cannot make " + data_dir + ": " + ec.message());
  auto store = Store::Open(db);
  if (!store.ok()) return store.status();
  SystemClock clock;
  LeaseQueue leases(store->get(), &clock, LeaseQueueOptions{});
  std::vector<double> omegas, amplitudes;
  for (int i = 0; i < 100; ++i) omegas.push_back(i < 50 ? -10.0 * (i + 1) : 10.0 * (i - 49));
  for (int i = 0; i < 100; ++i) amplitudes.push_back(0.005 + 0.0005 * i);
  StoredCampaign campaign;
  campaign.name = "big-10k";
  campaign.definition = {
      {"name", "big-10k"},
      {"description", "10,000 points with synthetic results (tests/bench/synthetic_campaign.h)"},
      {"scale", "smoke"},
      {"sweeps", json::array({{{"name", "Omega-A"},
                               {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -80}, {"duration_s", 2}}},
                               {"axes", json::array({{{"param", "Omega"}, {"values", omegas}},
                                                     {{"param", "A"}, {"values", amplitudes}}})},
                               {"combine", "product"}}})}};
  if (with_claim) {
    campaign.definition["claims"] = json::array(
        {{{"id", "S1"},
          {"title", "Omega < 0 rises, Omega > 0 sinks"},
          {"source", "tests/bench/synthetic_campaign.h"},
          {"paper", {{"text", "not from a paper: a benchmark's claim"}}},
          {"rule", {{"kind", "sign"}, {"sweeps", {"Omega-A"}}, {"expect", "against_Omega"}}}}});
  }
  if (Status s = PutCampaign(**store, campaign); !s.ok()) return s;
  SubmitRequest request;
  request.campaign = "big-10k";
  request.scale = "smoke";
  auto submitted = Submit(**store, request, engine, clock.Now());
  if (!submitted.ok()) return submitted.status();
  std::mt19937 rng(10000);
  std::normal_distribution<double> noise(0.0, 1.0);
  const auto start = std::chrono::steady_clock::now();
  SeededCampaign seeded;
  seeded.runs = 10000;
  while (seeded.runs_done < runs_done) {
    auto grant = leases.Lease(api::LeaseRequest{"bench:1", "bench", 1});
    if (!grant.ok()) return grant.status();
    if (!grant->has_value()) return Status::Internal("nothing left to lease after " + std::to_string(seeded.runs_done));
    const api::LeaseGrant& g = **grant;
    api::Completion c;
    c.ok = true;
    c.execution.engine_version = engine;
    if (g.kind == api::JobKind::kBed) {
      const std::string restart = "a synthetic bed";
      if (Status s = leases.PutBedRestart(g.token, restart, Sha256Hex(restart), data_dir); !s.ok()) return s;
      c.bed_result = api::BedResult{6682, -0.011, 0.329, true, 1e-4, Sha256Hex(restart), 15, 0.68, 0.28, 0.55, 154};
    } else {
      api::RunResult r;
      r.uz = 0.05 + 0.004 * noise(rng);
      r.uz_stderr = 0.004;
      r.uz_ci95 = 3.18 * 0.004;
      r.uz_blocks = 4;
      r.block_s = 1.0 / 3;
      r.block_kind = "period";
      r.conclusive = true;
      r.stop_reason = "target";
      r.dz = 0.1;
      c.result = r;
      api::Trajectory t;
      for (int i = 0; i < 50; ++i) {
        t.t.push_back(0.04 * i);
        t.x.push_back(0);
        t.y.push_back(0);
        t.z.push_back(*r.uz * 0.04 * i);
      }
      c.trajectory = t;
      ++seeded.runs_done;
    }
    auto reply = leases.Complete(g.token, c);
    if (!reply.ok()) return reply.status();
  }
  seeded.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return seeded;
}

}  // namespace sandswim::bench
