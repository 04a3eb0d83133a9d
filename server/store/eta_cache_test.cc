#include "server/store/eta_cache.h"

#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "server/store/store.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

// Rows written directly, as in cost_model_test.cc: a done bed of 999 grains and a sweep on it.
class EtaCacheTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(store_);
    Exec("INSERT INTO beds (id, key, scale, state, grains, created_at, started_at, finished_at, deck) VALUES (1, 'b', "
         "'smoke', 'done', 999, 0, 0, 99.9, '')");
    Exec("INSERT INTO sweeps (id, name, scale, spec, created_at) VALUES (1, 's', 'smoke', '{}', 0)");
    for (int id = 1; id <= 3; ++id) Run(id, "queued");
  }
  void Exec(const std::string& sql) {
    auto t = store_->db().Begin();
    ASSERT_TRUE(t.ok());
    Status s = t->Exec(sql);
    ASSERT_TRUE(s.ok()) << s.ToString() << "\n" << sql;
    ASSERT_TRUE(t->Commit().ok());
  }
  void Run(int id, const std::string& state) {
    const std::string n = std::to_string(id);
    Exec("INSERT INTO runs (id, key, bed_id, mode, A, f, osc_omega, rot_omega, axis, duration_s, run_duration_s, "
         "steps, state, created_at, queued_at, step) VALUES (" + n + ", 'r" + n +
         "', 1, 'oscillatory', 0.03, 3, -80, 0, '', 1, 1, 100000, '" + state + "', 0, 0, 0)");
    Exec("INSERT INTO sweep_runs (sweep_id, run_id, position) VALUES (1, " + n + ", " + n + ")");
  }
  // Run `id` ends: its state and its result (100,000 steps in 100 s), one commit each.
  void Finish(int id) {
    const std::string n = std::to_string(id);
    Exec("UPDATE runs SET state = 'done' WHERE id = " + n);
    Exec("INSERT INTO results (run_id, window_t0, window_t1, dz, z_osc_amplitude, x_drift, broke_surface, near_floor, "
         "stop_reason, sim_time_s, steps, grains, z0, engine_version, host, ranks, launcher, wall_s, cpu_s, key, "
         "created_at) VALUES (" + n + ", 0, 1, 0, 0, 0, 0, 0, 'target', 1, 100000, 999, 0, 'v', 'h', 1, 'mpirun', "
         "100, 0, 'r" + n + "', 0)");
  }
  double Seconds(EtaCache& cache, double now) {
    auto eta = cache.Get(EtaScope::kSweep, 1, now, 1);
    EXPECT_TRUE(eta.ok()) << eta.status().ToString();
    if (!eta.ok() || !eta->has_value()) return -1;
    return (*eta)->seconds;
  }
  testing::TempStore store_{"eta-cache", "test.db"};
};

TEST_F(EtaCacheTest, AnAnswerIsReadOnceWhileNothingIsWritten) {
  EtaCache cache(store_.get(), /*max_age_s=*/1.0, /*min_refresh_s=*/0.25);
  const double first = Seconds(cache, 100);
  auto direct = ReadEta(*store_, EtaScope::kSweep, 1, 100, 1);
  ASSERT_TRUE(direct.ok() && direct->has_value());
  EXPECT_DOUBLE_EQ(first, (*direct)->seconds);  // the same answer as a read
  for (double now : {100.0, 100.1, 100.5, 100.99}) EXPECT_DOUBLE_EQ(Seconds(cache, now), first);
  EXPECT_EQ(cache.reads(), 1u);
}

TEST_F(EtaCacheTest, ACompletionIsSeenOnceTheAnswerIsMinRefreshOld) {
  EtaCache cache(store_.get(), 1.0, 0.25);
  const double three_left = Seconds(cache, 100);
  Finish(1);
  // Within min_refresh_s of the read the previous answer stands (the bound the header states)...
  EXPECT_DOUBLE_EQ(Seconds(cache, 100.1), three_left);
  EXPECT_EQ(cache.reads(), 1u);
  // ...past it, the write makes the next call read again.
  const double two_left = Seconds(cache, 100.25);
  EXPECT_EQ(cache.reads(), 2u);
  EXPECT_NE(two_left, three_left);  // one run fewer, at the measured rate instead of the default
  auto direct = ReadEta(*store_, EtaScope::kSweep, 1, 100.25, 1);
  ASSERT_TRUE(direct.ok() && direct->has_value());
  EXPECT_DOUBLE_EQ(two_left, (*direct)->seconds);
  // The last runs end: nothing is left, and the cache says so.
  Finish(2);
  Finish(3);
  auto none = cache.Get(EtaScope::kSweep, 1, 100.5, 1);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
}

TEST_F(EtaCacheTest, EveryKindOfWriteInvalidates) {
  EtaCache cache(store_.get(), 1.0, 0.25);
  double last = Seconds(cache, 100);
  // A cancel, a heartbeat's progress, a new run: each a commit, each seen at the next refresh,
  // where the cache answers what a read at that time answers.
  const std::vector<std::function<void()>> writes = {
      [&] { Exec("UPDATE runs SET state = 'cancelled' WHERE id = 3"); },
      [&] { Exec("UPDATE runs SET state = 'running', step = 90000, started_at = 50, heartbeat_at = 100 WHERE id = 2"); },
      [&] { Run(4, "queued"); },
  };
  double now = 100;
  for (const auto& write : writes) {
    write();
    now += 0.3;
    const double seen = Seconds(cache, now);
    auto direct = ReadEta(*store_, EtaScope::kSweep, 1, now, 1);
    ASSERT_TRUE(direct.ok() && direct->has_value());
    EXPECT_DOUBLE_EQ(seen, (*direct)->seconds);
    EXPECT_NE(seen, last);
    last = seen;
  }
  EXPECT_EQ(cache.reads(), 4u);
}

TEST_F(EtaCacheTest, TheClockAloneEndsAnAnswerAtMaxAge) {
  EtaCache cache(store_.get(), 1.0, 0.25);
  Seconds(cache, 100);
  Seconds(cache, 100.9);
  EXPECT_EQ(cache.reads(), 1u);
  Seconds(cache, 101);  // nothing written, but a running job's elapsed time moves the ETA
  EXPECT_EQ(cache.reads(), 2u);
  Seconds(cache, 50);  // a clock set back: read again
  EXPECT_EQ(cache.reads(), 3u);
}

TEST_F(EtaCacheTest, ScopesAndSlotsAreKeptApart) {
  EtaCache cache(store_.get(), 1.0, 0.25);
  auto one = cache.Get(EtaScope::kSweep, 1, 100, 1);
  auto three = cache.Get(EtaScope::kSweep, 1, 100, 3);
  auto other = cache.Get(EtaScope::kCampaignRun, 1, 100, 1);
  ASSERT_TRUE(one.ok() && three.ok() && other.ok());
  EXPECT_EQ(cache.reads(), 3u);
  ASSERT_TRUE(one->has_value() && three->has_value());
  EXPECT_GT((*one)->seconds, (*three)->seconds);  // three runs over one engine, then over three
  EXPECT_FALSE(other->has_value());               // no campaign run 1
}

TEST_F(EtaCacheTest, CommitsCountEveryWriteTransaction) {
  const uint64_t before = store_->db().commits();
  Exec("UPDATE runs SET step = 1 WHERE id = 1");
  EXPECT_EQ(store_->db().commits(), before + 1);
  ASSERT_TRUE(store_->db().Write([](Transaction& t) { return t.Exec("UPDATE runs SET step = 2 WHERE id = 1"); }).ok());
  EXPECT_EQ(store_->db().commits(), before + 2);
  auto read = store_->db().BeginRead();  // a read of a file database commits nothing on the writer
  ASSERT_TRUE(read.ok());
  EXPECT_EQ(store_->db().commits(), before + 2);
}

}  // namespace
}  // namespace sandswim
