// The daemon's rounds (server/jobs/rounds.h) over a real SQLite store, the lease queue and the
// claims' own look (LookAtClaims), with synthetic results: a sign claim that round 1 leaves open
// gets a round 2 with its reason, stored once however often or by however many daemons the pass
// runs, and the rounds stop with a reason; cancelled sweeps stop them; what was spent is a ledger
// (failed and replaced runs stay charged, each attempt once, at its round's planning rates; a run
// shared with an earlier campaign run paid once) and stops them at the budget; a budget
// below round 1 is refused at PUT and at submission, naming the field and what it needs.
#include "server/jobs/rounds.h"

#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/keys.h"
#include "platform/clock.h"
#include "server/analysis/claim_check.h"
#include "server/jobs/campaign_edits.h"
#include "server/jobs/lease_queue.h"
#include "server/store/campaigns.h"
#include "server/store/rounds.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using ::testing::HasSubstr;

constexpr char kEngine[] = "LIGGGHTS (Version rounds test)";

json Adaptive(double budget_core_h, int max_rounds = 3) {
  return json{{"description", "the sign of U_z at +-80 rad/s, in rounds"},
              {"scale", "smoke"},
              {"sweeps",
               {{{"name", "signs"},
                 {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -80}, {"duration_s", 2}}},
                 {"axes", {{{"param", "Omega"}, {"values", {-80, 80}}}}}}}},
              {"claims",
               {{{"id", "S1"},
                 {"title", "Omega < 0 rises, Omega > 0 sinks"},
                 {"source", "test"},
                 {"paper", {{"text", "a test"}}},
                 {"rule", {{"kind", "sign"}, {"sweeps", {"signs"}}, {"expect", "against_Omega"}}}}}},
              {"adaptive", {{"budget_core_h", budget_core_h}, {"max_rounds", max_rounds}}}};
}

class RoundsTest : public ::testing::Test {
 protected:
  void SetUp() override { Restart(); }
  void TearDown() override {
    driver_.reset();
    queue_.reset();
  }
  // A daemon (re)start: a reopened Store on the same file, a new queue and driver.
  void Restart() {
    driver_.reset();
    queue_.reset();
    ASSERT_TRUE(store_.Reopen());
    queue_ = std::make_unique<LeaseQueue>(store_.get(), &clock_);
    driver_ = NewDriver();
  }
  std::unique_ptr<RoundDriver> NewDriver(int max_beds = AdaptiveOptions{}.max_beds) {
    RoundDriverOptions options;
    options.engine_version = kEngine;
    options.adaptive.max_beds = max_beds;
    return std::make_unique<RoundDriver>(store_.get(), &LookAtClaims, options);
  }
  // Works off the queue: beds, then runs; U_z by the run's Omega, with the standard error
  // `rise_se` at Omega < 0 (wide: its sign unclear on one bed) and a tight one at Omega > 0.
  int CompleteAll(double rise_se) {
    int runs = 0;
    while (true) {
      auto g = queue_->Lease({"w", "host", 1});
      EXPECT_TRUE(g.ok()) << g.status().ToString();
      if (!g.ok() || !g->has_value()) return runs;
      const api::LeaseGrant& grant = **g;
      api::Completion c;
      c.ok = true;
      c.execution.host = "host";
      c.execution.engine_version = kEngine;
      if (grant.kind == api::JobKind::kBed) {
        const std::string bytes = "restart " + grant.key;
        EXPECT_TRUE(queue_->PutBedRestart(grant.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
        c.bed_result = api::BedResult{};
        c.bed_result->grains = 3700;
        c.bed_result->bed_height = 0.22;
        c.bed_result->sha256 = Sha256Hex(bytes);
      } else {
        auto run = store_->GetRun(grant.id);
        EXPECT_TRUE(run.ok());
        if (fails_ && fails_(run->summary.point)) {
          // A failure for good (lost atoms are never retried), after a heartbeat when one is set.
          if (fail_heartbeat_s_ >= 0) {
            api::Heartbeat beat;
            beat.sim_time_s = fail_heartbeat_s_;
            EXPECT_TRUE(queue_->Heartbeat(grant.token, beat).ok());
          }
          c.ok = false;
          c.failure = api::Failure{"lost_atoms", "atoms were lost (test)"};
          clock_.Advance(1);
          auto reply = queue_->Complete(grant.token, c);
          EXPECT_TRUE(reply.ok()) << reply.status().ToString();
          continue;
        }
        const bool rises = run->summary.point.Omega < 0;
        api::RunResult r;
        r.uz = rises ? 0.004 : -0.01;
        r.uz_stderr = rises ? rise_se : 3e-4;
        r.uz_blocks = 4;
        r.uz_ci95 = 3.18 * *r.uz_stderr;
        r.block_kind = "period";
        r.block_s = 1.0 / 3;
        r.conclusive = true;
        r.stop_reason = "duration";
        r.sim_time_s = 1;
        r.steps = 100000;
        c.result = r;
        c.trajectory = api::Trajectory{{0, 0.1}, {0, 0}, {0, 0}, {0, *r.uz * 0.1}};
        ++runs;
      }
      clock_.Advance(1);
      auto reply = queue_->Complete(grant.token, c);
      EXPECT_TRUE(reply.ok()) << reply.status().ToString();
    }
  }
  // Leases the next job, which must be a bed, and prepares it.
  void PrepareBed() {
    auto bed = queue_->Lease({"w", "host", 1});
    ASSERT_TRUE(bed.ok() && bed->has_value());
    ASSERT_EQ((*bed)->kind, api::JobKind::kBed);
    const std::string bytes = "restart " + (*bed)->key;
    ASSERT_TRUE(queue_->PutBedRestart((*bed)->token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
    api::Completion c;
    c.ok = true;
    c.execution.host = "host";
    c.execution.engine_version = kEngine;
    c.bed_result = api::BedResult{};
    c.bed_result->grains = 3700;
    c.bed_result->bed_height = 0.22;
    c.bed_result->sha256 = Sha256Hex(bytes);
    ASSERT_TRUE(queue_->Complete((*bed)->token, c).ok());
  }
  // The campaign run's charges of one job: {priced_by, lease_token, sim_time_s, core_h} each.
  struct ChargeRow {
    std::string priced_by, lease_token;
    double sim_time_s = 0, core_h = 0;
  };
  std::vector<ChargeRow> Charges(int64_t campaign_run_id, const std::string& kind, int64_t job_id) {
    std::vector<ChargeRow> out;
    auto t = store_->db().BeginRead();
    EXPECT_TRUE(t.ok());
    if (!t.ok()) return out;
    Statement st = t->Prepare(
        "SELECT priced_by, COALESCE(lease_token, ''), COALESCE(sim_time_s, 0), core_h FROM campaign_run_charges "
        "WHERE campaign_run_id = ? AND kind = ? AND job_id = ? ORDER BY ended_at");
    st.Bind(1, campaign_run_id).Bind(2, kind).Bind(3, job_id);
    while (true) {
      auto row = st.Step();
      EXPECT_TRUE(row.ok());
      if (!row.ok() || !*row) break;
      out.push_back({st.Text(0), st.Text(1), st.Double(2), st.Double(3)});
    }
    return out;
  }
  std::vector<rounds::RoundRow> Rounds(int64_t id) {
    auto r = rounds::ListRounds(*store_, id);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return r.ok() ? *r : std::vector<rounds::RoundRow>{};
  }
  int64_t Submit(const std::string& name) {
    SubmitRequest request;
    request.campaign = name;
    auto sub = sandswim::Submit(*store_, request, kEngine, clock_.Now());
    EXPECT_TRUE(sub.ok()) << sub.status().ToString();
    return sub.ok() ? sub->campaign_run_id.value_or(0) : 0;
  }

  double Charged(int64_t id) {
    auto h = rounds::ChargedCoreHours(*store_, id);
    EXPECT_TRUE(h.ok()) << h.status().ToString();
    return h.ok() ? *h : -1;
  }
  // One value of a query that binds `id` (if it has a ?) and returns one number.
  double Query(const std::string& sql, int64_t id = 0) {
    auto t = store_->db().BeginRead();
    EXPECT_TRUE(t.ok());
    if (!t.ok()) return -1;
    Statement st = t->Prepare(sql);
    if (sql.find('?') != std::string::npos) st.Bind(1, id);
    auto row = st.Step();
    EXPECT_TRUE(row.ok() && *row) << sql;
    return row.ok() && *row ? st.Double(0) : -1;
  }
  void Exec(const std::string& sql) {
    Status s = store_->db().Write([&](Transaction& t) { return t.Exec(sql); });
    ASSERT_TRUE(s.ok()) << sql << ": " << s.ToString();
  }
  // How many ledgers, over every campaign run, charge each lease of a job in full (> 0 core-h):
  // {token: count}. A lease no ledger charged in full counts 0.
  std::map<std::string, int> FullCharges(const std::string& kind, int64_t job_id) {
    std::map<std::string, int> out;
    auto t = store_->db().BeginRead();
    EXPECT_TRUE(t.ok());
    if (!t.ok()) return out;
    Statement st = t->Prepare(
        "SELECT l.token, (SELECT COUNT(*) FROM campaign_run_charges c WHERE c.lease_token = l.token AND c.core_h > 0) "
        "FROM leases l WHERE l.kind = ? AND l.job_id = ?");
    st.Bind(1, kind).Bind(2, job_id);
    while (true) {
      auto row = st.Step();
      EXPECT_TRUE(row.ok());
      if (!row.ok() || !*row) break;
      out[st.Text(0)] = static_cast<int>(st.Int(1));
    }
    return out;
  }
  // Looks at every open campaign run until none of them plans or stops anything more.
  void LookUntilQuiet(double rise_se) {
    for (int i = 0; i < 6; ++i) {
      CompleteAll(rise_se);
      auto pass = driver_->Tick(clock_.Now());
      ASSERT_TRUE(pass.ok()) << pass.status().ToString();
      ASSERT_TRUE(pass->errors.empty()) << pass->errors.front().second.ToString();
      if (pass->steps.empty()) return;
    }
  }

  FakeClock clock_;
  std::function<bool(const Point&)> fails_;  // runs at these points fail for good
  double fail_heartbeat_s_ = -1;             // after a heartbeat at this simulated time (< 0: none)
  testing::TempStore store_{"rounds"};
  std::unique_ptr<LeaseQueue> queue_;
  std::unique_ptr<RoundDriver> driver_;
};

TEST_F(RoundsTest, ARoundIsPlannedOnceWithItsReasonAndSurvivesARestart) {
  auto saved = SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now());
  ASSERT_TRUE(saved.ok()) << saved.status().ToString();
  const int64_t id = Submit("mine");
  // Round 1 runs: nothing to plan, but round 1's row is stored (what was submitted and its cost).
  auto step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  EXPECT_FALSE(step->has_value());
  ASSERT_EQ(Rounds(id).size(), 1u);
  EXPECT_GT(Rounds(id)[0].core_h_planned, 0);
  EXPECT_EQ(Rounds(id)[0].actions[0]["kind"], "first round");
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);

  auto look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
  ASSERT_TRUE(look.ok());
  ASSERT_EQ(EvaluateClaims(look->claims, look->input)[0].verdict, Verdict::kInconclusive);

  const int64_t runs_before = *store_->db().CountRows("runs");
  step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  EXPECT_FALSE((*step)->stopped) << (*step)->text;
  EXPECT_EQ((*step)->round, 2);
  EXPECT_THAT((*step)->text, HasSubstr("S1"));
  std::vector<rounds::RoundRow> rows = Rounds(id);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_TRUE(rows[0].finished_at.has_value());
  EXPECT_TRUE(rows[0].core_h_spent.has_value());
  EXPECT_EQ(rows[0].verdicts_after[0]["verdict"], "inconclusive");
  EXPECT_FALSE(rows[0].stop_reason.has_value());
  ASSERT_FALSE(rows[1].actions.empty());
  EXPECT_EQ(rows[1].actions[0]["claim"], "S1");
  EXPECT_THAT(rows[1].actions[0]["reason"].get<std::string>(), HasSubstr("S1"));
  EXPECT_FALSE(rows[1].finished_at.has_value());
  const int64_t runs_added = *store_->db().CountRows("runs") - runs_before;
  EXPECT_GT(runs_added, 0);
  // Its runs are the campaign run's: queued in its sweep.
  auto info = store_->GetCampaignRun(id);
  EXPECT_EQ(info->counts.queued, runs_added) << rows[1].actions.dump();

  // Again, from this daemon and from a second one on the same file: nothing more while round 2 runs.
  auto other = NewDriver();
  for (RoundDriver* d : {driver_.get(), other.get()}) {
    auto again = d->Step(id, clock_.Now());
    ASSERT_TRUE(again.ok());
    EXPECT_FALSE(again->has_value());
  }
  other.reset();
  // A daemon killed between rounds: a new store and driver go on from what is stored.
  Restart();
  EXPECT_EQ(Rounds(id).size(), 2u);
  auto pass = driver_->Tick(clock_.Now());
  ASSERT_TRUE(pass.ok());
  EXPECT_TRUE(pass->steps.empty());
  EXPECT_EQ(*store_->db().CountRows("runs") - runs_before, runs_added);

  // Round 2's runs measure the rise tightly: the claim is decided and frozen, and the rounds stop.
  EXPECT_EQ(CompleteAll(/*rise_se=*/3e-4), runs_added);
  for (int i = 0; i < 4 && !Rounds(id).back().stop_reason; ++i) {
    pass = driver_->Tick(clock_.Now());
    ASSERT_TRUE(pass.ok());
    for (const auto& [cr, why] : pass->errors) ADD_FAILURE() << cr << ": " << why.ToString();
    CompleteAll(3e-4);
  }
  rows = Rounds(id);
  ASSERT_TRUE(rows.back().stop_reason.has_value());
  EXPECT_THAT(*rows.back().stop_reason, HasSubstr("decided"));
  auto frozen = rounds::FrozenVerdicts(*store_, id);
  ASSERT_TRUE(frozen.ok());
  ASSERT_EQ(frozen->count("S1"), 1u);
  EXPECT_EQ(frozen->at("S1").verdict, Verdict::kHolds);
  EXPECT_EQ(rows.back().verdicts_after[0]["verdict"], "holds");
  EXPECT_EQ(rows.back().verdicts_after[0]["frozen_at_round"], frozen->at("S1").round);
  // Stopped: no pass looks at it again.
  auto open = rounds::OpenAdaptiveCampaignRuns(*store_);
  ASSERT_TRUE(open.ok());
  EXPECT_TRUE(open->empty());
}

// Cancelling the campaign run's sweeps stops its rounds even when none of its runs ends cancelled
// (here every run had finished): no next round is planned into a cancelled sweep.
TEST_F(RoundsTest, CancelledSweepsStopTheRoundsThoughNoRunWasCancelled) {
  auto saved = SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now());
  ASSERT_TRUE(saved.ok()) << saved.status().ToString();
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);  // round 1 leaves S1 open: round 2 would be planned
  auto info = store_->GetCampaignRun(id);
  ASSERT_TRUE(info.ok()) << info.status().ToString();
  ASSERT_FALSE(info->sweep_ids.empty());
  for (int64_t sweep : info->sweep_ids) {
    auto cancelled = queue_->Cancel(sweep);
    ASSERT_TRUE(cancelled.ok()) << cancelled.status().ToString();
    EXPECT_EQ(cancelled->cancelled, 0);  // every run had finished: none ends cancelled
  }
  const int64_t runs_before = *store_->db().CountRows("runs");
  auto step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  EXPECT_TRUE((*step)->stopped) << (*step)->text;
  std::vector<rounds::RoundRow> rows = Rounds(id);
  ASSERT_EQ(rows.size(), 1u);
  ASSERT_TRUE(rows[0].stop_reason.has_value());
  EXPECT_THAT(*rows[0].stop_reason, HasSubstr("sweeps were cancelled"));
  EXPECT_EQ(*store_->db().CountRows("runs"), runs_before);
}

// What a campaign run spent is a ledger: a done run is charged its simulated time, a failed one the
// time its last heartbeat reached, a bed once; a look taken twice charges nothing more. (A run a
// longer one replaced stays charged: ADoneLongerRunStandsAndTheRunItReplacedStaysCharged.)
TEST_F(RoundsTest, TheLedgerChargesEachEndingOnceAndAFailedRunTheTimeItReached) {
  const double budget = 50;
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(budget), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  fails_ = [](const Point& p) { return p.Omega > 0; };
  fail_heartbeat_s_ = 0.4;
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 1);
  auto look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
  ASSERT_TRUE(look.ok());
  const ClaimRun* done = nullptr;
  const ClaimRun* failed = nullptr;
  for (const ClaimRun& r : look->input.sweeps.at(0).runs) (r.state == JobState::kDone ? done : failed) = &r;
  ASSERT_NE(done, nullptr);
  ASSERT_NE(failed, nullptr);
  ASSERT_EQ(failed->state, JobState::kFailed);
  // At the rates round 1 was planned at (the bed just prepared has since given the model a
  // measured bed rate: not what round 1 was priced at).
  auto now = rounds::AdaptiveCostNow(*store_, "smoke", clock_.Now());
  ASSERT_TRUE(now.ok());
  const AdaptiveCost planned = rounds::RoundRates(Rounds(id).at(0), *now);
  const AdaptiveCost* cost = &planned;
  const double expected = cost->RunCoreHours(done->point, 1) + cost->RunCoreHours(failed->point, 0.4) +
                          cost->BedCoreHours(done->point);
  ASSERT_GT(cost->RunCoreHours(failed->point, 0.4), 0);

  auto step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  std::vector<rounds::RoundRow> rows = Rounds(id);
  ASSERT_TRUE(rows[0].core_h_spent.has_value());
  EXPECT_NEAR(*rows[0].core_h_spent, expected, 1e-9 * expected);
  EXPECT_NEAR(Charged(id), expected, 1e-9 * expected);
  // The next round, if any, was planned within what the ledger left.
  if (rows.size() > 1) {
    EXPECT_LE(rows[1].core_h_planned, budget - Charged(id) + 1e-12);
  }

  // The same look again, from a second daemon, and the same attempts charged again: nothing more.
  EXPECT_FALSE(NewDriver()->Step(id, clock_.Now())->has_value());
  auto ended = rounds::UnchargedAttempts(*store_, id);
  ASSERT_TRUE(ended.ok());
  EXPECT_TRUE(ended->empty());
  Status added = store_->db().Write([&](Transaction& t) -> Status {
    Statement st = t.Prepare("SELECT lease_token, ended_at FROM campaign_run_charges WHERE kind = 'run' AND job_id = ?");
    st.Bind(1, done->run_id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    EXPECT_TRUE(*row);
    std::vector<rounds::Charge> again{{"run", done->run_id, st.Double(1), "done", 1.0, "result", 1.0, st.Text(0)}};
    Result<double> h = rounds::AddCharges(t, id, 1, clock_.Now(), again);
    if (!h.ok()) return h.status();
    EXPECT_EQ(*h, 0.0);
    return Status::Ok();
  });
  ASSERT_TRUE(added.ok()) << added.ToString();
  EXPECT_NEAR(Charged(id), expected, 1e-9 * expected);
}

// A heartbeat that carried no simulated time (api::Heartbeat's sim_time_s defaults to 0) is no
// measure: a run that failed after it is charged its planned length, as one with no heartbeat.
TEST_F(RoundsTest, AFailedRunWhoseHeartbeatSaidZeroIsChargedItsPlannedLength) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  fails_ = [](const Point& p) { return p.Omega > 0; };
  fail_heartbeat_s_ = 0;
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 1);
  auto ended = rounds::UnchargedAttempts(*store_, id);
  ASSERT_TRUE(ended.ok()) << ended.status().ToString();
  const rounds::ClosedAttempt* failed = nullptr;
  for (const rounds::ClosedAttempt& j : *ended)
    if (j.kind == "run" && j.outcome == "failed") failed = &j;
  ASSERT_NE(failed, nullptr);
  EXPECT_EQ(failed->sim_time_s.value_or(-1), 0.0);  // what its heartbeat said, recorded when its lease closed
  ASSERT_GT(failed->run_duration_s, 0);
  const double planned = failed->run_duration_s;
  const int64_t failed_id = failed->id;
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  auto t = store_->db().BeginRead();
  ASSERT_TRUE(t.ok());
  Statement st = t->Prepare("SELECT priced_by, sim_time_s FROM campaign_run_charges WHERE kind = 'run' AND job_id = ?");
  st.Bind(1, failed_id);
  auto row = st.Step();
  ASSERT_TRUE(row.ok() && *row);
  EXPECT_EQ(st.Text(0), "planned length");
  EXPECT_DOUBLE_EQ(st.Double(1), planned);
}

// A bed is charged per attempt: one whose lease expired (its worker vanished) and that was then
// prepared is charged for both attempts (its cost was spent each time), each once.
TEST_F(RoundsTest, ABedIsChargedPerAttemptExpiredOrPrepared) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  auto bed = queue_->Lease({"w", "host", 1});
  ASSERT_TRUE(bed.ok() && bed->has_value());
  ASSERT_EQ((*bed)->kind, api::JobKind::kBed);
  clock_.Advance((*bed)->ttl_s + 1);
  auto expired = queue_->ExpireLeases();
  ASSERT_TRUE(expired.ok());
  ASSERT_EQ(*expired, 1);
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  auto bed_attempts = [&] {
    auto ended = rounds::UnchargedAttempts(*store_, id);
    EXPECT_TRUE(ended.ok()) << ended.status().ToString();
    std::multiset<std::string> out;
    if (ended.ok())
      for (const rounds::ClosedAttempt& a : *ended)
        if (a.kind == "bed") out.insert(a.outcome);
    return out;
  };
  EXPECT_EQ(bed_attempts(), (std::multiset<std::string>{"done", "expired"}));
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  EXPECT_TRUE(bed_attempts().empty());
  auto t = store_->db().BeginRead();
  ASSERT_TRUE(t.ok());
  Statement st = t->Prepare("SELECT COUNT(*), COUNT(DISTINCT lease_token), SUM(core_h > 0) FROM campaign_run_charges "
                            "WHERE kind = 'bed' AND job_id = ?");
  st.Bind(1, (*bed)->id);
  auto row = st.Step();
  ASSERT_TRUE(row.ok() && *row);
  EXPECT_EQ(st.Int(0), 2);
  EXPECT_EQ(st.Int(1), 2);
  EXPECT_EQ(st.Int(2), 2);
}

// A longer run joins only its order's sweep: the run it replaces leaves that sweep and stays in the
// campaign run's other sweeps that share it.
TEST_F(RoundsTest, AReplacementLeavesOnlyTheOrdersSweep) {
  json twice = Adaptive(50);
  json other = twice["sweeps"][0];
  other["name"] = "signs_again";
  twice["sweeps"].push_back(other);
  ASSERT_TRUE(SaveCampaign(*store_, "twice", twice, kEngine, clock_.Now()).ok());
  const int64_t id = Submit("twice");
  auto members = [&](const std::string& sweep, int64_t run) {
    auto t = store_->db().BeginRead();
    EXPECT_TRUE(t.ok());
    Statement st = t->Prepare(
        "SELECT COUNT(*) FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
        "WHERE s.campaign_run_id = ? AND s.name = ? AND sr.run_id = ?");
    st.Bind(1, id).Bind(2, sweep).Bind(3, run);
    auto row = st.Step();
    EXPECT_TRUE(row.ok() && *row);
    return st.Int(0);
  };
  std::vector<std::pair<int64_t, std::string>> runs;  // id, key
  {
    auto t = store_->db().BeginRead();
    ASSERT_TRUE(t.ok());
    Statement st = t->Prepare("SELECT id, key FROM runs ORDER BY id");
    for (auto row = st.Step(); row.ok() && *row; row = st.Step()) runs.emplace_back(st.Int(0), st.Text(1));
  }
  ASSERT_EQ(runs.size(), 2u);  // the two sweeps share their runs
  const int64_t old_run = runs[0].first;
  ASSERT_EQ(members("signs", old_run), 1);
  ASSERT_EQ(members("signs_again", old_run), 1);
  auto n = store_->db().WriteResult<int64_t>([&](Transaction& t) {
    return rounds::ReplaceInCampaignRunSweeps(t, id, 2, old_run, runs[1].second, "signs");
  });
  ASSERT_TRUE(n.ok()) << n.status().ToString();
  EXPECT_EQ(*n, 1);
  EXPECT_EQ(members("signs", old_run), 0);
  EXPECT_EQ(members("signs_again", old_run), 1);
}

// The ledger, not the planner's hopes, decides when the budget is spent: with its charges at the
// budget, the rounds stop, saying so, and nothing is added.
TEST_F(RoundsTest, TheRoundsStopWhenTheLedgerReachesTheBudget) {
  const double budget = 50;
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(budget), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);  // round 1 leaves S1 open: round 2 would be planned
  // An attempt charged at an earlier look (say, at rates since revised) has used up the budget.
  ASSERT_TRUE(store_->db()
                  .Write([&](Transaction& t) -> Status {
                    return rounds::AddCharges(
                               t, id, 1, clock_.Now(),
                               {{"bed", 1000000, 1, "done", std::nullopt, "bed", budget, "an earlier attempt"}})
                        .status();
                  })
                  .ok());
  const int64_t runs_before = *store_->db().CountRows("runs");
  auto step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  EXPECT_TRUE((*step)->stopped) << (*step)->text;
  std::vector<rounds::RoundRow> rows = Rounds(id);
  ASSERT_EQ(rows.size(), 1u);
  ASSERT_TRUE(rows[0].stop_reason.has_value());
  EXPECT_THAT(*rows[0].stop_reason, HasSubstr("the budget is spent"));
  EXPECT_EQ(*store_->db().CountRows("runs"), runs_before);
  EXPECT_GT(Charged(id), budget);  // round 1's runs and bed were charged on top
}

// One bed a point at most: round 2 lengthens the unclear run, which takes its point's place on that
// bed. When the longer run fails for good, the point's earlier run goes back to its place (its
// measurement stands) and the failed one leaves the sweep; both stay charged. (Two rounds at most,
// so that the look after round 2 plans nothing more.)
TEST_F(RoundsTest, AFailedLongerRunGivesThePointsPlaceBackToItsEarlierRun) {
  driver_ = NewDriver(/*max_beds=*/1);
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50, /*max_rounds=*/2), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  auto runs_of = [&]() {
    std::map<int64_t, JobState> out;
    auto look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
    EXPECT_TRUE(look.ok());
    if (look.ok())
      for (const ClaimRun& r : look->input.sweeps.at(0).runs) out[r.run_id] = r.state;
    return out;
  };
  const std::map<int64_t, JobState> first = runs_of();
  ASSERT_EQ(first.size(), 2u);

  auto step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  ASSERT_FALSE((*step)->stopped) << (*step)->text;
  std::vector<rounds::RoundRow> rows = Rounds(id);
  ASSERT_EQ(rows.size(), 2u);
  ASSERT_EQ(rows[1].actions.at(0)["kind"], "longer") << rows[1].actions.dump();
  const size_t lengthened = rows[1].actions[0]["runs"].size();
  ASSERT_GE(lengthened, 1u);
  // The longer runs took their points' places: the sweep holds them and the runs they replaced left it.
  std::map<int64_t, JobState> during = runs_of();
  EXPECT_EQ(during.size(), 2u);
  int replaced = 0;
  for (const auto& [run, state] : first) replaced += during.count(run) == 0;
  EXPECT_EQ(replaced, static_cast<int>(lengthened));
  const double charged_before = Charged(id);

  // Every longer run fails for good, after a heartbeat at 0.5 s.
  fails_ = [](const Point&) { return true; };
  fail_heartbeat_s_ = 0.5;
  EXPECT_EQ(CompleteAll(3e-4), 0);
  step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  EXPECT_TRUE((*step)->stopped) << (*step)->text;
  // The point's earlier runs are back, done: the sweep is round 1's again.
  EXPECT_EQ(runs_of(), first);
  // Both stay charged: the failed longer runs at the time they reached, on top of round 1's.
  auto cost = rounds::AdaptiveCostNow(*store_, "smoke", clock_.Now());
  ASSERT_TRUE(cost.ok());
  double longer = 0;
  for (const auto& [run, state] : during) {
    if (first.count(run)) continue;
    auto r = store_->GetRun(run);
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->summary.state, JobState::kFailed);
    longer += cost->RunCoreHours(r->summary.point, 0.5);
  }
  ASSERT_GT(longer, 0);
  EXPECT_NEAR(Charged(id), charged_before + longer, 1e-9 * Charged(id));
  EXPECT_NEAR(*Rounds(id)[1].core_h_spent, longer, 1e-9 * longer);
  // Settled once: a second pass puts nothing back again.
  auto again = store_->db().WriteResult<int64_t>(
      [&](Transaction& t) { return rounds::SettleReplacements(t, id, clock_.Now()); });
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(*again, 0);
}

// The same, when the longer run is done: it stands in its point's place, and the run it replaced
// stays out of the sweep and in the ledger.
TEST_F(RoundsTest, ADoneLongerRunStandsAndTheRunItReplacedStaysCharged) {
  driver_ = NewDriver(/*max_beds=*/1);
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50, /*max_rounds=*/2), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  auto look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
  ASSERT_TRUE(look.ok());
  std::set<int64_t> first;
  for (const ClaimRun& r : look->input.sweeps.at(0).runs) first.insert(r.run_id);
  auto step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_EQ(Rounds(id).size(), 2u);
  ASSERT_EQ(Rounds(id)[1].actions.at(0)["kind"], "longer");
  const double charged_before = Charged(id);
  look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
  ASSERT_TRUE(look.ok());
  std::set<int64_t> during;
  for (const ClaimRun& r : look->input.sweeps.at(0).runs) during.insert(r.run_id);

  const int done = CompleteAll(/*rise_se=*/3e-4);
  EXPECT_GE(done, 1);
  step = driver_->Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
  ASSERT_TRUE(look.ok());
  std::set<int64_t> after;
  for (const ClaimRun& r : look->input.sweeps.at(0).runs) {
    after.insert(r.run_id);
    EXPECT_EQ(r.state, JobState::kDone);
  }
  EXPECT_EQ(after, during);
  EXPECT_NE(after, first);
  // Round 1's charges stand; the longer runs were charged their simulated time (1 s each here).
  auto cost = rounds::AdaptiveCostNow(*store_, "smoke", clock_.Now());
  ASSERT_TRUE(cost.ok());
  double longer = 0;
  for (const ClaimRun& r : look->input.sweeps.at(0).runs)
    if (!first.count(r.run_id)) longer += cost->RunCoreHours(r.point, 1);
  EXPECT_GT(longer, 0);
  EXPECT_NEAR(Charged(id), charged_before + longer, 1e-9 * Charged(id));
}

// A busy campaign run is not analysed: while any of its runs or beds is queued or running, a pass
// asks one cheap query and does not look at the claims (it used to analyse the whole campaign on
// every scheduler tick).
TEST_F(RoundsTest, ABusyCampaignRunIsNotAnalysed) {
  int looks = 0;
  RoundDriverOptions options;
  options.engine_version = kEngine;
  RoundDriver counting(
      store_.get(),
      [&looks](Store& store, const CampaignRunInfo& info) {
        ++looks;
        return LookAtClaims(store, info);
      },
      options);
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  for (int i = 0; i < 3; ++i) {
    auto pass = counting.Tick(clock_.Now());
    ASSERT_TRUE(pass.ok());
    EXPECT_TRUE(pass->steps.empty());
  }
  EXPECT_EQ(looks, 0);  // its bed and runs are queued
  // The bed is leased (running), then prepared; its runs are still queued.
  auto bed = queue_->Lease({"w", "host", 1});
  ASSERT_TRUE(bed.ok() && bed->has_value());
  ASSERT_EQ((*bed)->kind, api::JobKind::kBed);
  ASSERT_TRUE(counting.Tick(clock_.Now()).ok());
  EXPECT_EQ(looks, 0);
  const std::string bytes = "restart " + (*bed)->key;
  ASSERT_TRUE(queue_->PutBedRestart((*bed)->token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
  api::Completion c;
  c.ok = true;
  c.execution.host = "host";
  c.execution.engine_version = kEngine;
  c.bed_result = api::BedResult{};
  c.bed_result->grains = 3700;
  c.bed_result->bed_height = 0.22;
  c.bed_result->sha256 = Sha256Hex(bytes);
  ASSERT_TRUE(queue_->Complete((*bed)->token, c).ok());
  ASSERT_TRUE(counting.Tick(clock_.Now()).ok());
  EXPECT_EQ(looks, 0);
  // Once every run has ended: one look, which plans round 2; then none while round 2 runs.
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  auto pass = counting.Tick(clock_.Now());
  ASSERT_TRUE(pass.ok());
  EXPECT_EQ(pass->steps.size(), 1u);
  EXPECT_EQ(looks, 1);
  ASSERT_EQ(Rounds(id).size(), 2u);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(counting.Tick(clock_.Now()).ok());
  EXPECT_EQ(looks, 1);
}

// A rerun of an adaptive campaign (the nightly scheduler submits it again, as here) starts from
// what is stored: its round 1 and the rounds the stored results lead it to again find their runs
// stored by key, cost it nothing (the ledger charges what ended before it was submitted at 0), and
// it decides as the first did without a new run; its budget stays for what is still open.
TEST_F(RoundsTest, ARerunReplaysItsStoredRoundsFreeOfCharge) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t first = Submit("mine");
  ASSERT_TRUE(driver_->Step(first, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  for (int i = 0; i < 4 && !Rounds(first).back().stop_reason; ++i) {
    ASSERT_TRUE(driver_->Tick(clock_.Now()).ok());
    CompleteAll(3e-4);
  }
  ASSERT_TRUE(Rounds(first).back().stop_reason.has_value());
  ASSERT_GE(Rounds(first).size(), 2u);
  EXPECT_GT(Charged(first), 0);
  const int64_t runs = *store_->db().CountRows("runs");

  clock_.Advance(86400);
  const int64_t rerun = Submit("mine");
  ASSERT_NE(rerun, first);
  for (int i = 0; i < 4 && (Rounds(rerun).empty() || !Rounds(rerun).back().stop_reason); ++i) {
    auto pass = driver_->Tick(clock_.Now());
    ASSERT_TRUE(pass.ok());
    for (const auto& [cr, why] : pass->errors) ADD_FAILURE() << cr << ": " << why.ToString();
    EXPECT_EQ(CompleteAll(3e-4), 0);  // nothing to run: every run it orders is stored
  }
  std::vector<rounds::RoundRow> rows = Rounds(rerun);
  ASSERT_TRUE(rows.back().stop_reason.has_value());
  EXPECT_THAT(*rows.back().stop_reason, HasSubstr("decided"));
  EXPECT_EQ(rows.size(), Rounds(first).size());
  EXPECT_EQ(*store_->db().CountRows("runs"), runs);
  EXPECT_EQ(Charged(rerun), 0.0);
  for (const rounds::RoundRow& r : rows) EXPECT_EQ(r.core_h_spent.value_or(-1), 0.0);
}

// Every attempt is charged: a run whose first lease expired after a heartbeat at 0.6 s and whose
// second was handed back at 0.3 s, then done at 1 s, is charged 0.6 + 0.3 + 1 s of its point, once
// each: not again at a later look, after a daemon restart, nor by a rerun of the campaign (its
// attempts were leased before the rerun was submitted: that campaign run paid for them).
TEST_F(RoundsTest, ARetriedRunIsChargedForEachAttemptOnceAcrossLooksRestartsAndReruns) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  PrepareBed();
  auto first = queue_->Lease({"w", "host", 1});
  ASSERT_TRUE(first.ok() && first->has_value());
  ASSERT_EQ((*first)->kind, api::JobKind::kRun);
  const int64_t run_id = (*first)->id;
  api::Heartbeat beat;
  beat.sim_time_s = 0.6;
  ASSERT_TRUE(queue_->Heartbeat((*first)->token, beat).ok());
  clock_.Advance((*first)->ttl_s + 1);
  ASSERT_EQ(*queue_->ExpireLeases(), 1);
  auto second = queue_->Lease({"w", "host", 1});
  ASSERT_TRUE(second.ok() && second->has_value());
  ASSERT_EQ((*second)->id, run_id);
  beat.sim_time_s = 0.3;
  ASSERT_TRUE(queue_->Heartbeat((*second)->token, beat).ok());
  clock_.Advance(1);
  auto released = queue_->Release((*second)->token, "allocation ends (test)");
  ASSERT_TRUE(released.ok());
  ASSERT_EQ(released->state, "queued");
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);

  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  auto run = store_->GetRun(run_id);
  ASSERT_TRUE(run.ok());
  const Point p = run->summary.point;
  auto cost = rounds::AdaptiveCostNow(*store_, "smoke", clock_.Now());
  ASSERT_TRUE(cost.ok());
  const AdaptiveCost planned = rounds::RoundRates(Rounds(id)[0], *cost);
  std::vector<ChargeRow> rows = Charges(id, "run", run_id);
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].priced_by, "heartbeat");
  EXPECT_DOUBLE_EQ(rows[0].sim_time_s, 0.6);
  EXPECT_EQ(rows[1].priced_by, "heartbeat");
  EXPECT_DOUBLE_EQ(rows[1].sim_time_s, 0.3);
  EXPECT_EQ(rows[2].priced_by, "result");
  EXPECT_DOUBLE_EQ(rows[2].sim_time_s, 1.0);
  EXPECT_EQ(std::set<std::string>({rows[0].lease_token, rows[1].lease_token, rows[2].lease_token}).size(), 3u);
  const double expected = planned.RunCoreHours(p, 0.6) + planned.RunCoreHours(p, 0.3) + planned.RunCoreHours(p, 1);
  EXPECT_NEAR(rows[0].core_h + rows[1].core_h + rows[2].core_h, expected, 1e-9 * expected);
  const double charged = Charged(id);

  // Later looks, a restart, a second daemon: nothing charged again.
  for (int i = 0; i < 4 && !Rounds(id).back().stop_reason; ++i) {
    Restart();
    ASSERT_TRUE(driver_->Tick(clock_.Now()).ok());
    ASSERT_TRUE(NewDriver()->Tick(clock_.Now()).ok());
    CompleteAll(3e-4);
  }
  EXPECT_EQ(Charges(id, "run", run_id).size(), 3u);
  EXPECT_GE(Charged(id), charged);

  // A rerun of the campaign finds the run stored: its attempts cost the rerun nothing.
  clock_.Advance(86400);
  const int64_t rerun = Submit("mine");
  for (int i = 0; i < 4 && (Rounds(rerun).empty() || !Rounds(rerun).back().stop_reason); ++i) {
    ASSERT_TRUE(driver_->Tick(clock_.Now()).ok());
    CompleteAll(3e-4);
  }
  std::vector<ChargeRow> again = Charges(rerun, "run", run_id);
  ASSERT_EQ(again.size(), 3u);
  for (const ChargeRow& r : again) {
    EXPECT_EQ(r.priced_by, "leased before");
    EXPECT_EQ(r.core_h, 0.0);
  }
  EXPECT_EQ(Charges(id, "run", run_id).size(), 3u);
}

// A round's attempts are charged at the rates it was planned at (stored with its row), not at the
// cost model's rates at the look: planned and charged compare like with like.
TEST_F(RoundsTest, ARoundIsChargedAtTheRatesItWasPlannedAt) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  auto cost = rounds::AdaptiveCostNow(*store_, "smoke", clock_.Now());
  ASSERT_TRUE(cost.ok());
  std::vector<rounds::RoundRow> rows = Rounds(id);
  ASSERT_EQ(rows.size(), 1u);
  ASSERT_TRUE(rows[0].run_s_per_unit && rows[0].bed_s_per_unit);
  EXPECT_EQ(*rows[0].run_s_per_unit, cost->run_rate.s_per_unit);
  EXPECT_EQ(*rows[0].bed_s_per_unit, cost->bed_rate.s_per_unit);
  // The model has moved since round 1 was planned: here, round 1 was planned at 3x today's rates.
  ASSERT_TRUE(store_->db()
                  .Write([](Transaction& t) {
                    return t.Exec("UPDATE campaign_rounds SET run_s_per_unit = 3 * run_s_per_unit, "
                                  "bed_s_per_unit = 3 * bed_s_per_unit");
                  })
                  .ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  auto look = LookAtClaims(*store_, *store_->GetCampaignRun(id));
  ASSERT_TRUE(look.ok());
  auto now = rounds::AdaptiveCostNow(*store_, "smoke", clock_.Now());
  ASSERT_TRUE(now.ok());
  const AdaptiveCost planned = rounds::RoundRates(Rounds(id)[0], *now);
  double runs_planned = 0, runs_now = 0;  // the run rate is still the default (no result states a wall time)
  for (const ClaimRun& r : look->input.sweeps.at(0).runs) {
    runs_planned += planned.RunCoreHours(r.point, 1);
    runs_now += now->RunCoreHours(r.point, 1);
  }
  EXPECT_NEAR(runs_planned, 3 * runs_now, 1e-9 * runs_planned);
  const double at_planned = runs_planned + planned.BedCoreHours(look->input.sweeps.at(0).runs.at(0).point);
  ASSERT_TRUE(driver_->Step(id, clock_.Now()).ok());
  rows = Rounds(id);
  ASSERT_TRUE(rows[0].core_h_spent.has_value());
  EXPECT_NEAR(*rows[0].core_h_spent, at_planned, 1e-9 * at_planned);
  EXPECT_NEAR(Charged(id), at_planned, 1e-9 * at_planned);
  // The next round is planned, and will be charged, at the rates of its planning.
  if (rows.size() > 1 && !rows[0].stop_reason) {
    ASSERT_TRUE(rows[1].run_s_per_unit.has_value());
    EXPECT_EQ(*rows[1].run_s_per_unit, now->run_rate.s_per_unit);
  }
}

// The look's ledger is read before the claims are looked at and read again inside its write: a
// run of it run again meanwhile (a forced rerun of a run it shares: queued, leased, done between
// the look's reads and its write) makes the write store nothing, and the next look charges every
// attempt once, the new one included.
TEST_F(RoundsTest, AnAttemptClosingBetweenTheLooksReadsAndItsWriteIsChargedOnce) {
  int looks = 0;
  int64_t rerun_id = 0;
  RoundDriverOptions options;
  options.engine_version = kEngine;
  RoundDriver racing(
      store_.get(),
      [&](Store& store, const CampaignRunInfo& info) -> Result<ClaimLook> {
        if (++looks == 1) {
          EXPECT_TRUE(store.db()
                          .Write([&](Transaction& t) -> Status {
                            Statement st = t.Prepare(
                                "UPDATE runs SET state = 'queued' WHERE id = (SELECT MIN(sr.run_id) FROM sweep_runs sr "
                                "JOIN sweeps s ON s.id = sr.sweep_id WHERE s.campaign_run_id = ?) RETURNING id");
                            st.Bind(1, info.id);
                            Result<bool> row = st.Step();
                            if (!row.ok()) return row.status();
                            rerun_id = *row ? st.Int(0) : 0;
                            return Status::Ok();
                          })
                          .ok());
          EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 1);
        }
        return LookAtClaims(store, info);
      },
      options);
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(racing.Step(id, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  auto step = racing.Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  EXPECT_FALSE(step->has_value());
  ASSERT_GT(rerun_id, 0);
  EXPECT_FALSE(Rounds(id)[0].finished_at.has_value());
  EXPECT_EQ(Charged(id), 0.0);

  step = racing.Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  EXPECT_EQ(looks, 2);
  std::vector<ChargeRow> rows = Charges(id, "run", rerun_id);
  ASSERT_EQ(rows.size(), 2u);  // its first attempt and the one run between the reads and the write
  EXPECT_NE(rows[0].lease_token, rows[1].lease_token);
  auto all = store_->db().BeginRead();
  ASSERT_TRUE(all.ok());
  Statement st = all->Prepare("SELECT COUNT(*), SUM(core_h) FROM campaign_run_charges WHERE campaign_run_id = ?");
  st.Bind(1, id);
  ASSERT_TRUE(*st.Step());
  EXPECT_EQ(st.Int(0), 4);  // the bed, two attempts at one run, one at the other
  ASSERT_TRUE(Rounds(id)[0].core_h_spent.has_value());
  EXPECT_NEAR(*Rounds(id)[0].core_h_spent, st.Double(1), 1e-12);
}

// The look that freezes a claim stores its own verdict with it (parts, numbers, reason): a later
// evaluation that reads otherwise shows the frozen verdict, and GET .../claims shows what decided it.
TEST_F(RoundsTest, TheDecidingLooksVerdictIsStoredWithTheFrozenClaim) {
  std::vector<ClaimVerdict> last;  // the claims as the driver's last look evaluated them
  RoundDriverOptions options;
  options.engine_version = kEngine;
  RoundDriver capturing(
      store_.get(),
      [&last](Store& store, const CampaignRunInfo& info) -> Result<ClaimLook> {
        Result<ClaimLook> look = LookAtClaims(store, info);
        if (look.ok()) last = EvaluateClaims(look->claims, look->input);
        return look;
      },
      options);
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t id = Submit("mine");
  ASSERT_TRUE(capturing.Step(id, clock_.Now()).ok());
  json deciding;
  for (int i = 0; i < 4 && deciding.is_null(); ++i) {
    CompleteAll(/*rise_se=*/3e-4);
    auto step = capturing.Step(id, clock_.Now());
    ASSERT_TRUE(step.ok()) << step.status().ToString();
    auto frozen = rounds::FrozenVerdicts(*store_, id);
    ASSERT_TRUE(frozen.ok());
    if (frozen->count("S1")) deciding = ClaimVerdictToJson(last.at(0));
  }
  ASSERT_FALSE(deciding.is_null());
  auto frozen = rounds::FrozenVerdicts(*store_, id);
  ASSERT_TRUE(frozen.ok());
  const json& decided_by = frozen->at("S1").decided_by;
  EXPECT_EQ(decided_by, deciding);
  EXPECT_EQ(decided_by["verdict"], "holds");
  ASSERT_FALSE(decided_by["parts"].empty());

  // The results read otherwise now (the rising runs sink): the frozen verdict stands, and what
  // decided it is shown as that look read it.
  ASSERT_TRUE(store_->db().Write([](Transaction& t) { return t.Exec("UPDATE results SET uz = -0.01"); }).ok());
  auto claims = CheckClaims(*store_, id);
  ASSERT_TRUE(claims.ok()) << claims.status().ToString();
  const json j = CampaignRunClaimsToJson(*claims);
  ASSERT_EQ(j["claims"].size(), 1u);
  EXPECT_EQ(j["claims"][0]["verdict"], "holds");
  EXPECT_NE(j["claims"][0]["current_verdict"], "holds");
  EXPECT_EQ(j["claims"][0]["decided_by"], decided_by);
  EXPECT_THAT(j["claims"][0]["reason"].get<std::string>(), HasSubstr("decided_by"));

  // Looks after the freezing one (the driver's, which reads otherwise now, and a later round's
  // freeze that decides otherwise) leave the frozen verdict and what decided it as they were.
  const rounds::FrozenVerdict was = frozen->at("S1");
  clock_.Advance(100);
  CompleteAll(/*rise_se=*/3e-4);
  ASSERT_TRUE(capturing.Step(id, clock_.Now()).ok());
  ASSERT_TRUE(store_->db()
                  .Write([&](Transaction& t) {
                    return rounds::FreezeVerdicts(t, id, was.round + 1, clock_.Now(), {{"S1", Verdict::kDiffers}},
                                                  {{"S1", json{{"verdict", "differs"}}}});
                  })
                  .ok());
  auto later = rounds::FrozenVerdicts(*store_, id);
  ASSERT_TRUE(later.ok());
  EXPECT_EQ(later->at("S1").verdict, was.verdict);
  EXPECT_EQ(later->at("S1").round, was.round);
  EXPECT_EQ(later->at("S1").frozen_at, was.frozen_at);
  EXPECT_EQ(later->at("S1").decided_by, decided_by);
}

// A nightly rerun that starts while the night before's campaign run still runs a run they share:
// the attempt leased before the rerun is the earlier campaign run's to pay, and so is one leased
// after it (the lease expired and the run went again) while that campaign run has not stopped.
// Each attempt is charged once, to the campaign run that leased it; the rerun records it at 0.
TEST_F(RoundsTest, ARunSharedWithTheNightBeforeIsPaidOnceByTheCampaignRunThatLeasedIt) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t night = Submit("mine");
  ASSERT_TRUE(driver_->Step(night, clock_.Now()).ok());
  PrepareBed();
  auto first = queue_->Lease({"w", "host", 1});
  ASSERT_TRUE(first.ok() && first->has_value());
  const int64_t run_id = (*first)->id;
  api::Heartbeat beat;
  beat.sim_time_s = 0.5;
  ASSERT_TRUE(queue_->Heartbeat((*first)->token, beat).ok());
  clock_.Advance(10);
  const int64_t rerun = Submit("mine");  // the next night's, while run_id still runs
  ASSERT_NE(rerun, night);
  clock_.Advance((*first)->ttl_s + 1);
  ASSERT_EQ(*queue_->ExpireLeases(), 1);  // lost: it goes again, leased after the rerun began
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  ASSERT_TRUE(driver_->Step(night, clock_.Now()).ok());
  ASSERT_TRUE(driver_->Step(rerun, clock_.Now()).ok());
  std::vector<ChargeRow> paid = Charges(night, "run", run_id);
  std::vector<ChargeRow> free = Charges(rerun, "run", run_id);
  ASSERT_EQ(paid.size(), 2u);
  ASSERT_EQ(free.size(), 2u);
  EXPECT_EQ(paid[0].priced_by, "heartbeat");
  EXPECT_EQ(paid[1].priced_by, "result");
  for (const ChargeRow& r : paid) EXPECT_GT(r.core_h, 0);
  EXPECT_EQ(free[0].priced_by, "leased before");
  EXPECT_EQ(free[1].priced_by, "paid by campaign run " + std::to_string(night));
  for (const ChargeRow& r : free) EXPECT_EQ(r.core_h, 0.0);
  EXPECT_EQ(Charged(rerun), 0.0);
}

// Who pays for an attempt is decided when it is leased (issue 31, referee 7a F1a): a run the newer
// campaign run K leased and charged, that the older M's later round adds (the same key, reused
// done, as AddPlannedRuns does), costs M nothing: M records it "paid by campaign run K". Each
// attempt at it and its bed is charged in full by one ledger.
TEST_F(RoundsTest, ARunAnOlderCampaignRunAddsAfterANewerOneRanItIsChargedOnce) {
  ASSERT_TRUE(SaveCampaign(*store_, "m", Adaptive(50), kEngine, clock_.Now()).ok());
  json other = Adaptive(50);
  other["sweeps"][0]["axes"][0]["values"] = {-90, 90};  // other keys than M's
  ASSERT_TRUE(SaveCampaign(*store_, "k", other, kEngine, clock_.Now()).ok());
  const int64_t m = Submit("m");
  ASSERT_TRUE(driver_->Step(m, clock_.Now()).ok());
  clock_.Advance(10);
  const int64_t k = Submit("k");
  ASSERT_GT(k, m);
  ASSERT_TRUE(driver_->Step(k, clock_.Now()).ok());
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 4);
  const std::string k_runs = "SELECT MIN(sr.run_id) FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
                             "WHERE s.campaign_run_id = ?";
  const auto r = static_cast<int64_t>(Query(k_runs, k));
  const auto bed = static_cast<int64_t>(Query("SELECT bed_id FROM runs WHERE id = ?", r));
  ASSERT_TRUE(driver_->Step(k, clock_.Now()).ok());  // K's look charges r
  std::vector<ChargeRow> paid = Charges(k, "run", r);
  ASSERT_EQ(paid.size(), 1u);
  EXPECT_GT(paid[0].core_h, 0);

  // M's next round orders the same key: r joins M's sweep.
  Exec("INSERT INTO sweep_runs (sweep_id, run_id, position) SELECT s.id, " + std::to_string(r) +
       ", 1000 FROM sweeps s WHERE s.campaign_run_id = " + std::to_string(m));
  ASSERT_TRUE(driver_->Step(m, clock_.Now()).ok());
  std::vector<ChargeRow> free = Charges(m, "run", r);
  ASSERT_EQ(free.size(), 1u);
  EXPECT_EQ(free[0].priced_by, "paid by campaign run " + std::to_string(k));
  EXPECT_EQ(free[0].core_h, 0.0);
  LookUntilQuiet(3e-4);
  for (const auto& [token, n] : FullCharges("run", r)) EXPECT_EQ(n, 1) << "run lease " << token;
  for (const auto& [token, n] : FullCharges("bed", bed)) EXPECT_EQ(n, 1) << "bed lease " << token;
}

// F1b: a failed longer run that N's replacement settled out of its sweep stays N's run (its
// ledger and its look's wait count it). Run again because another campaign run asks for its key,
// its new attempt is charged in full once over every ledger.
TEST_F(RoundsTest, AReplacedRunRunAgainForAnotherCampaignRunIsChargedOnce) {
  ASSERT_TRUE(SaveCampaign(*store_, "n", Adaptive(50), kEngine, clock_.Now()).ok());
  json other = Adaptive(50);
  other["sweeps"][0]["axes"][0]["values"] = {-90, 90};  // other keys than N's
  ASSERT_TRUE(SaveCampaign(*store_, "k", other, kEngine, clock_.Now()).ok());
  const int64_t n = Submit("n");
  ASSERT_TRUE(driver_->Step(n, clock_.Now()).ok());
  const int64_t k = Submit("k");
  ASSERT_TRUE(driver_->Step(k, clock_.Now()).ok());
  fails_ = [](const Point& p) { return p.Omega == 90; };
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 3);
  fails_ = nullptr;
  const auto r = static_cast<int64_t>(
      Query("SELECT r.id FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id JOIN runs r ON r.id = sr.run_id "
            "WHERE s.campaign_run_id = ? AND r.state = 'failed'",
            k));
  // N had ordered r as the longer run at one of its points; r failed and the look settled it out
  // of N's sweep, the earlier run back in its place (what SettleReplacements leaves).
  Exec("INSERT INTO campaign_run_replacements (campaign_run_id, round, sweep_id, position, old_run_id, new_run_id, "
       "outcome, settled_at) SELECT " + std::to_string(n) + ", 1, sr.sweep_id, sr.position, sr.run_id, " +
       std::to_string(r) + ", 'restored', 1 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
       "WHERE s.campaign_run_id = " + std::to_string(n) + " ORDER BY sr.position LIMIT 1");
  clock_.Advance(10);
  const int64_t again = Submit("k");  // asks for r's key: the failed run is queued again
  ASSERT_NE(again, k);
  EXPECT_EQ(Query("SELECT state = 'queued' FROM runs WHERE id = ?", r), 1.0);
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 1);
  LookUntilQuiet(3e-4);
  std::map<std::string, int> full = FullCharges("run", r);
  ASSERT_EQ(full.size(), 2u);  // its failed attempt and the one for `again`
  for (const auto& [token, count] : full) EXPECT_EQ(count, 1) << "run lease " << token;
}

// F1c: a campaign run cancelled while a run it shares with a later one still runs pays for the
// attempt it leased, and not for what is leased for the other after its cancel (a retry, and the
// shared run never leased before it): those the live campaign run pays.
TEST_F(RoundsTest, ACancelledCampaignRunIsNotBilledForAttemptsLeasedForAnotherAfterItsCancel) {
  ASSERT_TRUE(SaveCampaign(*store_, "mine", Adaptive(50), kEngine, clock_.Now()).ok());
  const int64_t cancelled = Submit("mine");
  ASSERT_TRUE(driver_->Step(cancelled, clock_.Now()).ok());
  PrepareBed();
  auto first = queue_->Lease({"w", "host", 1});
  ASSERT_TRUE(first.ok() && first->has_value());
  const int64_t run_id = (*first)->id;
  api::Heartbeat beat;
  beat.sim_time_s = 0.5;
  ASSERT_TRUE(queue_->Heartbeat((*first)->token, beat).ok());
  clock_.Advance(10);
  const int64_t live = Submit("mine");  // the next night's: shares both runs
  auto info = store_->GetCampaignRun(cancelled);
  ASSERT_TRUE(info.ok());
  for (int64_t sweep : info->sweep_ids) {
    auto c = queue_->Cancel(sweep);
    ASSERT_TRUE(c.ok()) << c.status().ToString();
    EXPECT_EQ(c->cancelled, 0);  // the live campaign run still wants them
  }
  const double cancelled_at = clock_.Now();
  clock_.Advance((*first)->ttl_s + 1);
  ASSERT_EQ(*queue_->ExpireLeases(), 1);  // goes again, for the live campaign run
  EXPECT_EQ(CompleteAll(/*rise_se=*/1.6e-3), 2);
  ASSERT_TRUE(driver_->Step(cancelled, clock_.Now()).ok());
  ASSERT_TRUE(driver_->Step(live, clock_.Now()).ok());
  ASSERT_TRUE(Rounds(cancelled).back().stop_reason.has_value());

  std::vector<ChargeRow> before = Charges(cancelled, "run", run_id);
  ASSERT_EQ(before.size(), 2u);
  EXPECT_EQ(before[0].lease_token, (*first)->token);
  EXPECT_EQ(before[0].priced_by, "heartbeat");  // leased before its cancel: its own
  EXPECT_GT(before[0].core_h, 0);
  EXPECT_EQ(before[1].priced_by, "paid by campaign run " + std::to_string(live));
  // Nothing leased after the cancel is billed to it; each such attempt is the live one's, in full.
  EXPECT_EQ(Query("SELECT COUNT(*) FROM campaign_run_charges c JOIN leases l ON l.token = c.lease_token "
                  "WHERE c.campaign_run_id = ? AND l.granted_at > " + std::to_string(cancelled_at) +
                  " AND c.core_h > 0",
                  cancelled),
            0.0);
  EXPECT_GE(Query("SELECT COUNT(*) FROM leases WHERE granted_at > " + std::to_string(cancelled_at)), 2.0);
  EXPECT_EQ(Query("SELECT COUNT(*) FROM leases l WHERE l.granted_at > " + std::to_string(cancelled_at) +
                  " AND NOT EXISTS (SELECT 1 FROM campaign_run_charges c WHERE c.lease_token = l.token "
                  "AND c.campaign_run_id = ? AND c.core_h > 0)",
                  live),
            0.0);
  for (const auto& [token, n] : FullCharges("run", run_id)) EXPECT_EQ(n, 1) << "run lease " << token;
}

TEST_F(RoundsTest, ABudgetBelowTheFirstRoundIsRefusedAtPutAndAtSubmission) {
  auto saved = SaveCampaign(*store_, "mine", Adaptive(1e-4), kEngine, clock_.Now());
  ASSERT_FALSE(saved.ok());
  EXPECT_EQ(saved.status().code(), StatusCode::kFailedPrecondition);
  EXPECT_EQ(saved.status().field(), "adaptive.budget_core_h");
  EXPECT_THAT(saved.status().reason(), HasSubstr("needs at least"));
  EXPECT_THAT(saved.status().reason(), HasSubstr("cost model"));
  EXPECT_EQ(*store_->db().CountRows("campaign_versions"), 0);

  // Stored with a budget that paid for round 1 then, submitted when it no longer does (the check
  // at submission reads the rates of the moment; here, a budget the store was handed directly).
  StoredCampaign row;
  row.name = "mine";
  row.definition = Adaptive(1e-4);
  row.definition["name"] = "mine";
  ASSERT_TRUE(PutCampaign(*store_, row).ok());
  SubmitRequest request;
  request.campaign = "mine";
  auto sub = sandswim::Submit(*store_, request, kEngine, clock_.Now());
  ASSERT_FALSE(sub.ok());
  EXPECT_EQ(sub.status().field(), "adaptive.budget_core_h");
  EXPECT_EQ(*store_->db().CountRows("campaign_runs"), 0);
}

}  // namespace
}  // namespace sandswim
