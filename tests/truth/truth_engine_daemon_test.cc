// The truth engine through the REAL service: sandswimd, a sandswim-worker whose engine is
// sandswim-truth-engine (a stand-in whose SO follows a known law, tests/truth/truth_law.h), the
// worker's analysis and the daemon's claims. paper-58 at smoke, one bed, law and world set through
// the engine's environment; the U_z of every run and every claim's verdict, part by part, must be
// those the in-process calibration (tests/truth/calibration.h) gives for the same law and world:
// the same analysis on the same samples, and the same assembly of the claims' input.
//
// The engine writes its whole run at once, before the worker's first heartbeat, so no run is
// ended early by the precision target: the in-process side runs with the planned durations and
// targets and no worker following (Design::follow = false).
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "core/sweep.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"
#include "tests/truth/calibration.h"

namespace sandswim::truth {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

// The result row of `run`'s point and bed among the campaign run's rows (nullptr: none).
const json* RowOf(const json& rows, const SimRun& run) {
  const json point = PointToJson(run.point);
  for (const json& row : rows) {
    if (row.value("replicate", -1) != run.replicate) continue;
    bool same = true;
    for (auto it = point.begin(); it != point.end() && same; ++it) {
      if (it.key() == "duration_s") continue;
      same = row.contains(it.key()) && row[it.key()] == it.value();
    }
    if (same) return &row;
  }
  return nullptr;
}

TEST(TruthEngineDaemonTest, Paper58AtSmokeMatchesTheInProcessCalibration) {
  const std::string dir = testing::CacheDir() + "/truth-engine/paper-58";
  fs::remove_all(dir);
  const uint64_t world = 17;
  setenv("SANDSWIM_TRUTH_LAW", "paper", 1);
  setenv("SANDSWIM_TRUTH_SEED", std::to_string(world).c_str(), 1);
  unsetenv("SANDSWIM_TRUTH_PACE");

  testing::Daemon daemon(dir + "/daemon");
  int status = 0;
  const json submitted = daemon.Post("/api/v1/sweeps", {{"campaign", "paper-58"}, {"scale", "smoke"}}, &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t campaign_run = submitted["id"].get<int64_t>();
  auto worker = testing::StartWorker(daemon, dir + "/worker", 2,
                                     {"--launcher", "direct", "--engine", SANDSWIM_TRUTH_ENGINE_PATH});
  for (const json& sweep : submitted["sweeps"]) {
    const json s = daemon.WaitForSweep(sweep.get<int64_t>(), 600);
    ASSERT_EQ(s["counts"].value("failed", 0), 0) << s.dump() << "\n" << worker->Output();
  }
  const json results = daemon.Get("/api/v1/campaign-runs/" + std::to_string(campaign_run) + "/results");
  const json claims = daemon.Get("/api/v1/campaign-runs/" + std::to_string(campaign_run) + "/claims");
  worker->Stop();

  Design design;
  design.follow = false;
  Result<Calibrator> cal = Calibrator::Make(design);
  ASSERT_TRUE(cal.ok()) << cal.status().ToString();
  const SimCampaign sim = cal->Simulate(*FindLaw("paper"), Noise(), world);

  // Every run: the same U_z (to the last bit: the same samples, the same analysis).
  ASSERT_EQ(results["results"].size(), sim.runs.size()) << results.dump();
  int compared = 0;
  for (const SimRun& run : sim.runs) {
    const json* row = RowOf(results["results"], run);
    ASSERT_NE(row, nullptr) << PointToJson(run.point).dump();
    ASSERT_TRUE(run.result.has_value());
    EXPECT_EQ((*row)["stop_reason"], run.result->stop_reason) << PointToJson(run.point).dump();
    EXPECT_EQ((*row)["conclusive"], run.result->conclusive) << PointToJson(run.point).dump();
    EXPECT_EQ((*row)["Uz_blocks"], run.result->uz_blocks) << PointToJson(run.point).dump();
    ASSERT_EQ((*row)["Uz"].is_null(), !run.result->uz.has_value()) << PointToJson(run.point).dump();
    if (run.result->uz) {
      EXPECT_DOUBLE_EQ((*row)["Uz"].get<double>(), *run.result->uz) << PointToJson(run.point).dump();
      ++compared;
    }
    EXPECT_NE((*row).value("engine_version", "").find("sandswim-truth-engine"), std::string::npos);
  }
  EXPECT_GT(compared, 0);

  // The daemon finds the design the calibration was made at (paper-58 at smoke, one bed, these
  // rules and analysis) and quotes its committed rates, those of no other design.
  EXPECT_EQ(claims["design"], DesignKeyToJson(cal->Key())) << claims["design"].dump();
  // Every claim and part: the same verdict.
  ASSERT_EQ(claims["claims"].size(), sim.verdicts.size()) << claims.dump();
  for (size_t i = 0; i < sim.verdicts.size(); ++i) {
    const json& got = claims["claims"][i];
    const ClaimVerdict& want = sim.verdicts[i];
    EXPECT_EQ(got["id"], want.claim.id);
    EXPECT_EQ(got["verdict"], VerdictName(want.verdict)) << want.claim.id << ": " << got["reason"];
    const ClaimRates rates = RatesFor(want.claim.id, "", cal->Key(), CommittedCalibrations());
    EXPECT_TRUE(rates.calibrated) << rates.text;
    EXPECT_EQ(got["rates"]["text"], rates.text) << want.claim.id;
    ASSERT_EQ(got["parts"].size(), want.parts.size()) << want.claim.id;
    for (size_t p = 0; p < want.parts.size(); ++p) {
      EXPECT_EQ(got["parts"][p]["name"], want.parts[p].name);
      EXPECT_EQ(got["parts"][p]["verdict"], VerdictName(want.parts[p].verdict))
          << want.claim.id << " " << want.parts[p].name << ": daemon " << got["parts"][p]["reason"]
          << "; in process " << want.parts[p].reason;
    }
  }
}

// A campaign of one's own through the real daemon and worker: put -> run -> results ->
// edit -> run again -> the drift report of the second run says the definition changed, and
// compares nothing with a run of the other definition.
TEST(TruthEngineDaemonTest, AnOwnCampaignEditedSaysItsDefinitionChanged) {
  const std::string dir = testing::CacheDir() + "/truth-engine/own-campaign";
  fs::remove_all(dir);
  setenv("SANDSWIM_TRUTH_LAW", "paper", 1);
  setenv("SANDSWIM_TRUTH_SEED", "5", 1);
  unsetenv("SANDSWIM_TRUTH_PACE");
  auto definition = [](double amplitude) {
    return json{{"description", "the sign of U_z at +-80 rad/s"},
                {"scale", "smoke"},
                {"sweeps",
                 {{{"name", "signs"},
                   {"base", {{"mode", "oscillatory"}, {"A", amplitude}, {"f", 3}, {"Omega", -80}, {"duration_s", 1}}},
                   {"axes", {{{"param", "Omega"}, {"values", {-80, 80}}}}}}}}};
  };
  testing::Daemon daemon(dir + "/daemon", {"--scheduler-tick", "1"});
  auto worker = testing::StartWorker(daemon, dir + "/worker", 2,
                                     {"--launcher", "direct", "--engine", SANDSWIM_TRUTH_ENGINE_PATH});
  // Runs the campaign and waits for its drift report.
  auto run_and_report = [&](int expect_version) {
    int status = 0;
    const json submitted = daemon.Post("/api/v1/campaigns/mine/runs", json::object(), &status);
    EXPECT_EQ(status, 201) << submitted.dump();
    const int64_t id = submitted.value("id", int64_t{0});
    for (const json& sweep : submitted["sweeps"]) {
      const json s = daemon.WaitForSweep(sweep.get<int64_t>(), 300);
      EXPECT_EQ(s["counts"].value("failed", 0), 0) << s.dump() << "\n" << worker->Output();
    }
    const json results = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id) + "/results");
    EXPECT_EQ(results["results"].size(), 2u) << results.dump();
    json info;
    for (int i = 0; i < 120; ++i) {
      info = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id));
      if (info["last_drift"].is_object() && info["last_drift"]["campaign_run_id"] == id) break;
      usleep(250 * 1000);
    }
    EXPECT_EQ(info["campaign_version"], expect_version) << info.dump();
    EXPECT_EQ(info["last_drift"]["campaign_run_id"], id) << info.dump();
    return info["last_drift"];
  };

  int status = 0;
  json put = daemon.Put("/api/v1/campaigns/mine", definition(0.03), &status);
  ASSERT_EQ(status, 201) << put.dump();
  const json first = run_and_report(1);
  EXPECT_EQ(first["definition_changed"], nullptr) << first.dump();

  put = daemon.Put("/api/v1/campaigns/mine", definition(0.02), &status);
  ASSERT_EQ(status, 200) << put.dump();
  EXPECT_EQ(put["version"], 2);
  const json second = run_and_report(2);
  worker->Stop();
  EXPECT_EQ(second["definition_changed"]["from_version"], 1) << second.dump();
  EXPECT_EQ(second["definition_changed"]["to_version"], 2) << second.dump();
  EXPECT_EQ(second["previous_campaign_run_id"], nullptr) << second.dump();
  EXPECT_NE(second["summary"].get<std::string>().find("definition changed (version 1 -> 2)"), std::string::npos)
      << second["summary"];
  const json campaign = daemon.Get("/api/v1/campaigns/mine");
  EXPECT_EQ(campaign["versions"].size(), 2u) << campaign.dump();
  EXPECT_EQ(campaign["runs"].size(), 2u) << campaign.dump();
}

}  // namespace
}  // namespace sandswim::truth
