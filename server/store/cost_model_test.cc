#include "server/store/cost_model.h"

#include <stdlib.h>

#include <cmath>
#include <filesystem>

#include <gtest/gtest.h>

#include "server/store/store.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

// Rows written directly: a bed, a sweep of four runs on it (two done, one running, one queued).
class CostModelTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(store_); }
  void Exec(const std::string& sql) {
    auto t = store_->db().Begin();
    ASSERT_TRUE(t.ok());
    Status s = t->Exec(sql);
    ASSERT_TRUE(s.ok()) << s.ToString() << "\n" << sql;
    ASSERT_TRUE(t->Commit().ok());
  }
  // A bed of 999 grains prepared in 99.9 s (or `state` with no grains yet).
  void Bed(const std::string& state) {
    Exec("INSERT INTO beds (id, key, scale, state, grains, created_at, started_at, finished_at, deck) VALUES (1, 'b', "
         "'smoke', '" + state + "', " + (state == "done" ? "999" : "NULL") + ", 0, 0, " +
         (state == "done" ? "99.9" : "NULL") + ", '')");
  }
  void Run(int id, const std::string& state, long long steps, long long step, double started, double beat) {
    Exec("INSERT INTO runs (id, key, bed_id, mode, A, f, osc_omega, rot_omega, axis, duration_s, run_duration_s, "
         "steps, state, created_at, queued_at, step, started_at, heartbeat_at) VALUES (" +
         std::to_string(id) + ", 'r" + std::to_string(id) + "', 1, 'oscillatory', 0.03, 3, -80, 0, '', 1, 1, " +
         std::to_string(steps) + ", '" + state + "', 0, 0, " + std::to_string(step) + ", " + std::to_string(started) +
         ", " + std::to_string(beat) + ")");
    Exec("INSERT OR IGNORE INTO sweeps (id, name, scale, spec, created_at) VALUES (1, 's', 'smoke', '{}', 0)");
    Exec("INSERT INTO sweep_runs (sweep_id, run_id, position) VALUES (1, " + std::to_string(id) + ", " +
         std::to_string(id) + ")");
  }
  // A done run's result: `steps` of 999 grains + the SO in `wall_s`.
  void Result(int id, long long steps, double wall_s, const std::string& host = "h", int ranks = 1) {
    Exec("INSERT INTO results (run_id, window_t0, window_t1, dz, z_osc_amplitude, x_drift, broke_surface, near_floor, "
         "stop_reason, sim_time_s, steps, grains, z0, engine_version, host, ranks, launcher, wall_s, cpu_s, key, "
         "created_at) VALUES (" + std::to_string(id) + ", 0, 1, 0, 0, 0, 0, 0, 'target', 1, " + std::to_string(steps) +
         ", 999, 0, 'v', '" + host + "', " + std::to_string(ranks) + ", 'mpirun', " + std::to_string(wall_s) +
         ", 0, 'r" + std::to_string(id) + "', " + std::to_string(id) + ")");
  }
  testing::TempStore store_{"cost", "test.db"};
};

TEST_F(CostModelTest, NothingMeasuredGivesTheDefaultsAndSaysSo) {
  auto model = ReadCostModel(*store_, 0);
  ASSERT_TRUE(model.ok()) << model.status().ToString();
  EXPECT_EQ(model->run_rate.samples, 0);
  EXPECT_DOUBLE_EQ(model->run_rate.s_per_unit, kDefaultSecondsPerParticleStep);
  EXPECT_NE(model->run_rate.basis.find("default"), std::string::npos);
  EXPECT_TRUE(model->hosts.empty());
  // A queued run on a bed not prepared yet: the ETA counts the bed (estimated grains) and the run.
  Bed("queued");
  Run(1, "queued", 100000, 0, 0, 0);
  auto eta = ReadEta(*store_, EtaScope::kSweep, 1, 0, 2);
  ASSERT_TRUE(eta.ok()) << eta.status().ToString();
  ASSERT_TRUE(eta->has_value());
  const double bed_s = 6682 * kDefaultBedSecondsPerGrain, run_s = 100000 * 6683 * kDefaultSecondsPerParticleStep;
  EXPECT_NEAR((*eta)->seconds, bed_s + run_s, 1e-6);  // the bed, then the one run
  EXPECT_NE((*eta)->basis.find("beds"), std::string::npos);
}

TEST_F(CostModelTest, RatesComeFromDoneRunsAndRunningProgress) {
  Bed("done");
  Run(1, "done", 100000, 100000, 0, 0);
  Run(2, "done", 100000, 50000, 0, 0);
  Run(3, "running", 100000, 25000, 1000, 1025);  // 25,000 steps in 25 s: 1e-6 s a particle-step
  Run(4, "queued", 100000, 0, 0, 0);
  Result(1, 100000, 100);  // 1e8 particle-steps in 100 s
  Result(2, 50000, 50);
  auto model = ReadCostModel(*store_, 1030);  // its last heartbeat 5 s ago: an engine
  ASSERT_TRUE(model.ok()) << model.status().ToString();
  ASSERT_EQ(model->hosts.size(), 1u);
  EXPECT_EQ(model->hosts[0].host, "h");
  EXPECT_EQ(model->hosts[0].rate.samples, 2);
  EXPECT_DOUBLE_EQ(model->run_rate.s_per_unit, 1e-6);
  EXPECT_EQ(model->run_rate.samples, 3);
  EXPECT_EQ(model->run_rate.basis, "measured: 2 done runs and 1 running run");
  EXPECT_EQ(model->bed_rate.samples, 1);
  EXPECT_NEAR(model->bed_rate.s_per_unit, 0.1, 1e-12);
  EXPECT_EQ(model->engines_in_flight, 1);
  // Done runs used 75 % of their steps: the running run is past that (0 s left), the queued one
  // has 75,000 steps (75 s) left; over 2 engines, never less than the one run.
  auto eta = ReadEta(*store_, EtaScope::kSweep, 1, 2000, 2);
  ASSERT_TRUE(eta.ok()) << eta.status().ToString();
  ASSERT_TRUE(eta->has_value());
  EXPECT_NEAR((*eta)->seconds, 75, 1e-6);
  EXPECT_GT((*eta)->rel_error, kMinRateRelError);
  EXPECT_NE((*eta)->basis.find("75 %"), std::string::npos) << (*eta)->basis;
  // JSON: a 1-sigma band around the estimate.
  auto j = EtaJson(*eta);
  EXPECT_DOUBLE_EQ(j["s"].get<double>(), 75);
  EXPECT_LT(j["low_s"].get<double>(), 75);
  EXPECT_GT(j["high_s"].get<double>(), 75);
  // The band is a log-scale half-range: as wide on either side in ratio, never below 0.
  EXPECT_NEAR(j["low_s"].get<double>() * j["high_s"].get<double>(), 75.0 * 75.0, 1e-6);
  EXPECT_NEAR(j["high_s"].get<double>() / 75, std::exp((*eta)->rel_error), 1e-12);
  Eta wide = **eta;
  wide.rel_error = 1.5;
  EXPECT_GT(EtaJson(wide)["low_s"].get<double>(), 0);
}

// A running job counts as an engine only while it heartbeats: after a daemon restart a run whose
// worker died still holds a lease (extended over the outage) but no fresh heartbeat; a run just
// granted has none yet but its grant is fresh.
TEST_F(CostModelTest, OnlyRunningJobsThatHeartbeatAreEngines) {
  Bed("done");
  Run(1, "running", 100000, 25000, 1000, 1025);  // beat 5 s ago
  Run(2, "running", 100000, 40000, 0, 400);      // silent for 630 s
  Run(3, "running", 100000, 0, 1020, 0);         // granted 10 s ago, no heartbeat yet
  Run(4, "running", 100000, 0, 900, 0);          // granted 130 s ago, never heartbeated
  // Beds likewise, by their heartbeat_at.
  Exec("INSERT INTO beds (id, key, scale, state, created_at, started_at, heartbeat_at, deck) VALUES "
       "(2, 'b2', 'smoke', 'running', 0, 0, 1029, ''), (3, 'b3', 'smoke', 'running', 0, 0, 500, '')");
  auto model = ReadCostModel(*store_, 1030);
  ASSERT_TRUE(model.ok()) << model.status().ToString();
  EXPECT_EQ(model->engines_in_flight, 3);
  EXPECT_EQ(model->silent_jobs, 3);
  EXPECT_EQ(nlohmann::json(*model)["engines_silent"], 3);
  auto eta = ReadEta(*store_, EtaScope::kSweep, 1, 1030, 1);
  ASSERT_TRUE(eta.ok()) << eta.status().ToString();
  ASSERT_TRUE(eta->has_value());
  EXPECT_NE((*eta)->basis.find("; 3 engines (3 running jobs without a heartbeat for 60 s not counted)"),
            std::string::npos)
      << (*eta)->basis;
}

// A queued run with a precision target ends between its earliest target stop and its deck's end:
// before any run is done it is expected halfway, and the error says how wide that range is.
TEST_F(CostModelTest, ARunWithATargetIsExpectedHalfwayThroughItsRange) {
  Bed("done");
  Run(1, "queued", 500000, 0, 0, 0);
  // 3 Hz, at most 5 s: the earliest target stop is a one-period transient and 3 + 3 periods (7/3 s).
  Exec("UPDATE runs SET axis = 'x', duration_s = 5, run_duration_s = 5, precision = "
       "'{\"uz_rel\": 0.1, \"uz_abs\": 0, \"min_periods\": 3, \"max_duration_s\": 5}' WHERE id = 1");
  auto eta = ReadEta(*store_, EtaScope::kSweep, 1, 0, 2);
  ASSERT_TRUE(eta.ok()) << eta.status().ToString();
  ASSERT_TRUE(eta->has_value());
  const double min_steps = std::ceil(500000 * (7.0 / 3) / 5);
  const double s_per_step = 1000 * kDefaultSecondsPerParticleStep;
  EXPECT_NEAR((*eta)->seconds, (min_steps + 500000) / 2 * s_per_step, 1e-6);
  const double range_sigma = (500000 - min_steps) / std::sqrt(12.0) / ((min_steps + 500000) / 2);
  EXPECT_NEAR((*eta)->rel_error, std::hypot(kDefaultRateRelError, range_sigma), 1e-9);
  EXPECT_NE((*eta)->basis.find("halfway"), std::string::npos) << (*eta)->basis;
}

// Bed rates are kept per rank count: a bed prepared on 2 ranks (widened onto an idle slot) is
// faster and must not make the next one-rank bed look shorter (pooled, it did: up to 30 %). A bed
// prepared before ranks were recorded counts as one rank, and the basis says so.
TEST_F(CostModelTest, ATwoRankBedDoesNotChangeTheOneRankBedRate) {
  Bed("done");  // 999 grains in 99.9 s, ranks not recorded
  auto before = ReadCostModel(*store_, 0);
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  EXPECT_NEAR(before->bed_rate.s_per_unit, 0.1, 1e-12);
  EXPECT_NE(before->bed_rate.basis.find("1 of them prepared before ranks were recorded"), std::string::npos)
      << before->bed_rate.basis;
  Exec(
      "INSERT INTO beds (id, key, scale, state, grains, ranks, created_at, started_at, finished_at, deck) VALUES "
      "(2, 'b2', 'smoke', 'done', 999, 2, 0, 100, 169.93, '')");  // 0.07 s a grain
  auto after = ReadCostModel(*store_, 0);
  ASSERT_TRUE(after.ok()) << after.status().ToString();
  EXPECT_DOUBLE_EQ(after->bed_rate.s_per_unit, before->bed_rate.s_per_unit);
  EXPECT_EQ(after->bed_rate.samples, 1);
  ASSERT_EQ(after->bed_rates.size(), 2u);
  EXPECT_EQ(after->bed_rates[0].ranks, 1);
  EXPECT_EQ(after->bed_rates[1].ranks, 2);
  EXPECT_NEAR(after->bed_rates[1].rate.s_per_unit, 0.07, 1e-9);
  EXPECT_EQ(after->bed_rates[1].rate.basis, "measured: 1 done bed on 2 ranks");
  nlohmann::json j = *after;
  EXPECT_EQ(j["bed_rates"][1]["ranks"], 2);
  EXPECT_NEAR(j["bed_rate"]["s_per_unit"].get<double>(), 0.1, 1e-12);
  // The lease's wall budget and the ETA of a queued bed use the one-rank rate (a worker may not widen it).
  auto t = store_->db().BeginRead();
  ASSERT_TRUE(t.ok());
  auto one = BedRate(*t, 1), two = BedRate(*t, 2);
  ASSERT_TRUE(one.ok() && two.ok());
  EXPECT_NEAR(one->s_per_unit, 0.1, 1e-12);
  EXPECT_NEAR(two->s_per_unit, 0.07, 1e-9);
  // A rank count no bed was measured on: the one-rank rate over 1.42 a doubling, said in the basis.
  auto four = BedRate(*t, 4);
  ASSERT_TRUE(four.ok());
  EXPECT_NEAR(four->s_per_unit, 0.1 / (kDefaultTwoRankSpeedup * kDefaultTwoRankSpeedup), 1e-12);
  EXPECT_GT(four->rel_error, one->rel_error);
  EXPECT_NE(four->basis.find("no bed measured on 4"), std::string::npos) << four->basis;
}

TEST_F(CostModelTest, AFinishedSweepHasNoEta) {
  Bed("done");
  Run(1, "done", 100000, 100000, 0, 0);
  Result(1, 100000, 100);
  auto eta = ReadEta(*store_, EtaScope::kSweep, 1, 0, 2);
  ASSERT_TRUE(eta.ok());
  EXPECT_FALSE(eta->has_value());
  EXPECT_TRUE(EtaJson(*eta).is_null());
}

}  // namespace
}  // namespace sandswim
