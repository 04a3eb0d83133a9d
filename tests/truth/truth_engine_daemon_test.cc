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
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
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

// The same, as a user types it: the real CLI against the real daemon and worker. put -> run --wait
// (its results) -> edit in $EDITOR (a script) -> run --wait -> `status mine` (the campaign's last
// drift report) says the definition changed and held the second run to the second version's
// tolerance.
TEST(TruthEngineDaemonTest, AnOwnCampaignThroughTheCli) {
  const std::string dir = testing::CacheDir() + "/truth-engine/own-campaign-cli";
  fs::remove_all(dir);
  fs::create_directories(dir);
  setenv("SANDSWIM_TRUTH_LAW", "paper", 1);
  setenv("SANDSWIM_TRUTH_SEED", "6", 1);
  unsetenv("SANDSWIM_TRUTH_PACE");
  testing::Daemon daemon(dir + "/daemon", {"--scheduler-tick", "1"});
  auto worker = testing::StartWorker(daemon, dir + "/worker", 2,
                                     {"--launcher", "direct", "--engine", SANDSWIM_TRUTH_ENGINE_PATH});
  // Runs `sandswim ARGS` with `env` before it (a shell line), returns its exit code and output.
  auto cli = [&](const std::string& args, std::string* out, const std::string& env = "") {
    const std::string file = dir + "/cli.out";
    const std::string line = env + " " SANDSWIM_CLI_PATH " --server " + daemon.url() + " " + args + " >" + file +
                             " 2>&1 </dev/null";
    const int status = std::system(line.c_str());
    std::ifstream in(file);
    *out = std::string(std::istreambuf_iterator<char>(in), {});
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  std::ofstream(dir + "/mine.json") << json{{"name", "mine"},
                                            {"description", "the sign of U_z at +-80 rad/s"},
                                            {"scale", "smoke"},
                                            {"drift_tolerance_mps", 0.01},
                                            {"sweeps",
                                             {{{"name", "signs"},
                                               {"base",
                                                {{"mode", "oscillatory"},
                                                 {"A", 0.03},
                                                 {"f", 3},
                                                 {"Omega", -80},
                                                 {"duration_s", 1}}},
                                               {"axes", {{{"param", "Omega"}, {"values", {-80, 80}}}}}}}}}
                                           .dump(2);
  std::ofstream(dir + "/edit.sh") << "#!/bin/sh\nsed -i 's/\"A\": 0.03/\"A\": 0.02/; "
                                     "s/\"drift_tolerance_mps\": 0.01/\"drift_tolerance_mps\": 0.05/' \"$1\"\n";
  fs::permissions(dir + "/edit.sh", fs::perms::owner_all);

  std::string out;
  ASSERT_EQ(cli("campaign put " + dir + "/mine.json", &out), 0) << out;
  EXPECT_NE(out.find("mine: stored as version 1 (a new campaign)"), std::string::npos) << out;
  ASSERT_EQ(cli("campaign run mine --wait", &out), 0) << out << worker->Output();
  EXPECT_NE(out.find("2/2 done"), std::string::npos) << out;
  ASSERT_EQ(cli("campaign edit mine", &out, "VISUAL= EDITOR=" + dir + "/edit.sh"), 0) << out;
  EXPECT_NE(out.find("mine: stored as version 2"), std::string::npos) << out;
  ASSERT_EQ(cli("campaign run mine --wait", &out), 0) << out << worker->Output();
  // The drift report is made by the scheduler's next tick after the runs finish.
  bool reported = false;
  for (int i = 0; i < 120 && !reported; ++i) {
    reported = cli("status mine", &out) == 0 && out.find("rerun cr:2") != std::string::npos;
    if (!reported) usleep(250 * 1000);
  }
  worker->Stop();
  ASSERT_TRUE(reported) << out;
  EXPECT_NE(out.find("drifted beyond 0.05 m/s"), std::string::npos) << out;
  EXPECT_NE(out.find("definition changed (version 1 -> 2), no earlier run of this definition to compare with"),
            std::string::npos)
      << out;
}

// An adaptive campaign through the real daemon and worker on the truth engine: the
// sign of a slow rise (rotation alone), which one bed at the scale's target leaves open. Round 1 runs,
// the daemon's scheduler tick looks at the claim and plans round 2 with its reason, round 2 runs,
// and the rounds stop with a reason; a claim decided is frozen at the round whose look decided it.
TEST(TruthEngineDaemonTest, AnAdaptiveCampaignRunsInRoundsAndStopsWithAReason) {
  const std::string dir = testing::CacheDir() + "/truth-engine/adaptive";
  fs::remove_all(dir);
  setenv("SANDSWIM_TRUTH_LAW", "paper", 1);
  setenv("SANDSWIM_TRUTH_SEED", "11", 1);
  unsetenv("SANDSWIM_TRUTH_PACE");
  const json definition{
      {"description", "the sign of a slow rise, in rounds"},
      {"scale", "smoke"},
      {"sweeps",
       {{{"name", "rotation"}, {"base", {{"mode", "rotation"}, {"omega", 80}, {"axis", "x"}, {"duration_s", 2}}}}}},
      {"claims",
       {{{"id", "S1"},
         {"title", "Rotation alone rises (slowly: the truth law's 5 mm/s)"},
         {"source", "the abstract's three modes"},
         {"paper", {{"text", "the displacement in z is always upward"}}},
         {"rule", {{"kind", "sign"}, {"sweeps", {"rotation"}}, {"expect", "rise"}}}}}},
      {"adaptive", {{"budget_core_h", 20}, {"max_rounds", 3}}}};
  testing::Daemon daemon(dir + "/daemon", {"--scheduler-tick", "1"});
  int status = 0;
  const json put = daemon.Put("/api/v1/campaigns/signs", definition, &status);
  ASSERT_EQ(status, 201) << put.dump();
  const json submitted = daemon.Post("/api/v1/campaigns/signs/runs", json::object(), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t id = submitted.value("id", int64_t{0});
  auto worker = testing::StartWorker(daemon, dir + "/worker", 2,
                                     {"--launcher", "direct", "--engine", SANDSWIM_TRUTH_ENGINE_PATH});
  json info;
  for (int i = 0; i < 1200; ++i) {
    info = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id));
    const json& rounds = info["rounds"];
    if (rounds.is_array() && !rounds.empty() && rounds.back()["stop_reason"].is_string()) break;
    usleep(250 * 1000);
  }
  worker->Stop();
  const json& rounds = info["rounds"];
  ASSERT_TRUE(rounds.is_array() && !rounds.empty()) << info.dump();
  ASSERT_TRUE(rounds.back()["stop_reason"].is_string()) << info.dump(1) << "\n" << worker->Output();
  EXPECT_EQ(info["adaptive"]["budget_core_h"], 20);
  EXPECT_EQ(rounds[0]["actions"][0]["kind"], "first round");
  EXPECT_EQ(rounds[0]["actions"][0]["runs"], 1);
  ASSERT_GE(rounds.size(), 2u) << "round 1 decided the claim: pick a slower point\n" << info.dump(1);
  // Round 2: what it added, for which claim and why, at what cost.
  ASSERT_FALSE(rounds[1]["actions"].empty()) << info.dump(1);
  const json& action = rounds[1]["actions"][0];
  EXPECT_EQ(action["claim"], "S1");
  EXPECT_NE(action["reason"].get<std::string>().find("S1: "), std::string::npos) << action.dump();
  EXPECT_GT(action["runs"].get<int>(), 0);
  EXPECT_GT(rounds[1]["core_h_planned"].get<double>(), 0);
  EXPECT_EQ(rounds[0]["claims_after"][0]["verdict"], "inconclusive") << info.dump(1);
  double spent = 0;
  for (const json& r : rounds) {
    ASSERT_TRUE(r["finished_at"].is_number()) << r.dump();
    spent += r["core_h_spent"].get<double>();
    EXPECT_NEAR(r["budget_left_core_h"].get<double>(), 20 - spent, 1e-9);
  }
  EXPECT_LE(spent, 20);
  // The claim's state after the last look: decided and frozen at a round, or open with the reason.
  const json& last = rounds.back()["claims_after"][0];
  if (last["verdict"] != "inconclusive") {
    EXPECT_TRUE(last["frozen_at_round"].is_number()) << last.dump();
    EXPECT_NE(rounds.back()["stop_reason"].get<std::string>().find("decided"), std::string::npos);
  }
  // Its runs are the campaign run's results, round 2's among them (a longer run in its point's place).
  const json results = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id) + "/results");
  EXPECT_GE(results["results"].size(), 1u) << results.dump();
  // Its drift report is made once its rounds stopped, not when round 1's runs were done: it
  // counts the runs round 2 made.
  for (int i = 0; i < 120 && info["last_drift"].value("campaign_run_id", int64_t{0}) != id; ++i) {
    usleep(250 * 1000);
    info = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id));
  }
  ASSERT_EQ(info["last_drift"].value("campaign_run_id", int64_t{0}), id) << info.dump(1);
  EXPECT_GE(info["last_drift"]["created_at"].get<double>(), rounds.back()["finished_at"].get<double>());
  EXPECT_EQ(info["last_drift"]["ran"].get<int64_t>(), static_cast<int64_t>(results["results"].size()))
      << info["last_drift"].dump(1);
}

}  // namespace
}  // namespace sandswim::truth
