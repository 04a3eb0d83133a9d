// End to end, faults: a worker killed mid-run and a deck the engine rejects, with the
// real sandswimd, real sandswim-workers and LIGGGHTS at smoke scale. One daemon serves both tests;
// its bed is the tests' shared smoke bed (ctest's smoke_bed fixture), handed in through the worker
// protocol. A ctest test of its own, so that it runs beside the long e2e (e2e_test.cc).
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/deck.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim {
namespace {

using nlohmann::json;
using testing::Daemon;
using ::testing::HasSubstr;

constexpr double kTimeoutS = 900;

class EndToEndFaultsTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new std::string(testing::CacheDir() + "/e2e-faults");
    std::filesystem::remove_all(*dir_);
    daemon_ = new Daemon(*dir_ + "/daemon", {"--lease-ttl", "6", "--max-attempts", "3"});
  }
  static void TearDownTestSuite() {
    delete daemon_;
    delete dir_;
  }

  // Submits the sweep and hands its bed in (the shared smoke bed: no bed is prepared here).
  int64_t Submit(const json& sweep) {
    int status = 0;
    json r = daemon_->Post("/api/v1/sweeps", sweep, &status);
    EXPECT_EQ(status, 201) << r.dump();
    testing::HandInBeds(*daemon_, testing::PrepareBed(*FindScale("smoke")));
    return r.value("id", int64_t{0});
  }

  std::vector<json> Runs(int64_t sweep) {
    json page = daemon_->Get("/api/v1/runs?sweep=" + std::to_string(sweep));
    return page["runs"].get<std::vector<json>>();
  }

  static std::string* dir_;
  static Daemon* daemon_;
};
std::string* EndToEndFaultsTest::dir_ = nullptr;
Daemon* EndToEndFaultsTest::daemon_ = nullptr;

int ProcessesUnder(const std::string& dir) { return static_cast<int>(testing::ProcessesUnder(dir).size()); }

// A worker killed with SIGKILL in the middle of a run: its engine dies with it, its lease
// expires, a second worker runs the run again, and exactly one result exists. The first worker
// starts LIGGGHTS directly (no mpirun, no guard process), the second through mpirun.
TEST_F(EndToEndFaultsTest, KilledWorkerLosesNoRun) {
  int64_t id = Submit(testing::OmegaSweep("killed-worker", {-40}, 0.1));
  const std::string first_dir = *dir_ + "/worker-killed";
  auto first = testing::StartWorker(*daemon_, first_dir, 1, {"--launcher", "direct"});
  int64_t run_id = 0;
  bool caught_running = false;
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(static_cast<int>(kTimeoutS));
  while (!caught_running && std::chrono::steady_clock::now() < deadline) {
    std::vector<json> runs = Runs(id);
    ASSERT_EQ(runs.size(), 1u);
    run_id = runs[0]["id"];
    // A run that ended before it was caught running leaves nothing to kill: say so now rather
    // than wait for the deadline.
    ASSERT_TRUE(runs[0]["state"] == "queued" || runs[0]["state"] == "running")
        << "the run ended before the worker could be killed: " << runs[0].dump() << "\nworker:\n"
        << first->Output();
    caught_running = runs[0]["state"] == "running" && runs[0]["progress"]["sim_time_s"].get<double>() > 0.02;
    if (!caught_running) std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
  ASSERT_TRUE(caught_running) << "the run was not seen running within " << kTimeoutS << " s\nworker:\n"
                              << first->Output();
  ASSERT_GE(ProcessesUnder(first_dir + "/"), 1) << "no engine runs in " << first_dir;
  first->Kill(SIGKILL);
  for (int i = 0; i < 100 && ProcessesUnder(first_dir + "/") > 0; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_EQ(ProcessesUnder(first_dir + "/"), 0) << "the engine outlived its SIGKILLed worker";
  auto second = testing::StartWorker(*daemon_, *dir_ + "/worker-second", 1);
  json sweep = daemon_->WaitForSweep(id, kTimeoutS);
  ASSERT_EQ(sweep["counts"]["done"], 1) << sweep.dump() << "\nsecond worker:\n" << second->Output();
  json detail = daemon_->Get("/api/v1/runs/" + std::to_string(run_id));
  EXPECT_EQ(detail["attempts"], 2);
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM results WHERE run_id = " + std::to_string(run_id)), "1");
}

// A deck LIGGGHTS rejects fails its run with the ERROR: line, without retries; the sweep's other
// run finishes. The deck is broken in the database, where a stored deck is read from.
TEST_F(EndToEndFaultsTest, RejectedDeckFailsItsRunOnly) {
  int64_t id = Submit(testing::OmegaSweep("bad-deck", {-20, 20}, 0.05));
  std::vector<json> runs = Runs(id);
  ASSERT_EQ(runs.size(), 2u);
  const std::string bad = std::to_string(runs[0]["id"].get<int64_t>());
  // Decks are rendered at lease time unless one is stored for the run: store a broken one.
  std::string deck = daemon_->Get("/api/v1/runs/" + bad)["deck"];
  const std::string good_line = "pair_style      gran";
  ASSERT_NE(deck.find(good_line), std::string::npos);
  deck.replace(deck.find(good_line), good_line.size(), "pair_style      no_such_style");
  daemon_->StoreDeckForRun(runs[0]["id"].get<int64_t>(), deck);
  ASSERT_EQ(daemon_->Query("SELECT count(*) FROM run_decks WHERE run_id = " + bad), "1");
  auto worker = testing::StartWorker(*daemon_, *dir_ + "/worker-bad-deck", 2);
  json sweep = daemon_->WaitForSweep(id, kTimeoutS);
  EXPECT_EQ(sweep["counts"]["done"], 1) << sweep.dump();
  EXPECT_EQ(sweep["counts"]["failed"], 1) << sweep.dump();
  json detail = daemon_->Get("/api/v1/runs/" + bad);
  EXPECT_EQ(detail["state"], "failed");
  EXPECT_EQ(detail["attempts"], 1);
  EXPECT_EQ(detail["last_error"]["kind"], "deck_error") << detail.dump();
  EXPECT_THAT(detail["last_error"]["message"].get<std::string>(), HasSubstr("ERROR"));
}

}  // namespace
}  // namespace sandswim
