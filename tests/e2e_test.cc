// End to end: the real sandswimd, a real sandswim-worker launching LIGGGHTS under mpirun
// at smoke scale, a real SQLite file. The daemon's smoke bed replicate 0 is the tests' shared bed
// (ctest's smoke_bed fixture prepares it, beside this test), handed in through the worker
// protocol; replicate 1 is prepared by the daemon's own bed job on the worker, as a user's bed is,
// at the same time. A killed worker and a rejected deck: e2e_faults_test.cc, beside this one.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/api.h"
#include "core/deck.h"
#include "core/trajectory.h"
#include "tests/browser/webdriver.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim {
namespace {

using nlohmann::json;
using testing::Daemon;
using ::testing::HasSubstr;

constexpr double kTimeoutS = 1800;  // the replicate sweep prepares a bed (~4 min on a free core)

class EndToEndTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::CacheDir() + "/e2e");
    std::filesystem::remove_all(*dir_);
    daemon_ = new Daemon(*dir_ + "/daemon", {"--lease-ttl", "6", "--max-attempts", "3"});
  }
  static void TearDownTestSuite() {
    delete daemon_;
    delete dir_;
  }

  int64_t Submit(const json& sweep) {
    int status = 0;
    json r = daemon_->Post("/api/v1/sweeps", sweep, &status);
    EXPECT_EQ(status, 201) << r.dump();
    return r.value("id", int64_t{0});
  }

  std::vector<json> Runs(int64_t sweep) {
    json page = daemon_->Get("/api/v1/runs?sweep=" + std::to_string(sweep));
    return page["runs"].get<std::vector<json>>();
  }

  // The run's three snapshots (start, middle, end) of the whole bed: recorded with their times,
  // served as the engine's dump, as VTK (parsed back here by a reader of this test's own: every
  // grain and the SO a point) and as the y-z slice through the SO.
  void CheckSnapshots(int64_t run_id, const json& res) {
    const std::string base = "/api/v1/runs/" + std::to_string(run_id);
    const json detail = daemon_->Get(base);
    EXPECT_EQ(detail["snapshots"], json({0, 0.5, 1})) << detail.dump();
    const json& taken = detail["snapshots_taken"];
    ASSERT_EQ(taken.size(), 3u) << detail.dump();
    const double t_end = res["sim_time_s"].get<double>();
    EXPECT_EQ(taken[0]["t_s"].get<double>(), 0.0);
    EXPECT_NEAR(taken[1]["t_s"].get<double>(), t_end / 2, t_end / kSnapshotFramesPerRun) << taken.dump();
    EXPECT_NEAR(taken[2]["t_s"].get<double>(), t_end, 1e-9) << taken.dump();
    const int64_t grains = res["grains"].get<int64_t>();
    for (const json& snap : taken) {
      EXPECT_EQ(snap["grains"].get<int64_t>(), grains) << snap.dump();
      int status = 0;
      const std::string vtk = daemon_->GetText(snap["links"]["vtk"].get<std::string>(), &status);
      ASSERT_EQ(status, 200) << vtk.substr(0, 500);
      std::istringstream in(vtk);
      std::string line, word, type;
      std::getline(in, line);
      EXPECT_EQ(line, "# vtk DataFile Version 3.0");
      std::getline(in, line);  // title
      std::getline(in, line);
      EXPECT_EQ(line, "ASCII");
      in >> word >> type;
      EXPECT_EQ(word + " " + type, "DATASET POLYDATA");
      int64_t points = 0;
      in >> word >> points >> type;
      EXPECT_EQ(word, "POINTS");
      EXPECT_EQ(points, grains + 1) << "every grain and the SO";
      double lowest = 1e9;
      for (int64_t i = 0; i < points; ++i) {
        double x = 0, y = 0, z = 0;
        ASSERT_TRUE(in >> x >> y >> z) << "point " << i;
        lowest = std::min(lowest, z);
      }
      EXPECT_GT(lowest, -1.0);  // inside the smoke box
      const std::string svg = daemon_->GetText(snap["links"]["slice_svg"].get<std::string>(), &status);
      ASSERT_EQ(status, 200) << svg.substr(0, 500);
      // Every grain the plane cuts is a filled polygon: hundreds of them in a 6,682-grain bed.
      size_t filled = 0;
      for (size_t at = svg.find("fill-rule"); at != std::string::npos; at = svg.find("fill-rule", at + 1)) ++filled;
      EXPECT_GT(filled, 200u);
      const std::string dump = daemon_->GetText(snap["links"]["dump"].get<std::string>(), &status);
      ASSERT_EQ(status, 200);
      EXPECT_THAT(dump, HasSubstr("ITEM: ATOMS id type x y z vx vy vz radius"));
    }
    std::printf("E2E snapshots of run %lld: t = %.3f, %.3f, %.3f s of %.3f s, %lld grains each\n",
                static_cast<long long>(run_id), taken[0]["t_s"].get<double>(), taken[1]["t_s"].get<double>(),
                taken[2]["t_s"].get<double>(), t_end, static_cast<long long>(grains));
    int status = 0;
    daemon_->GetText(base + "/snapshots/3.vtk", &status);
    EXPECT_EQ(status, 404);
  }

  // The dashboard with a real smoke run (the stand-in's pages: tests/browser/dashboard_test.cc):
  // the run's page, opened while LIGGGHTS runs it, shows its simulated time moving and its z(t)
  // drawn, without a reload.
  void WatchInTheDashboard(int64_t run_id) {
    std::string why;
    if (!testing::BrowserAvailable(&why)) {
      std::printf("E2E dashboard: not checked (%s)\n", why.c_str());
      return;
    }
    const std::string path = "/api/v1/runs/" + std::to_string(run_id);
    for (int i = 0; i < 600 && !(daemon_->Get(path)["progress"]["sim_time_s"].get<double>() > 0); ++i) {
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
    ASSERT_EQ(daemon_->Get(path)["state"], "running");
    const std::string out = SANDSWIM_BROWSER_TEST_DIR;
    std::filesystem::create_directories(out);
    testing::Browser browser(out);
    browser.Navigate(daemon_->url() + "/runs/" + std::to_string(run_id));
    browser.Script("window.__sameDocument = 7;");
    ASSERT_TRUE(browser.WaitUntil("/ s simulated/.test(document.querySelector('#sim-time').textContent)", 30));
    const std::string first = browser.Text("#sim-time");
    ASSERT_TRUE(browser.WaitUntil("document.querySelector('#sim-time').textContent !== " + json(first).dump(), 120))
        << first;
    ASSERT_TRUE(browser.WaitUntil("!!document.querySelector('#zt-plot canvas')", 60)) << browser.Text("#main");
    EXPECT_EQ(browser.Script("return window.__sameDocument;").get<int>(), 7) << "the page was reloaded";
    std::printf("E2E dashboard: run %lld's page went from \"%s\" to \"%s\" on its own\n",
                static_cast<long long>(run_id), first.c_str(), browser.Text("#sim-time").c_str());
    browser.Screenshot(out + "/e2e-run-live.png");
    EXPECT_THAT(browser.ConsoleErrors(), ::testing::IsEmpty());
  }

  static std::string* dir_;
  static Daemon* daemon_;
};
std::string* EndToEndTest::dir_ = nullptr;
Daemon* EndToEndTest::daemon_ = nullptr;

// Precision targets and replicate beds, end to end. Three sweeps at once:
//   - Omega = -80 at 20 Hz on 2 replicate beds, with a target any interval meets (uz_abs 1 m/s):
//     each run ends, through the deck's control file, once its window holds the pilot's 3 whole
//     periods and the 3 after it, after the 0.3 s transient (0.6 s), before its 0.8 s maximum,
//     saying the target was met; the
//     two beds are prepared once
//     each, lie differently, and the point's results aggregate over both (K = 2);
//   - Omega = -80 at 20 Hz with a target no interval meets: it runs to its 0.2 s maximum (the least
//     a target of 3 periods allows) and says so
//     (on replicate 0's bed, as a sweep without replicates does);
//   - the paper's sinking baseline, Omega = +80 at 3 Hz, at smoke's default target with a 1.34 s
//     maximum: the floor no longer ends it early -- its window holds the 3 whole periods the
//     target asks before any boundary (the old smoke box stopped it at dz = -0.059 m, before two).
TEST_F(EndToEndTest, RunsEndAtTheirPrecisionTargetOnReplicateBeds) {
  json met = testing::OmegaSweep("replicated", {-80}, 0.8, 20);
  met["precision"] = {{"uz_rel", 0}, {"uz_abs", 1.0}, {"min_periods", 3}, {"max_duration_s", 0.8}};
  met["replicates"] = 2;
  json unreachable = testing::OmegaSweep("unreachable", {-80}, 0.2, 20);
  unreachable["precision"] = {{"uz_rel", 0}, {"uz_abs", 1e-9}, {"min_periods", 3}, {"max_duration_s", 0.2}};
  json sinking = testing::OmegaSweep("sinking-baseline", {80}, 5, 3);
  sinking["precision"] = {{"uz_rel", 0.2}, {"uz_abs", 0.005}, {"min_periods", 3}, {"max_duration_s", 1.34}};
  sinking["snapshots"] = {0, 0.5, 1};  // the paper's Fig. 5: the whole bed at its start, middle and end
  // The longest run first (runs are leased in the order they were submitted): it ends no later.
  const int64_t id_sinking = Submit(sinking), id = Submit(met), id_unreachable = Submit(unreachable);
  // Replicate 0 (the first bed leased) is the tests' shared bed: hold its lease while the fixture
  // prepares it, so that the worker prepares replicate 1 meanwhile.
  const Scale& smoke = *FindScale("smoke");
  testing::BedHandIn replicate0(*daemon_);
  ASSERT_EQ(replicate0.grant().deck, RenderBedDeck(smoke, 0));
  auto worker = testing::StartWorker(*daemon_, *dir_ + "/worker-pair", 2);
  replicate0.Complete(testing::PrepareBed(smoke));
  WatchInTheDashboard(Runs(id_sinking).at(0)["id"].get<int64_t>());

  json sweep = daemon_->WaitForSweep(id, kTimeoutS);
  ASSERT_EQ(sweep["counts"]["done"], 2) << sweep.dump() << "\nworker:\n" << worker->Output();
  for (const json& run : Runs(id)) {
    json detail = daemon_->Get("/api/v1/runs/" + std::to_string(run["id"].get<int64_t>()));
    const json& res = detail["result"];
    ASSERT_TRUE(res.is_object()) << detail.dump();
    ASSERT_TRUE(res.contains("uz")) << res.dump();
    EXPECT_TRUE(std::isfinite(res["uz"].get<double>()));
    EXPECT_EQ(res["analysis"], api::kAnalysisVersion);
    EXPECT_EQ(res["stop_reason"], "target") << res.dump();
    EXPECT_EQ(res["precision_met"], true) << res.dump();
    EXPECT_THAT(res["stop_note"].get<std::string>(), HasSubstr("precision target met"));
    // Ended after its transient (0.3 s: six periods at 20 Hz), the pilot's 3 whole periods and 3
    // more (0.6 s), at the worker's next look, before the 0.8 s maximum; U_z from the 3 after the
    // pilot.
    EXPECT_GE(res["uz_blocks"].get<int>(), 3) << res.dump();
    EXPECT_GE(res["sim_time_s"].get<double>(), 0.6 - 1e-9) << res.dump();
    EXPECT_LT(res["sim_time_s"].get<double>(), 0.8) << res.dump();
    EXPECT_EQ(res["conclusive"], true) << res.dump();
    ASSERT_TRUE(res.contains("uz_stderr")) << res.dump();
    EXPECT_GT(res["uz_stderr"].get<double>(), 0.0);
    EXPECT_GT(res["grains"].get<int64_t>(), 6000);
    EXPECT_GT(detail["trajectory"]["t"].size(), 100u);
    EXPECT_EQ(detail["trajectory"]["t"].size(), detail["trajectory"]["z"].size());
    EXPECT_EQ(res["launcher"], "mpirun");
    EXPECT_EQ(detail["attempts"], 1);
    EXPECT_THAT(detail["deck"].get<std::string>(), HasSubstr("# Precision target: "));
    // The sign (Sec. 3.2): Omega < 0 rises. The run's net displacement shows it (+28 and +29 mm
    // on the two beds in 0.2 s, against sub-mm jitter); U_z must agree wherever its 95 % interval
    // excludes zero (a few periods may leave the sign open). The sinking baseline below checks
    // Omega > 0.
    EXPECT_GT(res["dz"].get<double>(), 0.0) << res.dump();
    if (std::fabs(res["uz"].get<double>()) > res["uz_ci95"].get<double>()) {
      EXPECT_GT(res["uz"].get<double>(), 0.0) << res.dump();
    }
    std::printf("E2E Omega=%+g at 20 Hz, target met: U_z=%s dz=%+.4f m t=%.3f s wall=%.1f s lease->start=%.3f s\n",
                run["point"]["Omega"].get<double>(), res.value("uz_text", "?").c_str(), res["dz"].get<double>(),
                res["sim_time_s"].get<double>(), res["wall_s"].get<double>(), res.value("lease_to_start_s", -1.0));
  }

  // Two replicate beds, prepared once each (replicate 0 by the fixture, 1 by the worker), poured
  // differently: their figures differ.
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM beds"), "2");
  EXPECT_EQ(daemon_->Query("SELECT group_concat(attempts) FROM beds"), "1,1");
  EXPECT_EQ(daemon_->Query("SELECT count(DISTINCT sha256) FROM beds"), "2");
  std::vector<json> beds;
  for (int replicate : {0, 1}) {
    beds.push_back(
        json::parse(daemon_->Query("SELECT result FROM beds WHERE replicate = " + std::to_string(replicate))));
    const json& b = beds.back();
    ASSERT_TRUE(b.contains("packing_fraction")) << b.dump();
    EXPECT_GT(b["packing_fraction"].get<double>(), 0.3) << b.dump();
    EXPECT_LT(b["packing_fraction"].get<double>(), 0.75) << b.dump();
    EXPECT_GT(b["so_depth"].get<double>(), 0.2) << b.dump();
    std::printf("E2E bed replicate %d: %lld grains, height %.3f m, SO depth %.3f m, packing %.3f in the shell\n",
                replicate, static_cast<long long>(b["grains"].get<int64_t>()), b["bed_height"].get<double>(),
                b["so_depth"].get<double>(), b["packing_fraction"].get<double>());
  }
  EXPECT_TRUE(beds[0]["so_z"] != beds[1]["so_z"] || beds[0]["grain_top"] != beds[1]["grain_top"] ||
              beds[0]["packing_fraction"] != beds[1]["packing_fraction"])
      << beds[0].dump() << "\n"
      << beds[1].dump();
  // The point aggregates over its two beds.
  const json results = daemon_->Get("/api/v1/sweeps/" + std::to_string(id) + "/results");
  ASSERT_EQ(results["aggregates"].size(), 1u) << results.dump();
  for (const json& a : results["aggregates"]) {
    EXPECT_EQ(a["replicates"], 2) << a.dump();
    ASSERT_EQ(a["values"].size(), 2u) << a.dump();
    EXPECT_NE(a["values"][0]["bed_id"], a["values"][1]["bed_id"]);
    if (a["conclusive"] == 2) {
      EXPECT_TRUE(a.contains("uz_sd_between")) << a.dump();
      const double mean = (a["values"][0]["uz"].get<double>() + a["values"][1]["uz"].get<double>()) / 2;
      EXPECT_NEAR(a["uz_mean"].get<double>(), mean, 1e-12);
    }
    std::printf("E2E aggregate Omega=%+g: %s\n", a["Omega"].get<double>(), a["uz_text"].get<std::string>().c_str());
  }

  sweep = daemon_->WaitForSweep(id_unreachable, kTimeoutS);
  ASSERT_EQ(sweep["counts"]["done"], 1) << sweep.dump() << "\nworker:\n" << worker->Output();
  {
    const json run = Runs(id_unreachable).at(0);
    const json res = daemon_->Get("/api/v1/runs/" + std::to_string(run["id"].get<int64_t>()))["result"];
    EXPECT_EQ(res["stop_reason"], "duration") << res.dump();
    EXPECT_EQ(res["precision_met"], false) << res.dump();
    EXPECT_NEAR(res["sim_time_s"].get<double>(), 0.2, 1e-9);
    EXPECT_THAT(res["stop_note"].get<std::string>(), HasSubstr("without meeting the precision target"));
  }

  sweep = daemon_->WaitForSweep(id_sinking, kTimeoutS);
  ASSERT_EQ(sweep["counts"]["done"], 1) << sweep.dump() << "\nworker:\n" << worker->Output();
  {
    const json run = Runs(id_sinking).at(0);
    const json res = daemon_->Get("/api/v1/runs/" + std::to_string(run["id"].get<int64_t>()))["result"];
    EXPECT_NE(res["stop_reason"], "floor") << res.dump();
    EXPECT_NE(res["stop_reason"], "window") << res.dump();
    EXPECT_EQ(res["window_end"], "run_end") << res.dump();
    EXPECT_GE(res["uz_blocks"].get<int>(), 3) << res.dump();
    EXPECT_LT(res["dz"].get<double>(), 0.0) << res.dump();  // it sinks
    std::printf("E2E Omega=+80 at 3 Hz (smoke baseline): U_z=%s dz=%+.4f m t=%.3f s, %s\n",
                res.value("uz_text", "?").c_str(), res["dz"].get<double>(), res["sim_time_s"].get<double>(),
                res.value("stop_note", "?").c_str());
    CheckSnapshots(run["id"].get<int64_t>(), res);
  }

  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM beds"), "2");
  EXPECT_EQ(daemon_->Query("SELECT group_concat(attempts) FROM beds"), "1,1");
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM results"), "4");
  // Submitting the same sweep again reuses both results: nothing is queued.
  json again_sweep = met;
  again_sweep["name"] = "replicated-again";
  int64_t again = Submit(again_sweep);
  json s2 = daemon_->Get("/api/v1/sweeps/" + std::to_string(again));
  EXPECT_EQ(s2["counts"]["done"], 2) << s2.dump();
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM runs"), "4");
}

}  // namespace
}  // namespace sandswim
