#include "server/store/store.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <filesystem>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/result_fields_test_util.h"
#include "core/trajectory.h"
#include "platform/clock.h"
#include "server/jobs/submission.h"
#include "server/store/campaigns.h"
#include "server/store/cost_model.h"
#include "server/store/job_table.h"
#include "server/store/result_columns.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

namespace fs = std::filesystem;

class StoreTest : public ::testing::Test {
 protected:
  // The store's file opened (again: a store a test opened before is closed first); nullptr and a
  // test failure when it does not open.
  Store* MustOpen() { return temp_.Reopen() ? temp_.get() : nullptr; }
  // Not opened until a test does: opening (a directory made, migrations run) is what some test.
  testing::TempStore temp_{"store", "nested/sandswim.db", /*open=*/false};
};

nlohmann::json Sweep(const std::string& name, int points) {
  std::vector<double> omegas;
  for (int i = 0; i < points; ++i) omegas.push_back(10 + 10 * i);
  return {{"name", name},
          {"scale", "smoke"},
          {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", 10}, {"duration_s", 0.3}}},
          {"axes", {{{"param", "Omega"}, {"values", omegas}}}}};
}

TEST_F(StoreTest, OpenCreatesTheDirectoryAndMigratesOnce) {
  {
    auto store = MustOpen();
    ASSERT_TRUE(store);
    // Every migration of schema/ (001, 002, 003, ...) applied once.
    EXPECT_GE(store->db().schema_version(), 3);
    EXPECT_EQ(*store->db().CountRows("schema_migrations"), store->db().schema_version());
    EXPECT_TRUE(store->db().HealthCheck().ok());
  }
  auto again = MustOpen();
  ASSERT_TRUE(again);
  EXPECT_EQ(*again->db().CountRows("schema_migrations"), again->db().schema_version());
  auto t = again->db().BeginRead();
  ASSERT_TRUE(t.ok());
  Statement st = t->Prepare("PRAGMA journal_mode");
  ASSERT_TRUE(*st.Step());
  EXPECT_EQ(st.Text(0), "wal");
  Statement fk = t->Prepare("PRAGMA foreign_keys");
  ASSERT_TRUE(*fk.Step());
  EXPECT_EQ(fk.Int(0), 1);
}

TEST_F(StoreTest, RefusesAFileFromANewerSchema) {
  {
    auto store = MustOpen();
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Exec("PRAGMA user_version = 99").ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  temp_.reset();
  auto s = Store::Open(temp_.path());
  EXPECT_EQ(s.status().code(), StatusCode::kFailedPrecondition);
}

// A database from before migration 7 (results of the old estimator, analysis 1): the upgrade keeps
// every row and marks it; the daemon's start-up re-analysis recomputes each result that has a
// stored trajectory, and leaves one without a trajectory visibly inconclusive.
// One result with a trajectory, and more without one than a page of the re-analysis holds.
// Every schema/NNN_*.sql in the source tree is compiled in, numbered 1, 2, ... without gaps: adding
// a migration is adding its file.
TEST(MigrationsTest, EveryMigrationFileIsCompiledInAndNumberedInOrder) {
  std::vector<std::string> on_disk;
  for (const auto& e : fs::directory_iterator(std::string(SANDSWIM_SOURCE_DIR) + "/schema")) {
    const std::string name = e.path().filename().string();
    if (name.size() > 8 && std::isdigit(static_cast<unsigned char>(name[0])) && e.path().extension() == ".sql") {
      on_disk.push_back("schema/" + name);
    }
  }
  std::sort(on_disk.begin(), on_disk.end());
  std::vector<Migration> migrations = Migrations();
  ASSERT_EQ(migrations.size(), on_disk.size());
  for (size_t i = 0; i < migrations.size(); ++i) {
    EXPECT_EQ(migrations[i].file, on_disk[i]);
    EXPECT_EQ(migrations[i].version, static_cast<int>(i) + 1);
  }
}

TEST_F(StoreTest, ResultsOfTheOldEstimatorAreMigratedAndReanalysed) {
  constexpr int kOld = 450;
  int64_t with_trajectory = 0, without = 0;
  std::vector<int64_t> ids;
  {
    auto store = MustOpen();
    auto req = ParseSubmitRequest(Sweep("old", kOld));
    auto sub = Submit(*store, *req, "engine", 1.7e9);
    ASSERT_TRUE(sub.ok()) << sub.status().ToString();
    RunFilter all;
    all.limit = kOld;
    auto runs = store->ListRuns(all);
    ASSERT_EQ(runs->runs.size(), static_cast<size_t>(kOld));
    for (const auto& r : runs->runs) ids.push_back(r.id);
    with_trajectory = runs->runs[0].id;
    without = runs->runs[1].id;
    // Back to schema 6: its results table, two results of analysis 1, one with a trajectory.
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Exec("DROP TABLE results; DELETE FROM schema_migrations WHERE version >= 7; PRAGMA user_version = 6;"
                        "ALTER TABLE runs DROP COLUMN precision; ALTER TABLE runs DROP COLUMN snapshots;"
                        "ALTER TABLE runs DROP COLUMN materials; ALTER TABLE runs DROP COLUMN dt_s;"
                        "DROP TABLE campaign_versions; ALTER TABLE campaigns DROP COLUMN version;"
                        "ALTER TABLE campaign_runs DROP COLUMN campaign_version;"
                        "ALTER TABLE campaign_runs DROP COLUMN definition;"
                        "ALTER TABLE campaign_runs DROP COLUMN definition_sha256;"
                        "ALTER TABLE campaign_schedules DROP COLUMN source;"
                        "DROP TABLE snapshots;"
                        "DROP TABLE campaign_rounds; DROP TABLE campaign_run_verdicts; DROP TABLE campaign_run_charges; DROP TABLE campaign_run_replacements;"
                        "ALTER TABLE beds DROP COLUMN heartbeat_at; DROP TABLE run_progress;"
                        "DROP INDEX leases_by_job; ALTER TABLE leases DROP COLUMN closed_at; "
                        "ALTER TABLE leases DROP COLUMN sim_time_s;"
                        "ALTER TABLE leases DROP COLUMN payer_campaign_run_id; ALTER TABLE leases DROP COLUMN payer_decided;"
                        "ALTER TABLE beds DROP COLUMN replicate; ALTER TABLE beds DROP COLUMN seed_pour1;"
                        "ALTER TABLE beds DROP COLUMN seed_pour2; ALTER TABLE beds DROP COLUMN ranks;"
                        "CREATE TABLE results (run_id INTEGER PRIMARY KEY REFERENCES runs (id), uz REAL NOT NULL, "
                        "uz_stderr REAL NOT NULL, window_t0 REAL NOT NULL, window_t1 REAL NOT NULL, dz REAL NOT NULL, "
                        "z_osc_amplitude REAL NOT NULL, x_drift REAL NOT NULL, broke_surface INTEGER NOT NULL, "
                        "near_floor INTEGER NOT NULL, stop_reason TEXT NOT NULL, sim_time_s REAL NOT NULL, steps "
                        "INTEGER NOT NULL, "
                        "grains INTEGER NOT NULL, z0 REAL NOT NULL, engine_version TEXT NOT NULL, host TEXT NOT NULL, "
                        "ranks INTEGER NOT NULL, launcher TEXT NOT NULL, wall_s REAL NOT NULL, cpu_s REAL NOT NULL, "
                        "key TEXT NOT NULL, created_at REAL NOT NULL, lease_to_start_s REAL);"
                        "UPDATE beds SET state = 'done', result = '{\"grain_top\": 0.9}';"
                        "UPDATE runs SET state = 'done';")
                    .ok());
    for (int64_t id : ids) {
      ASSERT_TRUE(t->Exec("INSERT INTO results VALUES (" + std::to_string(id) +
                          ", -0.0066, 0.0002, 0.3333, 0.6667, 0.001, 0.004, 0, 0, 0, 'duration', 1.0, 100000, "
                          "5000, 0, 'engine', 'h', 1, 'mpirun', 60, 60, 'k', 1.7e9, 0.1)")
                      .ok());
    }
    // z = 0.03 t + 0.004 sin(4 pi f t) at 3 Hz over 1 s, every 1 ms: 2 whole periods after one.
    api::Trajectory tr;
    for (int i = 0; i <= 1000; ++i) {
      double time = i * 1e-3;
      tr.t.push_back(time);
      tr.x.push_back(0);
      tr.y.push_back(0);
      tr.z.push_back(0.03 * time + 0.004 * std::sin(2 * 3.14159265358979 * 6 * time));
    }
    Statement st = t->Prepare("INSERT INTO trajectories (run_id, data) VALUES (?, ?)");
    st.Bind(1, with_trajectory).Bind(2, nlohmann::json(tr).dump());
    ASSERT_TRUE(st.Run().ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  auto store = MustOpen();
  ASSERT_TRUE(store);
  EXPECT_EQ(store->db().schema_version(), static_cast<int>(Migrations().size()));  // every migration applied
  EXPECT_EQ(*store->db().CountRows("results"), kOld);
  auto before = store->GetRun(without);
  ASSERT_TRUE(before->result.has_value());
  EXPECT_EQ(before->result->result.analysis, 1);
  EXPECT_FALSE(before->result->result.conclusive);
  EXPECT_EQ(before->result->result.uz, -0.0066);  // kept, never shown as a result of this analysis

  auto re = store->ReanalyzeOldResults();
  ASSERT_TRUE(re.ok()) << re.status().ToString();
  EXPECT_EQ(re->reanalysed, 1);
  EXPECT_EQ(re->kept_old, kOld - 1);
  const api::RunResult fresh = store->GetRun(with_trajectory)->result->result;
  EXPECT_EQ(fresh.analysis, api::kAnalysisVersion);
  EXPECT_TRUE(fresh.conclusive);
  EXPECT_EQ(fresh.uz_blocks, 2);
  ASSERT_TRUE(fresh.uz.has_value());
  EXPECT_NEAR(*fresh.uz, 0.03, 1e-4);
  EXPECT_EQ(fresh.grains, 5000);
  EXPECT_EQ(fresh.analysed_from, "trajectory");
  const api::RunResult kept = store->GetRun(without)->result->result;
  EXPECT_EQ(kept.analysis, 1);
  EXPECT_NE(kept.inconclusive_reason.find("old estimator"), std::string::npos);
  EXPECT_NE(kept.inconclusive_reason.find("cannot be re-analysed: no stored trajectory"), std::string::npos)
      << kept.inconclusive_reason;
  EXPECT_EQ(kept.analysed_from, "unreadable");
  EXPECT_EQ(DescribeUz(kept), "old estimator (-0.007 m/s)");
  // Idempotent, and a result that cannot be re-analysed is not tried again at the next start.
  auto again = store->ReanalyzeOldResults();
  EXPECT_EQ(again->reanalysed, 0);
  EXPECT_EQ(again->kept_old, 0);
}

// Analysis 3 changed only the runs ended by their precision target: such a result of analysis 2
// keeps its rate but loses its interval (its stop was chosen on it: optional stopping); any other
// keeps its numbers, marked as this analysis's.
TEST_F(StoreTest, ResultsOfAnalysis2AreReanalysedOnlyWhereATargetEndedThem) {
  auto store = MustOpen();
  ASSERT_TRUE(store);
  auto req = ParseSubmitRequest(Sweep("v2", 2));
  ASSERT_TRUE(req.ok()) << req.status().ToString();
  ASSERT_TRUE(Submit(*store, *req, "engine", 1.7e9).ok());
  RunFilter all;
  auto runs = store->ListRuns(all);
  ASSERT_EQ(runs->runs.size(), 2u);
  const int64_t stopped = runs->runs[0].id, whole = runs->runs[1].id;
  // At 3 Hz: a still transient period, a pilot of 3 periods (rates 0.012, 0.060, 0.054 m/s), then
  // 12 periods at 0.036 m/s; every 1 ms.
  const std::vector<double> advances = {0.004, 0.020, 0.018, 0.012, 0.012, 0.012, 0.012, 0.012,
                                        0.012, 0.012, 0.012, 0.012, 0.012, 0.012, 0.012};
  api::Trajectory tr;
  for (int i = 0; i <= 5340; ++i) {
    const double time = i * 1e-3, periods = time * 3;
    const int k = static_cast<int>(std::floor(periods)) - 1;  // the period after the transient
    double z = 0;
    for (int j = 0; j < k && j < static_cast<int>(advances.size()); ++j) z += advances[j];
    if (k >= 0 && k < static_cast<int>(advances.size())) z += advances[k] * (periods - std::floor(periods));
    tr.t.push_back(time);
    tr.x.push_back(0);
    tr.y.push_back(0);
    tr.z.push_back(z);
  }
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Exec("UPDATE beds SET state = 'done', result = '{\"grain_top\": 0.9}'; UPDATE runs SET state = "
                        "'done'; UPDATE runs SET precision = '{\"uz_rel\": 0.5, \"uz_abs\": 0, \"min_periods\": 3, "
                        "\"max_duration_s\": 10}' WHERE id = " +
                        std::to_string(stopped))
                    .ok());
    for (int64_t id : {stopped, whole}) {
      ASSERT_TRUE(t->Exec("INSERT INTO results (run_id, uz, uz_stderr, uz_ci95, uz_blocks, block_s, block_kind, "
                          "window_t0, window_t1, window_end, conclusive, dz, dz_rate, z_osc_amplitude, x_drift, "
                          "broke_surface, near_floor, stop_reason, sim_time_s, steps, grains, z0, analysis, "
                          "engine_version, host, ranks, launcher, wall_s, cpu_s, key, created_at) VALUES (" +
                          std::to_string(id) + ", 0.0385, 0.001, 0.002, 15, 0.3333, 'period', 0.3333, 5.3333, "
                          "'run_end', 1, 0.2, 0.0375, 0.001, 0, 0, 0, '" +
                          (id == stopped ? "target" : "duration") +
                          "', 5.34, 534000, 5000, 0, 2, 'engine', 'h', 1, 'mpirun', 60, 60, 'k', 1.7e9)")
                      .ok());
    }
    Statement st = t->Prepare("INSERT INTO trajectories (run_id, data) VALUES (?, ?)");
    st.Bind(1, stopped).Bind(2, nlohmann::json(tr).dump());
    ASSERT_TRUE(st.Run().ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  auto re = store->ReanalyzeOldResults();
  ASSERT_TRUE(re.ok()) << re.status().ToString();
  EXPECT_EQ(re->reanalysed, 1);
  EXPECT_EQ(re->unchanged, 1);
  EXPECT_EQ(re->kept_old, 0);
  const api::RunResult fresh = store->GetRun(stopped)->result->result;
  EXPECT_EQ(fresh.analysis, api::kAnalysisVersion);
  EXPECT_EQ(fresh.analysed_from, "trajectory");
  EXPECT_EQ(fresh.uz_blocks, 15);  // every block: no two-stage pilot to leave out
  ASSERT_TRUE(fresh.uz.has_value());
  EXPECT_NEAR(*fresh.uz, (0.004 + 0.020 + 0.018 + 12 * 0.012) / 5, 1e-4);
  EXPECT_FALSE(fresh.uz_stderr.has_value());
  EXPECT_FALSE(fresh.uz_ci95.has_value());
  EXPECT_NE(fresh.uz_stderr_note.find("optional stopping"), std::string::npos) << fresh.uz_stderr_note;
  EXPECT_EQ(fresh.precision_met, false);
  // Analysis 3 changed none of its numbers: it keeps them and becomes a result of analysis 3, which
  // analysis 4 (a transient in seconds, the trend test, x's amplitude) leaves as it is: its
  // numbers stand for its one-period window, it says its analysis, and has no trend test or x
  // amplitude (a rerun with --force gets them).
  const api::RunResult kept = store->GetRun(whole)->result->result;
  EXPECT_EQ(kept.analysis, 3);
  EXPECT_EQ(kept.analysed_from, "dump");
  EXPECT_EQ(kept.uz, 0.0385);
  EXPECT_EQ(kept.uz_ci95, 0.002);
  EXPECT_TRUE(kept.conclusive);
  EXPECT_FALSE(kept.x_osc_amplitude);
  EXPECT_FALSE(kept.trend_p);
  EXPECT_FALSE(kept.trending);
  EXPECT_EQ(DescribeUz(kept), "0.0385 ± 0.0010 m/s, 15 periods (analysis 3)");
  // Idempotent.
  auto again = store->ReanalyzeOldResults();
  EXPECT_EQ(again->reanalysed + again->unchanged + again->kept_old, 0);
}

TEST_F(StoreTest, TransactionRollsBackUnlessCommitted) {
  auto store = MustOpen();
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Event(1, "test", "x/1").ok());
  }
  EXPECT_EQ(*store->db().CountRows("events"), 0);
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Event(1, "test", "x/1").ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  EXPECT_EQ(*store->db().CountRows("events"), 1);
  auto t = store->db().Begin();
  Statement bad = t->Prepare("SELECT nope FROM nowhere");
  EXPECT_FALSE(bad.Step().ok());
}

// A backup taken while another thread keeps committing: the copy opens, passes integrity_check,
// and holds a prefix of the writes (every committed event up to some point, none half-written).
// Whether the writer gets in between the copy's steps is up to the scheduler: not asserted. A backup to a directory
// that does not exist fails and leaves nothing.
TEST_F(StoreTest, BackupWhileWritingIsAConsistentCopy) {
  auto store = MustOpen();
  {  // about 4 MB: the copy takes several steps of 256 pages
    auto t = store->db().Begin();
    for (int i = 0; i < 4000; ++i) {
      ASSERT_TRUE(t->Event(i, "seed", "x/" + std::to_string(i), {{"pad", std::string(1000, 'x')}}).ok());
    }
    ASSERT_TRUE(t->Commit().ok());
  }
  std::atomic<bool> stop{false};
  std::atomic<int> written{0};
  std::thread writer([&] {
    for (int i = 0; !stop; ++i) {
      Status s = store->db().Write([&](Transaction& t) { return t.Event(i, "during", "y/" + std::to_string(i)); });
      if (s.ok()) ++written;
    }
  });
  const std::string copy = (temp_.dir() / "copy.db").string();
  Result<int64_t> bytes = store->db().BackupTo(copy);
  const int during_backup = written.load();
  stop = true;
  writer.join();
  ASSERT_TRUE(bytes.ok()) << bytes.status().ToString();
  EXPECT_EQ(*bytes, static_cast<int64_t>(fs::file_size(copy)));
  EXPECT_FALSE(fs::exists(copy + ".partial"));
  auto restored = Store::Open(copy);
  ASSERT_TRUE(restored.ok()) << restored.status().ToString();
  {
    auto t = (*restored)->db().BeginRead();
    ASSERT_TRUE(t.ok());
    Statement check = t->Prepare("PRAGMA integrity_check");
    ASSERT_TRUE(*check.Step());
    EXPECT_EQ(check.Text(0), "ok");
    Statement during = t->Prepare(
        "SELECT count(*), COALESCE(max(CAST(substr(subject, 3) AS INTEGER)), -1) "
        "FROM events WHERE kind = 'during'");
    ASSERT_TRUE(*during.Step());
    // A prefix: the events written during the backup are 0..n-1 with no gap.
    EXPECT_EQ(during.Int(1), during.Int(0) - 1);
    EXPECT_LE(during.Int(0), during_backup + 1);
  }
  EXPECT_GE(*(*restored)->db().CountRows("events"), 4000);

  Result<int64_t> bad = store->db().BackupTo((temp_.dir() / "no-such-dir" / "copy.db").string());
  EXPECT_FALSE(bad.ok());
  EXPECT_NE(bad.status().ToString().find("check that the directory exists"), std::string::npos)
      << bad.status().ToString();
  EXPECT_FALSE(fs::exists(temp_.dir() / "no-such-dir"));
}

TEST_F(StoreTest, ListRunsPagesByCursorAndFilters) {
  auto store = MustOpen();
  auto req = ParseSubmitRequest(Sweep("five", 5));
  auto sub = Submit(*store, *req, "engine", 1.7e9);
  ASSERT_TRUE(sub.ok()) << sub.status().ToString();
  auto req2 = ParseSubmitRequest(Sweep("two", 2));
  ASSERT_TRUE(Submit(*store, *req2, "engine", 1.7e9).ok());

  RunFilter f;
  f.sweep_id = sub->sweep_ids[0];
  f.limit = 2;
  std::vector<int64_t> seen;
  for (int page = 0; page < 5; ++page) {
    auto p = store->ListRuns(f);
    ASSERT_TRUE(p.ok());
    for (const RunSummary& r : p->runs) seen.push_back(r.id);
    if (!p->next_cursor) break;
    f.after_id = *p->next_cursor;
  }
  EXPECT_EQ(seen.size(), 5u);
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));

  RunFilter all;
  all.state = JobState::kQueued;
  EXPECT_EQ(store->ListRuns(all)->runs.size(), 5u);  // the two are shared with "five"
  all.state = JobState::kDone;
  EXPECT_TRUE(store->ListRuns(all)->runs.empty());

  auto page = store->ListSweeps(0, 1);
  ASSERT_EQ(page->sweeps.size(), 1u);
  ASSERT_TRUE(page->next_cursor.has_value());
  EXPECT_EQ(store->ListSweeps(*page->next_cursor, 1)->sweeps[0].name, "two");
  nlohmann::json j = *page;
  EXPECT_EQ(j["sweeps"][0]["counts"]["queued"], 5);
  EXPECT_EQ(j["sweeps"][0]["runs"], 5);

  // A state that is no JobState cannot be asked for: the route refuses it (routes_test
  // ListRunsPagesWithCursorRoundTrip), and a state column whose text is none is Corruption, never a default.
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Exec("PRAGMA ignore_check_constraints = ON; UPDATE runs SET state = 'finished' WHERE id = " +
                        std::to_string(seen.front()) + "; PRAGMA ignore_check_constraints = OFF")
                    .ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  auto corrupt = store->GetRun(seen.front());
  ASSERT_FALSE(corrupt.ok());
  EXPECT_EQ(corrupt.status().code(), StatusCode::kCorruption);
  EXPECT_NE(corrupt.status().reason().find("'finished', which is not a job state"), std::string::npos)
      << corrupt.status().ToString();
  EXPECT_EQ(store->ListRuns(RunFilter{}).status().code(), StatusCode::kCorruption);
  EXPECT_EQ(store->GetMetrics().status().code(), StatusCode::kCorruption);
  // The ETA reads the beds' state column too (its SQL keeps only queued and running runs): a bed it
  // cannot place is an error, not a bed left out of the work left.
  EXPECT_TRUE(ReadEta(*store, EtaScope::kSweep, sub->sweep_ids[0], 1.7e9, 1).ok());
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t->Exec("PRAGMA ignore_check_constraints = ON; UPDATE beds SET state = 'finished'; "
                        "PRAGMA ignore_check_constraints = OFF")
                    .ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  EXPECT_EQ(ReadEta(*store, EtaScope::kSweep, sub->sweep_ids[0], 1.7e9, 1).status().code(), StatusCode::kCorruption);
}

// Every row of `of` `id`, read `limit` rows a page; fails the test on an error.
std::vector<ResultRow> AllPages(Store& store, ResultsOf of, int64_t id, int limit, int* pages) {
  std::vector<ResultRow> out;
  ResultCursor after;
  *pages = 0;
  for (;;) {
    auto page = store.ResultsPage(of, id, after, limit);
    EXPECT_TRUE(page.ok()) << page.status().ToString();
    if (!page.ok() || ++*pages > 100) break;
    EXPECT_LE(static_cast<int>(page->rows.size()), limit);
    for (ResultRow& r : page->rows) out.push_back(std::move(r));
    if (!page->next) break;
    after = *page->next;
  }
  return out;
}

std::vector<int64_t> RunIds(const std::vector<ResultRow>& rows) {
  std::vector<int64_t> ids;
  for (const ResultRow& r : rows) ids.push_back(r.run_id);
  return ids;
}

TEST_F(StoreTest, ResultsPagesOfASweepFollowItsExpansionOrder) {
  auto store = MustOpen();
  auto req = ParseSubmitRequest(Sweep("two", 2));  // Omega 10, 20: runs made first
  ASSERT_TRUE(Submit(*store, *req, "engine", 1.7e9).ok());
  req = ParseSubmitRequest(Sweep("five", 5));  // Omega 10..50: its first two runs are older than the rest
  auto sub = Submit(*store, *req, "engine", 1.7e9);
  ASSERT_TRUE(sub.ok()) << sub.status().ToString();
  const int64_t sweep = sub->sweep_ids[0];
  auto whole = store->SweepResults(sweep);
  ASSERT_TRUE(whole.ok());
  ASSERT_EQ(whole->size(), 5u);
  for (int limit : {1, 2, 5, 6}) {
    int pages = 0;
    EXPECT_EQ(RunIds(AllPages(*store, ResultsOf::kSweep, sweep, limit, &pages)), RunIds(*whole)) << limit;
    EXPECT_EQ(pages, (5 + limit - 1) / limit) << limit;  // the last page says there is no next
  }
  auto first = store->ResultsPage(ResultsOf::kSweep, sweep, {}, 2);
  ASSERT_TRUE(first.ok() && first->next.has_value());
  EXPECT_EQ(first->rows[0].point.Omega, 10);
  EXPECT_EQ(first->rows[1].point.Omega, 20);
  EXPECT_TRUE(first->rows[0].sweeps.empty());
  EXPECT_EQ(store->ResultsPage(ResultsOf::kSweep, 12345, {}, 10).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store->ResultsPage(ResultsOf::kCampaignRun, 12345, {}, 10).status().code(), StatusCode::kNotFound);
}

TEST_F(StoreTest, ResultsPagesOfACampaignRunShowEachRunOnceWithItsSweeps) {
  auto store = MustOpen();
  auto sweep = [](const std::string& name, std::vector<double> omegas) {
    nlohmann::json s = Sweep(name, 1);
    s.erase("scale");
    s["axes"][0]["values"] = omegas;
    return s;
  };
  StoredCampaign c;
  c.name = "overlap";
  c.definition = {{"name", "overlap"},
                  {"description", "two sweeps that share two runs"},
                  {"scale", "smoke"},
                  {"sweeps", {sweep("early", {10, 20, 30, 40}), sweep("late", {40, 30, 60, 70})}}};
  ASSERT_TRUE(PutCampaign(*store, c).ok());
  SubmitRequest request;
  request.campaign = "overlap";
  auto sub = Submit(*store, request, "engine", 1.7e9);
  ASSERT_TRUE(sub.ok()) << sub.status().ToString();
  ASSERT_TRUE(sub->campaign_run_id.has_value());
  int pages = 0;
  const std::vector<ResultRow> all = AllPages(*store, ResultsOf::kCampaignRun, *sub->campaign_run_id, 100, &pages);
  ASSERT_EQ(all.size(), 6u);
  std::vector<double> omegas;
  for (const ResultRow& r : all) omegas.push_back(r.point.Omega);
  EXPECT_EQ(omegas, (std::vector<double>{10, 20, 30, 40, 60, 70}));
  EXPECT_EQ(all[0].sweeps, (std::vector<std::string>{"early"}));
  EXPECT_EQ(all[2].sweeps, (std::vector<std::string>{"early", "late"}));
  EXPECT_EQ(all[3].sweeps, (std::vector<std::string>{"early", "late"}));
  EXPECT_EQ(all[4].sweeps, (std::vector<std::string>{"late"}));
  for (int limit : {1, 3, 4}) {
    EXPECT_EQ(RunIds(AllPages(*store, ResultsOf::kCampaignRun, *sub->campaign_run_id, limit, &pages)), RunIds(all))
        << limit;
    EXPECT_EQ(pages, (6 + limit - 1) / limit) << limit;
  }
}

TEST_F(StoreTest, GetRunHasDeckAndSweepsAndNotFoundIsReported) {
  auto store = MustOpen();
  auto req = ParseSubmitRequest(Sweep("one", 1));
  auto sub = Submit(*store, *req, "engine", 1.7e9);
  ASSERT_TRUE(sub.ok());
  auto runs = store->ListRuns({});
  auto run = store->GetRun(runs->runs[0].id);
  ASSERT_TRUE(run.ok()) << run.status().ToString();
  EXPECT_FALSE(run->deck.empty());
  EXPECT_EQ(run->sweep_ids, sub->sweep_ids);
  EXPECT_EQ(run->bed_state, JobState::kQueued);
  nlohmann::json j = *run;
  EXPECT_EQ(j["state"], "queued");
  EXPECT_EQ(j["point"]["mode"], "oscillatory");
  EXPECT_TRUE(j.contains("deck"));
  // Without the deck: no render, the rest the same.
  auto lean = store->GetRun(runs->runs[0].id, Store::Deck::kLeftOut);
  ASSERT_TRUE(lean.ok()) << lean.status().ToString();
  EXPECT_TRUE(lean->deck.empty());
  nlohmann::json lean_json = *lean;
  j.erase("deck");
  lean_json.erase("deck");
  EXPECT_EQ(lean_json, j);
  EXPECT_EQ(store->GetRun(12345).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store->GetSweep(12345).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store->SweepResults(12345).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(store->db().CountRows("sqlite_master; DROP TABLE runs").status().code(), StatusCode::kInvalidArgument);
}

// A sweep's trajectories in one read: each of its done runs that has one, by run id, none of
// another sweep's; a run not done is not read, even with a trajectory that does not parse.
TEST_F(StoreTest, SweepTrajectoriesAreItsRunsStoredTrajectories) {
  auto store = MustOpen();
  auto first = Submit(*store, *ParseSubmitRequest(Sweep("first", 3)), "engine", 1.7e9);
  nlohmann::json second_spec = Sweep("second", 1);
  second_spec["base"]["A"] = 0.02;  // a run of its own, not one of the first sweep's
  auto second = Submit(*store, *ParseSubmitRequest(second_spec), "engine", 1.7e9);
  ASSERT_TRUE(first.ok() && second.ok());
  auto rows = store->SweepResults(first->sweep_ids[0]);
  auto other = store->SweepResults(second->sweep_ids[0]);
  ASSERT_TRUE(rows.ok() && rows->size() == 3u && other.ok() && other->size() == 1u);
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t.ok());
    for (int i : {0, 2}) {
      const double v = 0.5 * (i + 1);
      ASSERT_TRUE(jobs::PutTrajectory(*t, (*rows)[i].run_id, api::Trajectory{{0, v}, {0, 0}, {0, 0}, {0, -v}}).ok());
      ASSERT_TRUE(jobs::MarkRunDone(*t, (*rows)[i].run_id, v, 10, 1.7e9).ok());
    }
    ASSERT_TRUE(jobs::PutTrajectory(*t, (*other)[0].run_id, api::Trajectory{{0, 9}, {0, 0}, {0, 0}, {0, 9}}).ok());
    ASSERT_TRUE(jobs::MarkRunDone(*t, (*other)[0].run_id, 9, 10, 1.7e9).ok());
    // Run 1 is still queued, with a trajectory that does not parse (an object of the wrong form).
    Statement odd = t->Prepare("INSERT OR REPLACE INTO trajectories (run_id, data) VALUES (?, ?)");
    odd.Bind(1, (*rows)[1].run_id).Bind(2, std::string(R"({"t": "not numbers"})"));
    ASSERT_TRUE(odd.Run().ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  auto trajectories = store->SweepTrajectories(first->sweep_ids[0]);
  ASSERT_TRUE(trajectories.ok()) << trajectories.status().ToString();
  ASSERT_EQ(trajectories->size(), 2u);
  EXPECT_EQ(trajectories->count((*rows)[1].run_id), 0u) << "not done: not read";
  for (int i : {0, 2}) {
    const int64_t id = (*rows)[i].run_id;
    ASSERT_EQ(trajectories->count(id), 1u) << i;
    auto run = store->GetRun(id, Store::Deck::kLeftOut);
    ASSERT_TRUE(run.ok() && run->trajectory);
    EXPECT_EQ(nlohmann::json(trajectories->at(id)), nlohmann::json(*run->trajectory)) << "as GetRun reads it";
  }
  EXPECT_TRUE(store->SweepTrajectories(12345)->empty());
}

// Every field of a run's result with a value of its own (core/result_fields_test_util.h), as the
// columns' CHECKs allow.
StoredResult EveryFieldSet() {
  StoredResult s = testing::EveryFieldSet();
  s.result.analysed_from = "trajectory";  // the column's CHECK: one of dump, trajectory, unreadable
  return s;
}

TEST_F(StoreTest, ResultFieldsAreTheResultsTable) {
  auto store = MustOpen();
  auto t = store->db().BeginRead();
  ASSERT_TRUE(t.ok());
  Statement st = t->Prepare("PRAGMA table_info(results)");
  std::set<std::string> columns;
  while (*st.Step()) columns.insert(st.Text(1));
  std::set<std::string> described = {"run_id"};
  for (const ResultField& f : ResultFields()) EXPECT_TRUE(described.insert(f.name).second) << f.name << " twice";
  EXPECT_EQ(columns, described) << "a results column without a field in core/result_fields.h, or a field "
                                   "without its migration";
}

TEST_F(StoreTest, EveryResultFieldIsStoredAndReadBackInItsOwnColumn) {
  auto store = MustOpen();
  auto req = ParseSubmitRequest(Sweep("two", 2));
  auto sub = Submit(*store, *req, "engine", 1.7e9);
  ASSERT_TRUE(sub.ok()) << sub.status().ToString();
  auto runs = store->ListRuns({});
  ASSERT_TRUE(runs.ok() && runs->runs.size() == 2u);
  const StoredResult full = EveryFieldSet();
  StoredResult bare;  // every optional field absent
  bare.key = "bare";
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t.ok());
    Status s = InsertResult(*t, runs->runs[0].id, full);
    ASSERT_TRUE(s.ok()) << s.ToString();
    s = InsertResult(*t, runs->runs[1].id, bare);
    ASSERT_TRUE(s.ok()) << s.ToString();
    ASSERT_TRUE(t->Commit().ok());
  }
  auto rows = store->SweepResults(sub->sweep_ids[0]);
  ASSERT_TRUE(rows.ok() && rows->size() == 2u);
  for (int i : {0, 1}) {
    const StoredResult& want = i == 0 ? full : bare;
    auto run = store->GetRun(runs->runs[i].id);
    ASSERT_TRUE(run.ok() && run->result && (*rows)[i].result) << i;
    for (const ResultField& f : ResultFields()) {
      EXPECT_EQ(f.get(*run->result), f.get(want)) << f.name << " of run " << i << " (GetRun)";
      EXPECT_EQ(f.get(*(*rows)[i].result), f.get(want)) << f.name << " of run " << i << " (SweepResults)";
    }
  }
  auto listed = store->ListRuns({});
  ASSERT_TRUE(listed.ok());
  EXPECT_EQ(listed->runs[0].uz, full.result.uz);
  EXPECT_EQ(listed->runs[0].uz_text, DescribeUz(full.result));
  // The re-analysis's UPDATE rewrites what the analysis makes and nothing else.
  {
    auto t = store->db().Begin();
    ASSERT_TRUE(t.ok());
    Statement update = t->Prepare(UpdateAnalysedFieldsSql());
    ASSERT_TRUE(UpdateAnalysedFields(update, runs->runs[0].id, bare.result).ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  auto run = store->GetRun(runs->runs[0].id);
  ASSERT_TRUE(run.ok() && run->result);
  for (const ResultField& f : ResultFields()) {
    EXPECT_EQ(f.get(*run->result), f.get(f.origin == ResultOrigin::kAnalysis ? bare : full)) << f.name;
  }
}

TEST_F(StoreTest, CampaignsRoundTrip) {
  auto store = MustOpen();
  StoredCampaign c{"mine", {{"name", "mine"}}, "0 3 * * *", 0.01, 5};
  ASSERT_TRUE(PutCampaign(*store, c).ok());
  c.schedule.reset();
  ASSERT_TRUE(PutCampaign(*store, c).ok());
  auto got = store->GetCampaign("mine");
  ASSERT_TRUE(got.ok() && got->has_value());
  EXPECT_FALSE((*got)->schedule.has_value());
  EXPECT_EQ(store->ListCampaigns()->size(), 1u);
  EXPECT_FALSE(store->GetCampaign("other")->has_value());
}

// Group commit: many threads hand changes to Write() at once. Every change that succeeds is in
// the file once Write returns; one that fails or throws is rolled back alone, and its caller
// (only its caller) gets the error.
TEST_F(StoreTest, GroupedWritesCommitTogetherAndFailAlone) {
  auto store = MustOpen();
  ASSERT_NE(store, nullptr);
  constexpr int kThreads = 16, kEach = 50;
  std::atomic<int> ok{0}, refused{0}, thrown{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < kThreads; ++i) {
    threads.emplace_back([&, i] {
      for (int k = 0; k < kEach; ++k) {
        const int n = i * kEach + k;
        Status s = store->db().Write([&](Transaction& t) -> Status {
          // Every change writes first, so a failing one has something to roll back.
          SANDSWIM_RETURN_IF_ERROR(t.Count("grouped"));
          if (n % 7 == 3) return Status::Conflict("refused on purpose");
          if (n % 11 == 5) throw std::runtime_error("thrown on purpose");
          return Status::Ok();
        });
        if (s.ok()) {
          ++ok;
          // Durable and visible as soon as Write returned.
          Result<int64_t> rows = store->db().CountRows("counters");
          EXPECT_TRUE(rows.ok() && *rows >= 1);
        } else if (s.code() == StatusCode::kConflict) {
          ++refused;
        } else {
          EXPECT_NE(s.reason().find("thrown on purpose"), std::string::npos) << s.ToString();
          ++thrown;
        }
      }
    });
  }
  for (auto& t : threads) t.join();
  int want_refused = 0, want_thrown = 0;
  for (int n = 0; n < kThreads * kEach; ++n) {
    if (n % 7 == 3)
      ++want_refused;
    else if (n % 11 == 5)
      ++want_thrown;
  }
  EXPECT_EQ(refused.load(), want_refused);
  EXPECT_EQ(thrown.load(), want_thrown);
  EXPECT_EQ(ok.load(), kThreads * kEach - want_refused - want_thrown);
  temp_.reset();
  // Reopened: exactly the successful changes were committed.
  auto again = MustOpen();
  ASSERT_NE(again, nullptr);
  Result<Metrics> m = again->GetMetrics();
  ASSERT_TRUE(m.ok());
  auto t = again->db().BeginRead();
  ASSERT_TRUE(t.ok());
  Statement st = t->Prepare("SELECT value FROM counters WHERE name = 'grouped'");
  Result<bool> row = st.Step();
  ASSERT_TRUE(row.ok() && *row);
  EXPECT_EQ(st.Int(0), ok.load());
}

// Reads run on read-only connections beside the writer's: a read transaction held open (a long
// results read) does not hold up a write, and sees the file as it was when it began.
TEST_F(StoreTest, AnOpenReadDoesNotHoldUpWrites) {
  auto store = MustOpen();
  ASSERT_TRUE(store);
  EXPECT_GT(store->db().read_connections(), 0);
  auto read = store->db().BeginRead();
  ASSERT_TRUE(read.ok());
  Statement before = read->Prepare("SELECT count(*) FROM events");
  ASSERT_TRUE(*before.Step());
  const int64_t seen = before.Int(0);
  before.Reset();
  std::atomic<bool> written{false};
  std::thread writer([&] {
    Status s = store->db().Write([&](Transaction& t) { return t.Event(1, "during-read", "x/1"); });
    EXPECT_TRUE(s.ok()) << s.ToString();
    written = true;
  });
  for (int i = 0; i < 500 && !written; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_TRUE(written.load()) << "a write waited for an open read";
  Statement again = read->Prepare("SELECT count(*) FROM events");
  ASSERT_TRUE(*again.Step());
  EXPECT_EQ(again.Int(0), seen) << "the read's snapshot changed under it";
  writer.join();
  // A write slipped into a read transaction fails at once.
  EXPECT_FALSE(read->Exec("INSERT INTO events (time, kind, subject, detail) VALUES (1, 'x', 'y', '{}')").ok());
}

}  // namespace
}  // namespace sandswim
