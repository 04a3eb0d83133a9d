// sandswim on a real Slurm: deploy/slurm/local-cluster.sh brings up a single-node
// Slurm (munge, slurmctld, slurmd), a real sandswimd hands out smoke runs, and `sandswim slurm
// submit` sbatches pilots (srun-launched LIGGGHTS) and job arrays of one-shot workers.
//
// The daemon's bed is the shared smoke bed (tests/engine_fixture.h PrepareBed): the test hands it
// in through the worker protocol (lease, upload, complete) before any worker starts, so no test
// prepares a bed. Runs last 0.05 s
// of simulated time (0.1 s for the one cancelled mid-run, so there is a middle to cancel in).
// Each test uses its own Omega values, so no run is shared (and so reused) between tests.
//
// Skips, saying why, only when Slurm's packages are missing or the cluster cannot start (not
// root, no munge); CI installs them with deploy/install-deps.sh. When every test skipped, the
// program exits 77, which ctest shows as skipped (SKIP_RETURN_CODE), not as passed.
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/scale.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"
#include "workers/run_dir.h"

namespace sandswim {
namespace {

using nlohmann::json;
using testing::Daemon;
using Clock = std::chrono::steady_clock;

const std::string kCluster = std::string(SANDSWIM_SOURCE_DIR) + "/deploy/slurm/local-cluster.sh";
constexpr double kSweepTimeoutS = 240;

double Since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

// Runs a shell command; returns its exit code and (in `out`) what it printed.
int Shell(const std::string& command, std::string* out = nullptr) {
  std::string text;
  FILE* p = popen((command + " 2>&1").c_str(), "r");
  if (p == nullptr) return -1;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) text.append(buf, n);
  int rc = pclose(p);
  if (out) *out = text;
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

class SlurmTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string out;
    if (Shell("command -v sbatch && command -v slurmctld && command -v slurmd && command -v munged", &out) != 0 &&
        Shell("test -x /usr/sbin/slurmctld && test -x /usr/sbin/slurmd && test -x /usr/sbin/munged", &out) != 0) {
      skip_ = new std::string(
          "Slurm is not installed (slurmctld slurmd slurm-client munge): run "
          "deploy/install-deps.sh as root");
      return;
    }
    if (geteuid() != 0) {
      skip_ = new std::string("the local Slurm cluster needs root (it starts munged, slurmctld and slurmd)");
      return;
    }
    const auto t0 = Clock::now();
    if (Shell(kCluster + " start", &out) != 0) {
      skip_ = new std::string("Slurm could not be started: " + out);
      return;
    }
    std::printf("SLURM cluster up in %.1f s: %s", Since(t0), out.c_str());
    dir_ = new std::string(testing::CacheDir() + "/slurm");
    std::filesystem::remove_all(*dir_);
    std::filesystem::create_directories(*dir_);
    bed_ = new std::string(testing::PrepareBed(*FindScale("smoke")));
    // Lease TTL 20 s (heartbeats every 5 s): a gone pilot's run is reclaimed after 10 s of silence,
    // well before its lease would expire; squeue is asked every second.
    daemon_ = new Daemon(*dir_ + "/daemon", {"--lease-ttl", "20", "--max-attempts", "3", "--slurm-check", "1"});
  }
  static void TearDownTestSuite() {
    if (skip_ == nullptr) Shell(kCluster + " stop");
    delete daemon_;
    delete dir_;
    delete bed_;
    delete skip_;
    daemon_ = nullptr;
    dir_ = bed_ = skip_ = nullptr;
  }
  void SetUp() override {
    if (skip_ != nullptr) GTEST_SKIP() << *skip_;
  }

  // Submits a sweep and hands the shared smoke bed in for its bed (through the worker protocol).
  int64_t Submit(const json& sweep) {
    int status = 0;
    json r = daemon_->Post("/api/v1/sweeps", sweep, &status);
    EXPECT_EQ(status, 201) << r.dump();
    testing::HandInBeds(*daemon_, *bed_);
    EXPECT_EQ(daemon_->Query("SELECT count(*) FROM beds WHERE state != 'done'"), "0");
    return r.value("id", int64_t{0});
  }

  // `sandswim slurm submit ...`; returns the job id.
  int64_t SlurmSubmit(const std::string& flags) {
    const std::string cmd = std::string(SANDSWIM_CLI_PATH) + " --server " + daemon_->url() +
                            " slurm submit --time 5:00 --ranks-per-run 1 --worker " + SANDSWIM_WORKER_PATH +
                            " --workdir " + *dir_ + "/work --end-margin 20 --output " + *dir_ + "/slurm-%j.out " +
                            flags;
    std::string out;
    int rc = Shell(cmd + " 2>/dev/null", &out);
    EXPECT_EQ(rc, 0) << cmd << "\n" << out;
    int64_t id = 0;
    try {
      id = std::stoll(out);
    } catch (...) {
      ADD_FAILURE() << "no job id from `" << cmd << "`: " << out;
    }
    return id;
  }

  static std::string JobLog(int64_t job) { return testing::ReadFile(*dir_ + "/slurm-" + std::to_string(job) + ".out"); }

  std::vector<json> Runs(int64_t sweep) {
    return daemon_->Get("/api/v1/runs?sweep=" + std::to_string(sweep))["runs"].get<std::vector<json>>();
  }

  // Waits until `pred` holds for the runs of `sweep`; false at the timeout.
  bool WaitForRuns(int64_t sweep, double timeout_s, const std::function<bool(const std::vector<json>&)>& pred) {
    const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
    while (Clock::now() < deadline) {
      if (pred(Runs(sweep))) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    return false;
  }

  // A one-run sweep (0.1 s of simulated time) and a 1-CPU pilot, returned once the pilot's engine
  // has made progress on the run.
  void PilotInTheMiddleOfARun(const std::string& name, double omega, int64_t* sweep, int64_t* pilot, int64_t* run_id) {
    *sweep = Submit(testing::OmegaSweep(name, {omega}, 0.1));
    *pilot = SlurmSubmit("--nodes 1 --tasks-per-node 1");
    ASSERT_GT(*pilot, 0);
    ASSERT_TRUE(WaitForRuns(*sweep, 120, [&](const std::vector<json>& runs) {
      *run_id = runs.at(0)["id"];
      return runs[0]["state"] == "running" && runs[0]["progress"]["sim_time_s"].get<double>() > 0;
    })) << JobLog(*pilot);
  }

  static std::string* skip_;
  static std::string* dir_;
  static std::string* bed_;
  static Daemon* daemon_;
};
std::string* SlurmTest::skip_ = nullptr;
std::string* SlurmTest::dir_ = nullptr;
std::string* SlurmTest::bed_ = nullptr;
Daemon* SlurmTest::daemon_ = nullptr;

// A pilot of 2 CPUs runs a 4-run sweep to completion, two srun steps side by side.
TEST_F(SlurmTest, PilotOfTwoCpusRunsAFourRunSweep) {
  int64_t sweep = Submit(testing::OmegaSweep("slurm-pilot", {-80, -40, 40, 80}, 0.05));
  const auto submitted = Clock::now();
  int64_t job = SlurmSubmit("--nodes 1 --tasks-per-node 2");
  ASSERT_GT(job, 0);
  ASSERT_TRUE(WaitForRuns(sweep, 60, [](const std::vector<json>& runs) {
    for (const json& r : runs) {
      if (r["state"] != "queued") return true;
    }
    return false;
  })) << JobLog(job);
  const double to_first_lease = Since(submitted);
  json s = daemon_->WaitForSweep(sweep, kSweepTimeoutS);
  const double to_done = Since(submitted);
  Shell("scancel " + std::to_string(job));
  ASSERT_EQ(s["counts"]["done"], 4) << s.dump() << "\npilot log:\n" << JobLog(job);
  for (const json& run : Runs(sweep)) {
    json detail = daemon_->Get("/api/v1/runs/" + std::to_string(run["id"].get<int64_t>()));
    EXPECT_EQ(detail["result"]["launcher"], "srun") << detail.dump();
    EXPECT_EQ(detail["attempts"], 1);
    std::printf("SLURM run Omega=%+g: wall %.2f s, U_z %s\n", run["point"]["Omega"].get<double>(),
                detail["result"]["wall_s"].get<double>(), detail["result"].value("uz_text", "?").c_str());
  }
  // Two runs shared the allocation at once: some lease was granted before another completed.
  EXPECT_EQ(daemon_->Query("SELECT count(*) > 0 FROM leases a JOIN leases b ON a.token != b.token "
                           "WHERE b.granted_at < a.completed_at AND b.granted_at >= a.granted_at"),
            "1");
  EXPECT_THAT(JobLog(job), ::testing::HasSubstr("launcher srun"));
  std::printf("SLURM submit -> first lease %.2f s; 4 runs done %.1f s after submit\n", to_first_lease, to_done);
}

// scancel of a pilot in the middle of a run: the worker hands the run back (not counted as an
// attempt) and a second pilot finishes it; exactly one result.
TEST_F(SlurmTest, CancelledPilotsRunIsFinishedByTheNextPilotOnce) {
  int64_t sweep = 0, first = 0, run_id = 0;
  ASSERT_NO_FATAL_FAILURE(PilotInTheMiddleOfARun("slurm-scancel", -60, &sweep, &first, &run_id));
  ASSERT_EQ(Shell("scancel " + std::to_string(first)), 0);
  // Handed back: queued again well before the 20 s lease would have expired.
  const auto cancelled = Clock::now();
  ASSERT_TRUE(WaitForRuns(sweep, 60, [](const std::vector<json>& runs) { return runs[0]["state"] == "queued"; }))
      << JobLog(first);
  std::printf("SLURM scancel -> run queued again in %.2f s\n", Since(cancelled));
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM events WHERE kind = 'run.released' AND subject = 'run/" +
                           std::to_string(run_id) + "'"),
            "1")
      << JobLog(first);
  int64_t second = SlurmSubmit("--nodes 1 --tasks-per-node 1");
  json s = daemon_->WaitForSweep(sweep, kSweepTimeoutS);
  Shell("scancel " + std::to_string(second));
  ASSERT_EQ(s["counts"]["done"], 1) << s.dump() << "\nsecond pilot:\n" << JobLog(second);
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM results WHERE run_id = " + std::to_string(run_id)), "1");
  json detail = daemon_->Get("/api/v1/runs/" + std::to_string(run_id));
  EXPECT_EQ(detail["attempts"], 1) << "the handed-back lease must not count as an attempt";
  EXPECT_THAT(detail["result"]["host"].get<std::string>(), ::testing::Not(::testing::IsEmpty()));
}

// A pilot whose worker is SIGKILLed mid-run (the OOM killer, a crash) cannot hand its run back;
// its job then ends, the daemon sees (squeue) that the job is gone and queues the run again
// before the lease would have expired ("pilot_gone", not "lease_expired"). (`scancel -s KILL`
// would not do: Slurm turns it into a normal cancel, SIGTERM first, and the worker hands back.)
TEST_F(SlurmTest, KilledPilotsRunIsReclaimedFromSlurmBeforeItsLeaseExpires) {
  int64_t sweep = 0, pilot = 0, run_id = 0;
  ASSERT_NO_FATAL_FAILURE(PilotInTheMiddleOfARun("slurm-kill", -70, &sweep, &pilot, &run_id));
  EXPECT_EQ(
      daemon_->Query("SELECT slurm_job FROM leases WHERE job_id = " + std::to_string(run_id) + " AND kind = 'run'"),
      std::to_string(pilot));
  // The worker is the batch shell itself (pilot.sbatch execs it), named after its job. ("[-]-name"
  // keeps the pattern from matching the shell that runs pkill.)
  ASSERT_EQ(Shell("pkill -KILL -f -- '[-]-name slurm-" + std::to_string(pilot) + "@'"), 0) << JobLog(pilot);
  const auto killed = Clock::now();
  json queued;
  ASSERT_TRUE(WaitForRuns(sweep, 60, [&](const std::vector<json>& runs) {
    queued = runs[0];
    return runs[0]["state"] == "queued";
  })) << JobLog(pilot);
  const double took = Since(killed);
  std::printf("SLURM pilot's worker SIGKILLed -> run queued again in %.2f s (lease TTL 20 s)\n", took);
  EXPECT_EQ(queued["last_error"]["kind"], "pilot_gone") << queued.dump();
  // Reclaimed after 10 s of silence (up to 5 s of it before the kill) and the next look: 5-11 s
  // after the kill; the lease would have expired 15-20 s after it.
  EXPECT_LT(took, 15.0) << "reclaimed only when the lease expired";
  // Nothing else needs it: cancel the sweep so later tests' pilots do not run it.
  int status = 0;
  daemon_->Post("/api/v1/sweeps/" + std::to_string(sweep) + "/cancel", json::object(), &status);
  EXPECT_EQ(status, 200);
}

// A job array of 2 one-shot workers, throttled to one at a time, runs a 2-run sweep.
TEST_F(SlurmTest, ArrayOfOneShotWorkersRunsATwoRunSweep) {
  int64_t sweep = Submit(testing::OmegaSweep("slurm-array", {-20, 20}, 0.05));
  int64_t job = SlurmSubmit("--array 2 --throttle 1");
  ASSERT_GT(job, 0);
  json s = daemon_->WaitForSweep(sweep, kSweepTimeoutS);
  ASSERT_EQ(s["counts"]["done"], 2) << s.dump() << "\nelement logs:\n"
                                    << JobLog(job)
                                    << testing::ReadFile(*dir_ + "/slurm-" + std::to_string(job + 1) + ".out");
  // Each element took exactly one run, and the throttle (%1) kept them apart.
  EXPECT_EQ(daemon_->Query("SELECT count(DISTINCT worker) FROM leases WHERE job_id IN (SELECT run_id FROM sweep_runs "
                           "WHERE sweep_id = " +
                           std::to_string(sweep) + ")"),
            "2");
  EXPECT_EQ(
      daemon_->Query("SELECT count(*) FROM leases a JOIN leases b ON a.token < b.token "
                     "WHERE a.job_id IN (SELECT run_id FROM sweep_runs WHERE sweep_id = " +
                     std::to_string(sweep) + ") AND b.job_id IN (SELECT run_id FROM sweep_runs WHERE sweep_id = " +
                     std::to_string(sweep) + ") AND a.granted_at < b.completed_at AND b.granted_at < a.completed_at"),
      "0");
  // Both elements exited after their one run: nothing of the array is left in the queue.
  std::string left;
  const auto deadline = Clock::now() + std::chrono::seconds(30);
  do {
    Shell("squeue -h -j " + std::to_string(job), &left);
    if (left.find_first_not_of(" \n") == std::string::npos) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  } while (Clock::now() < deadline);
  EXPECT_EQ(left.find_first_not_of(" \n"), std::string::npos) << left;
}

}  // namespace
}  // namespace sandswim

// gtest's main, except that a run in which every test skipped exits kSkipped.
int main(int argc, char** argv) {
  constexpr int kSkipped = 77;  // tests/slurm/CMakeLists.txt: SKIP_RETURN_CODE
  ::testing::InitGoogleTest(&argc, argv);
  const int rc = RUN_ALL_TESTS();
  const ::testing::UnitTest& unit = *::testing::UnitTest::GetInstance();
  if (rc == 0 && unit.test_to_run_count() > 0 && unit.skipped_test_count() == unit.test_to_run_count()) {
    return kSkipped;
  }
  return rc;
}
