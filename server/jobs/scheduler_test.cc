#include "server/jobs/scheduler.h"

#include <time.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/keys.h"
#include "platform/clock.h"
#include "server/analysis/drift_report.h"
#include "server/jobs/lease_queue.h"
#include "server/store/store.h"
#include "server/jobs/submission.h"
#include "tests/fixture_file.h"
#include "server/store/campaigns.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

namespace fs = std::filesystem;

constexpr char kNewEngine[] = "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.1, test)";

double Utc(int y, int mo, int d, int h, int mi, int s = 0) {
  struct tm tm {};
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  tm.tm_sec = s;
  return static_cast<double>(timegm(&tm));
}

// Two points (Omega = -80 and +80) at smoke scale, due every night at 02:00.
nlohmann::json TinyCampaign() {
  return nlohmann::json::parse(
      R"({"name": "tiny", "description": "two points", "scale": "smoke", "schedule": "0 2 * * *",
    "drift_tolerance_mps": 0.005,
    "sweeps": [{"name": "sign",
                "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
                "axes": [{"param": "Omega", "values": [-80, 80]}]}]})");
}

class SchedulerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    clock_.Set(Utc(2026, 11, 22, 12, 0));
    Restart();
    StoredCampaign c;
    c.name = "tiny";
    c.definition = TinyCampaign();
    c.schedule = "0 2 * * *";
    c.updated_at = clock_.Now();
    ASSERT_TRUE(PutCampaign(*store_, c).ok());
  }
  void TearDown() override {
    scheduler_.reset();
    queue_.reset();
  }
  // A daemon (re)start: a reopened Store on the same file, a new Scheduler, registration.
  void Restart(const std::string& engine = kTestEngine) {
    scheduler_.reset();
    queue_.reset();
    ASSERT_TRUE(store_.Reopen());
    queue_ = std::make_unique<LeaseQueue>(store_.get(), &clock_);
    scheduler_ = std::make_unique<Scheduler>(store_.get(), &clock_, engine, CronZone::kUtc);
  }
  void Register() {
    Status s = scheduler_->Register({{"tiny", std::nullopt}});
    ASSERT_TRUE(s.ok()) << s.ToString();
  }
  std::vector<ScheduledRerun> Tick() {
    auto r = scheduler_->Tick();
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    if (!r.ok()) return {};
    for (const auto& [name, status] : r->errors) ADD_FAILURE() << name << ": " << status.ToString();
    return r->submitted;
  }
  int64_t CampaignRuns() { return store_->db().CountRows("campaign_runs").value(); }

  // Works off the queue: the bed (if any), then every run, with U_z chosen by the run's Omega.
  void CompleteAll(double uz_minus, double uz_plus) {
    while (true) {
      auto g = queue_->Lease({"w", "host", 1});
      ASSERT_TRUE(g.ok()) << g.status().ToString();
      if (!g->has_value()) return;
      const api::LeaseGrant& grant = **g;
      api::Completion c;
      c.ok = true;
      c.execution.host = "host";
      c.execution.engine_version = kTestEngine;
      if (grant.kind == api::JobKind::kBed) {
        const std::string bytes = "restart " + grant.key;
        ASSERT_TRUE(queue_->PutBedRestart(grant.token, bytes, Sha256Hex(bytes), store_.dir().string()).ok());
        c.bed_result = api::BedResult{};
        c.bed_result->grains = 100;
        c.bed_result->sha256 = Sha256Hex(bytes);
      } else {
        auto run = store_->GetRun(grant.id);
        ASSERT_TRUE(run.ok());
        c.result = api::RunResult{};
        c.result->uz = run->summary.point.Omega < 0 ? uz_minus : uz_plus;
        c.result->uz_blocks = 4;
        c.result->conclusive = inconclusive_omega_ == 0 || run->summary.point.Omega != inconclusive_omega_;
        c.result->stop_reason = "duration";
        c.trajectory = api::Trajectory{{0, 0.1}, {0, 0}, {0, 0}, {0, -0.001}};
      }
      clock_.Advance(1);
      auto reply = queue_->Complete(grant.token, c);
      ASSERT_TRUE(reply.ok()) << reply.status().ToString();
      ASSERT_EQ(reply->state, "done");
    }
  }
  std::vector<DriftReport> Reports() {
    auto r = ReportFinishedCampaignRuns(*store_, clock_.Now(), CronZone::kUtc);
    EXPECT_TRUE(r.ok()) << r.status().ToString();
    return r.ok() ? *r : std::vector<DriftReport>{};
  }

  FakeClock clock_;
  testing::TempStore store_{"sched"};
  std::unique_ptr<LeaseQueue> queue_;
  std::unique_ptr<Scheduler> scheduler_;
  double inconclusive_omega_ = 0;  // CompleteAll marks this point's result inconclusive (0: none)
};

TEST_F(SchedulerTest, FiresExactlyOncePerDueTime) {
  Register();
  EXPECT_TRUE(Tick().empty());
  clock_.Set(Utc(2026, 11, 23, 1, 59, 59));
  EXPECT_TRUE(Tick().empty());
  clock_.Set(Utc(2026, 11, 23, 2, 0, 0));
  auto fired = Tick();
  ASSERT_EQ(fired.size(), 1u);
  EXPECT_EQ(fired[0].due_time, Utc(2026, 11, 23, 2, 0));
  EXPECT_EQ(fired[0].scale, "smoke");
  EXPECT_EQ(fired[0].runs, 2);
  EXPECT_EQ(fired[0].skipped, 0);
  EXPECT_FALSE(fired[0].replayed);
  // Many ticks within the same minute (and the rest of the day) submit nothing more.
  for (int s = 1; s < 60; s += 3) {
    clock_.Set(Utc(2026, 11, 23, 2, 0, s));
    EXPECT_TRUE(Tick().empty()) << s;
  }
  clock_.Set(Utc(2026, 11, 23, 23, 59));
  EXPECT_TRUE(Tick().empty());
  EXPECT_EQ(CampaignRuns(), 1);

  auto run = store_->GetCampaignRun(fired[0].campaign_run_id);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->trigger, "schedule");
  ASSERT_TRUE(run->due_time.has_value());
  EXPECT_EQ(*run->due_time, Utc(2026, 11, 23, 2, 0));

  // The next night fires once more.
  clock_.Set(Utc(2026, 11, 24, 2, 0, 20));
  fired = Tick();
  ASSERT_EQ(fired.size(), 1u);
  EXPECT_EQ(fired[0].due_time, Utc(2026, 11, 24, 2, 0));
  EXPECT_EQ(fired[0].runs_reused + fired[0].runs_shared, 2);  // nothing new to run: same keys
  EXPECT_TRUE(Tick().empty());
  EXPECT_EQ(CampaignRuns(), 2);
  EXPECT_NE(DescribeRerun(fired[0], CronZone::kUtc).find("tiny@smoke night 2026-11-24 02:00: submitted campaign run"),
            std::string::npos)
      << DescribeRerun(fired[0], CronZone::kUtc);
}

TEST_F(SchedulerTest, RestartAtTheDueMinuteDoesNotSubmitAgain) {
  Register();
  clock_.Set(Utc(2026, 11, 23, 2, 0, 5));
  ASSERT_EQ(Tick().size(), 1u);
  // The daemon restarts within the same minute.
  clock_.Set(Utc(2026, 11, 23, 2, 0, 40));
  Restart();
  Register();
  EXPECT_TRUE(Tick().empty());
  EXPECT_EQ(CampaignRuns(), 1);
  // And if a submission for that minute came again anyway, the store answers with the first.
  SubmitRequest again;
  again.campaign = "tiny";
  again.trigger = "schedule";
  again.due_time = Utc(2026, 11, 23, 2, 0);
  auto r = Submit(*store_, again, kTestEngine, clock_.Now());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->replayed);
  EXPECT_EQ(CampaignRuns(), 1);
}

TEST_F(SchedulerTest, RestartJustBeforeTheDueMinuteStillFiresOnce) {
  Register();
  clock_.Set(Utc(2026, 11, 23, 1, 59, 30));
  EXPECT_TRUE(Tick().empty());
  Restart();
  Register();  // first_seen_at is kept: the 02:00 slot still belongs to the schedule
  clock_.Set(Utc(2026, 11, 23, 2, 3));
  EXPECT_EQ(Tick().size(), 1u);
  EXPECT_TRUE(Tick().empty());
  EXPECT_EQ(CampaignRuns(), 1);
}

TEST_F(SchedulerTest, MissedNightsRunOnceAtStart) {
  Register();
  clock_.Set(Utc(2026, 11, 23, 2, 1));
  ASSERT_EQ(Tick().size(), 1u);
  // Down from the 23rd until the 27th at 09:00: nights 24, 25, 26 and 27 were missed.
  clock_.Set(Utc(2026, 11, 27, 9, 0));
  Restart();
  Register();
  auto fired = Tick();
  ASSERT_EQ(fired.size(), 1u);
  EXPECT_EQ(fired[0].due_time, Utc(2026, 11, 27, 2, 0));  // only the latest
  EXPECT_EQ(fired[0].skipped, 3);
  EXPECT_TRUE(Tick().empty());
  EXPECT_EQ(CampaignRuns(), 2);
}

TEST_F(SchedulerTest, NothingBeforeTheCampaignWasFirstRegistered) {
  clock_.Set(Utc(2026, 11, 23, 2, 30));
  Register();  // registered after tonight's 02:00: that night is not "missed"
  EXPECT_TRUE(Tick().empty());
  auto list = scheduler_->List();
  ASSERT_TRUE(list.ok());
  ASSERT_EQ(list->size(), 1u);
  ASSERT_TRUE((*list)[0].next_due.has_value());
  EXPECT_EQ(*(*list)[0].next_due, Utc(2026, 11, 24, 2, 0));
}

TEST_F(SchedulerTest, ReEnablingAfterAPauseDoesNotRunStaleNights) {
  Register();
  ASSERT_TRUE(scheduler_->Register({}, /*exclusive=*/true).ok());  // --schedule dropped
  clock_.Set(Utc(2026, 11, 25, 9, 0));
  EXPECT_TRUE(Tick().empty());
  Register();  // back again: starts now
  EXPECT_TRUE(Tick().empty());
  clock_.Set(Utc(2026, 11, 26, 2, 0));
  EXPECT_EQ(Tick().size(), 1u);
}

TEST_F(SchedulerTest, RegistrationErrorsNameTheFlag) {
  Status s = scheduler_->Register({{"no-such-campaign", std::nullopt}});
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_EQ(s.field(), "--schedule");
  s = scheduler_->Register({{"tiny", std::nullopt}, {"tiny", std::string("mini")}});
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  StoredCampaign manual;
  manual.name = "manual-only";
  manual.definition = TinyCampaign();
  manual.definition.erase("schedule");
  manual.definition["name"] = "manual-only";
  ASSERT_TRUE(PutCampaign(*store_, manual).ok());
  s = scheduler_->Register({{"manual-only", std::nullopt}});
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_NE(s.reason().find("no \"schedule\""), std::string::npos) << s.reason();
  EXPECT_EQ(store_->db().CountRows("campaign_schedules").value(), 0);  // nothing half-written

  // The builtin campaign registers by name.
  EXPECT_TRUE(scheduler_->Register({{"paper-58", std::string("smoke")}}).ok());

  EXPECT_FALSE(ParseScheduleFlag("").ok());
  EXPECT_FALSE(ParseScheduleFlag("paper-58:huge").ok());
  EXPECT_FALSE(ParseScheduleFlag("a b").ok());
  auto flag = ParseScheduleFlag("paper-58:smoke");
  ASSERT_TRUE(flag.ok());
  EXPECT_EQ(flag->campaign, "paper-58");
  EXPECT_EQ(flag->scale, "smoke");
  flag = ParseScheduleFlag("paper-58");
  ASSERT_TRUE(flag.ok());
  EXPECT_FALSE(flag->scale.has_value());
}

// An inconclusive result (too few whole periods) is counted as such and never compared, however
// far it moved.
TEST_F(SchedulerTest, DriftReportNeverComparesAnInconclusiveResult) {
  Register();
  clock_.Set(Utc(2026, 11, 23, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  CompleteAll(-0.010, 0.020);
  ASSERT_EQ(Reports().size(), 1u);
  Restart(kNewEngine);
  Register();
  inconclusive_omega_ = 80;
  clock_.Set(Utc(2026, 11, 24, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  CompleteAll(-0.010, 0.090);
  auto second = Reports();
  ASSERT_EQ(second.size(), 1u);
  EXPECT_EQ(second[0].inconclusive, 1);
  EXPECT_EQ(second[0].compared, 1);
  EXPECT_EQ(second[0].drifted, 0);
  EXPECT_EQ(second[0].summary,
            "tiny@smoke night 2026-11-24 02:00: 2 points, 0 reused, 2 run, 0 drifted beyond 0.005 m/s, "
            "1 inconclusive (not compared)");
  for (const DriftPoint& p : second[0].rows) {
    EXPECT_EQ(p.inconclusive, p.point["Omega"].get<double>() > 0);
    EXPECT_EQ(p.difference.has_value(), p.point["Omega"].get<double>() < 0);
  }
}

TEST_F(SchedulerTest, DriftReportFlagsOnlyChangesBeyondTheTolerance) {
  Register();
  clock_.Set(Utc(2026, 11, 23, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  EXPECT_TRUE(Reports().empty());  // runs still queued: no report yet
  CompleteAll(-0.010, 0.020);
  auto first = Reports();
  ASSERT_EQ(first.size(), 1u);
  EXPECT_EQ(first[0].points, 2);
  EXPECT_EQ(first[0].ran, 2);
  EXPECT_EQ(first[0].compared, 0);
  EXPECT_FALSE(first[0].previous_campaign_run_id.has_value());
  EXPECT_EQ(first[0].summary,
            "tiny@smoke night 2026-11-23 02:00: 2 points, 0 reused, 2 run, 0 drifted beyond 0.005 m/s; "
            "first report, nothing to compare");
  EXPECT_TRUE(Reports().empty());  // made once

  // The engine is upgraded: new content keys, every point runs again. Omega=-80 moves by
  // 0.001 m/s (within 0.005), Omega=+80 by 0.010 m/s (beyond).
  Restart(kNewEngine);
  Register();
  clock_.Set(Utc(2026, 11, 24, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  CompleteAll(-0.009, 0.030);
  auto second = Reports();
  ASSERT_EQ(second.size(), 1u);
  const DriftReport& r = second[0];
  EXPECT_EQ(r.previous_campaign_run_id, first[0].campaign_run_id);
  EXPECT_EQ(r.compared, 2);
  EXPECT_EQ(r.drifted, 1);
  EXPECT_EQ(r.summary, "tiny@smoke night 2026-11-24 02:00: 2 points, 0 reused, 2 run, 1 drifted beyond 0.005 m/s");
  ASSERT_EQ(r.rows.size(), 2u);
  for (const DriftPoint& p : r.rows) {
    ASSERT_TRUE(p.difference.has_value());
    if (p.point["Omega"].get<double>() < 0) {
      EXPECT_NEAR(*p.difference, 0.001, 1e-12);
      EXPECT_FALSE(p.drifted);
    } else {
      EXPECT_NEAR(*p.difference, 0.010, 1e-12);
      EXPECT_TRUE(p.drifted);
    }
  }

  // The next night reuses both results: nothing runs, nothing drifts.
  clock_.Set(Utc(2026, 11, 25, 2, 0, 10));
  auto fired = Tick();
  ASSERT_EQ(fired.size(), 1u);
  EXPECT_EQ(fired[0].runs_reused, 2);
  auto third = Reports();
  ASSERT_EQ(third.size(), 1u);
  EXPECT_EQ(third[0].summary,
            "tiny@smoke night 2026-11-25 02:00: 2 points, 2 reused, 0 run, 0 drifted beyond 0.005 m/s");

  // Read back: the latest report of the campaign, and each campaign run's own.
  auto latest = LatestDriftReport(*store_, "tiny");
  ASSERT_TRUE(latest.ok() && latest->has_value());
  EXPECT_EQ((*latest)->campaign_run_id, third[0].campaign_run_id);
  auto at_scale = LatestDriftReport(*store_, "tiny", "mini");
  ASSERT_TRUE(at_scale.ok());
  EXPECT_FALSE(at_scale->has_value());
  auto own = DriftReportFor(*store_, second[0].campaign_run_id);
  ASSERT_TRUE(own.ok() && own->has_value());
  EXPECT_EQ((*own)->drifted, 1);
  EXPECT_EQ((*own)->rows.size(), 2u);
}

TEST_F(SchedulerTest, DriftReportCountsFailedRunsAsMissing) {
  SubmitRequest manual;
  manual.campaign = "tiny";
  auto submitted = Submit(*store_, manual, kTestEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok());
  auto cancelled = queue_->Cancel(submitted->sweep_ids.at(0));
  ASSERT_TRUE(cancelled.ok());
  auto reports = Reports();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].missing, 2);
  EXPECT_EQ(reports[0].trigger, "manual");
  EXPECT_NE(reports[0].summary.find("tiny@smoke rerun cr:"), std::string::npos) << reports[0].summary;
  EXPECT_NE(reports[0].summary.find("2 failed or cancelled"), std::string::npos) << reports[0].summary;
}

// A schedule given through the API (PUT /api/v1/campaigns/{name}/schedule) for a campaign of
// one's own whose definition states none: it reruns on the fake clock's nights, and restarts
// with no --schedule flag (which disable every flag's schedule) keep it.
TEST_F(SchedulerTest, AnApiScheduleOfAStoredCampaignRerunsAndSurvivesRestarts) {
  nlohmann::json mine = TinyCampaign();
  mine.erase("schedule");
  mine["name"] = "mine";
  StoredCampaign c;
  c.name = "mine";
  c.definition = mine;
  c.updated_at = clock_.Now();
  ASSERT_TRUE(PutCampaign(*store_, c).ok());
  // The definition states no schedule: a flag alone is refused, as before.
  EXPECT_FALSE(scheduler_->Register({{"mine", std::nullopt}}).ok());
  auto put = scheduler_->Put("mine", "0 3 * * *", std::nullopt);
  ASSERT_TRUE(put.ok()) << put.status().ToString();
  EXPECT_EQ(put->scale, "smoke");
  EXPECT_EQ(put->source, "api");
  EXPECT_EQ(put->next_due, Utc(2026, 11, 23, 3, 0));

  Restart();
  ASSERT_TRUE(scheduler_->Register({}).ok());  // sandswimd started without --schedule
  clock_.Set(Utc(2026, 11, 23, 3, 0, 10));
  auto fired = Tick();
  ASSERT_EQ(fired.size(), 1u);
  EXPECT_EQ(fired[0].campaign, "mine");
  EXPECT_EQ(fired[0].due_time, Utc(2026, 11, 23, 3, 0));

  // Down over the next night and back the morning after: that night runs once at start.
  clock_.Set(Utc(2026, 11, 24, 9, 0));
  Restart();
  ASSERT_TRUE(scheduler_->Register({}).ok());
  fired = Tick();
  ASSERT_EQ(fired.size(), 1u);
  EXPECT_EQ(fired[0].due_time, Utc(2026, 11, 24, 3, 0));
  EXPECT_EQ(CampaignRuns(), 2);
  // A --schedule flag for it now takes the API's cron, and a start without it keeps the schedule.
  ASSERT_TRUE(scheduler_->Register({{"mine", std::nullopt}}).ok());
  Restart();
  ASSERT_TRUE(scheduler_->Register({}).ok());
  auto kept = scheduler_->Find("mine");
  ASSERT_TRUE(kept.ok() && kept->has_value());
  EXPECT_EQ((*kept)->cron, "0 3 * * *");

  ASSERT_TRUE(scheduler_->Remove("mine").ok());
  EXPECT_EQ(scheduler_->Remove("mine").code(), StatusCode::kNotFound);
  clock_.Set(Utc(2026, 11, 25, 3, 0, 10));
  EXPECT_TRUE(Tick().empty());
}

// Drift compares a run only with one of the same definition: after an edit the report says the
// definition changed and compares nothing; the next night of the new definition compares again.
TEST_F(SchedulerTest, DriftSaysWhenTheDefinitionChanged) {
  Register();
  clock_.Set(Utc(2026, 11, 23, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  CompleteAll(-0.010, 0.020);
  ASSERT_EQ(Reports().size(), 1u);

  nlohmann::json edited = TinyCampaign();
  edited["description"] = "two points, edited";
  StoredCampaign c;
  c.name = "tiny";
  c.definition = edited;
  c.schedule = "0 2 * * *";
  c.updated_at = clock_.Now();
  ASSERT_TRUE(PutCampaign(*store_, c).ok());

  clock_.Set(Utc(2026, 11, 24, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  auto changed = Reports();
  ASSERT_EQ(changed.size(), 1u);
  ASSERT_TRUE(changed[0].definition_changed.has_value());
  EXPECT_EQ(changed[0].definition_changed->from_version, 1);
  EXPECT_EQ(changed[0].definition_changed->to_version, 2);
  EXPECT_FALSE(changed[0].previous_campaign_run_id.has_value());
  EXPECT_EQ(changed[0].compared, 0);
  EXPECT_EQ(changed[0].summary,
            "tiny@smoke night 2026-11-24 02:00: 2 points, 2 reused, 0 run, 0 drifted beyond 0.005 m/s; "
            "definition changed (version 1 -> 2), no earlier run of this definition to compare with");
  // Stored and read back with it.
  auto own = DriftReportFor(*store_, changed[0].campaign_run_id);
  ASSERT_TRUE(own.ok() && own->has_value());
  ASSERT_TRUE((*own)->definition_changed.has_value());
  EXPECT_EQ((*own)->definition_changed->to_version, 2);

  clock_.Set(Utc(2026, 11, 25, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  auto next = Reports();
  ASSERT_EQ(next.size(), 1u);
  EXPECT_FALSE(next[0].definition_changed.has_value());
  EXPECT_EQ(next[0].previous_campaign_run_id, changed[0].campaign_run_id);
  EXPECT_EQ(next[0].compared, 2);
}

// A campaign run's drift is held to the tolerance of the definition it recorded, not to that of
// the campaign's version when its report is made (before, the campaign's current one: 0.05 here).
TEST_F(SchedulerTest, DriftUsesTheToleranceOfTheDefinitionTheRunRecorded) {
  auto put = [&](double tolerance) {
    StoredCampaign c;
    c.name = "tiny";
    c.definition = TinyCampaign();
    c.definition["drift_tolerance_mps"] = tolerance;
    c.schedule = "0 2 * * *";
    c.updated_at = clock_.Now();
    ASSERT_TRUE(PutCampaign(*store_, c).ok());
  };
  put(0.01);  // version 2 (SetUp stored version 1 at 0.005)
  Register();
  clock_.Set(Utc(2026, 11, 23, 2, 0, 10));
  auto first = Tick();
  ASSERT_EQ(first.size(), 1u);
  put(0.05);  // version 3, while version 2's runs are still queued
  CompleteAll(-0.010, 0.020);
  auto reports = Reports();
  ASSERT_EQ(reports.size(), 1u);
  EXPECT_EQ(reports[0].campaign_run_id, first[0].campaign_run_id);
  EXPECT_EQ(reports[0].tolerance_mps, 0.01);
  EXPECT_NE(reports[0].summary.find("drifted beyond 0.01 m/s"), std::string::npos) << reports[0].summary;

  // The next night runs version 3: its own tolerance.
  clock_.Set(Utc(2026, 11, 24, 2, 0, 10));
  ASSERT_EQ(Tick().size(), 1u);
  auto next = Reports();
  ASSERT_EQ(next.size(), 1u);
  EXPECT_EQ(next[0].tolerance_mps, 0.05);
  ASSERT_TRUE(next[0].definition_changed.has_value());
  EXPECT_EQ(next[0].definition_changed->from_version, 2);
  EXPECT_EQ(next[0].definition_changed->to_version, 3);
}

}  // namespace
}  // namespace sandswim
