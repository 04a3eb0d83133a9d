#include "server/jobs/submission.h"

#include "server/store/campaigns.h"

#include <filesystem>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>

#include <gtest/gtest.h>

#include "core/deck.h"
#include "core/keys.h"
#include "platform/clock.h"
#include "server/jobs/lease_queue.h"
#include "server/store/store.h"
#include "server/store/temp_store_test_util.h"
#include "tests/fixture_file.h"

namespace sandswim {
namespace {

namespace fs = std::filesystem;

const char* const kTables[] = {"campaigns", "campaign_runs", "submissions", "sweeps",  "beds",
                               "runs",      "sweep_runs",    "leases",      "results", "trajectories",
                               "run_logs",  "events",        "counters"};

nlohmann::json Sweep(const std::string& name, std::vector<double> omegas = {-80, 80}) {
  return {{"name", name},
          {"scale", "smoke"},
          {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -80}, {"duration_s", 0.3}}},
          {"axes", {{{"param", "Omega"}, {"values", omegas}}}},
          {"combine", "product"}};
}

class SubmissionTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(store_); }
  Result<SubmitResult> SubmitBody(const nlohmann::json& body, bool force = false,
                                  std::optional<std::string> key = std::nullopt) {
    Result<SubmitRequest> req = ParseSubmitRequest(body);
    if (!req.ok()) return req.status();
    req->force = req->force || force;
    req->idempotency_key = key;
    return Submit(*store_, *req, kTestEngine, clock_.Now());
  }
  std::map<std::string, int64_t> AllRows() {
    std::map<std::string, int64_t> out;
    for (const char* t : kTables) out[t] = store_->db().CountRows(t).value();
    return out;
  }
  int64_t Rows(const std::string& t) { return store_->db().CountRows(t).value(); }

  FakeClock clock_;
  testing::TempStore store_{"sub"};
};

TEST_F(SubmissionTest, InsertsBedRunsSweepAndMembershipInOrder) {
  auto r = SubmitBody(Sweep("omega-sign"));
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->sweep_ids.size(), 1u);
  EXPECT_EQ(r->runs, 2);
  EXPECT_EQ(r->runs_new, 2);
  EXPECT_EQ(Rows("beds"), 1);
  EXPECT_EQ(Rows("runs"), 2);
  EXPECT_EQ(Rows("sweep_runs"), 2);
  auto info = store_->GetSweep(r->sweep_ids[0]);
  ASSERT_TRUE(info.ok());
  EXPECT_EQ(info->name, "omega-sign");
  EXPECT_EQ(info->scale, "smoke");
  EXPECT_EQ(info->counts.queued, 2);
  auto rows = store_->SweepResults(r->sweep_ids[0]);
  ASSERT_EQ(rows->size(), 2u);
  EXPECT_DOUBLE_EQ((*rows)[0].point.Omega, -80);
  EXPECT_DOUBLE_EQ((*rows)[1].point.Omega, 80);
  EXPECT_FALSE((*rows)[0].result.has_value());
  nlohmann::json j = *r;
  EXPECT_EQ(j["id"], r->sweep_ids[0]);
}

// replicates: K beds (one per replicate, seeds of their own), every point on each.
TEST_F(SubmissionTest, ReplicatesMakeOneBedEachAndRunEveryPointOnEach) {
  nlohmann::json body = Sweep("replicated");
  body["replicates"] = 3;
  auto r = SubmitBody(body);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->runs, 6);
  EXPECT_EQ(Rows("beds"), 3);
  EXPECT_EQ(Rows("runs"), 6);
  auto beds = store_->ListBeds();
  ASSERT_TRUE(beds.ok()) << beds.status().ToString();
  ASSERT_EQ(beds->size(), 3u);
  std::set<int64_t> seeds;
  for (int i = 0; i < 3; ++i) {
    const BedView& b = (*beds)[i];
    EXPECT_EQ(b.replicate, i);
    EXPECT_EQ(b.state, JobState::kQueued);
    EXPECT_EQ(b.runs, 2);
    ASSERT_TRUE(b.seed_pour1 && b.seed_pour2);
    EXPECT_EQ(*b.seed_pour1, BedSeedsFor(i).pour1);
    seeds.insert(*b.seed_pour1);
    EXPECT_FALSE(b.result.has_value());
    auto one = store_->GetBed(b.id);
    ASSERT_TRUE(one.ok());
    EXPECT_EQ(one->key, b.key);
  }
  EXPECT_EQ(seeds.size(), 3u);
  EXPECT_EQ(store_->GetBed(999).status().code(), StatusCode::kNotFound);
  auto rows = store_->SweepResults(r->sweep_ids[0]);
  ASSERT_TRUE(rows.ok());
  std::map<int, int> per_replicate;
  for (const ResultRow& row : *rows) ++per_replicate[row.replicate];
  EXPECT_EQ(per_replicate, (std::map<int, int>{{0, 2}, {1, 2}, {2, 2}}));
  // The same sweep without replicates is replicate 0's runs: nothing new.
  auto single = SubmitBody(Sweep("single"));
  ASSERT_TRUE(single.ok());
  EXPECT_EQ(single->runs_new, 0);
  EXPECT_EQ(Rows("beds"), 3);
  // Too many replicates are refused naming the field, and change nothing.
  const auto before = AllRows();
  body["name"] = "too-many";
  body["replicates"] = 21;
  auto refused = SubmitBody(body);
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.status().field(), "replicates");
  EXPECT_EQ(AllRows(), before);
}

TEST_F(SubmissionTest, SharedPointsAcrossSweepsOfOneSubmissionRunOnce) {
  auto r = SubmitBody({{"sweeps", {Sweep("a", {-80, 80}), Sweep("b", {80, 160})}}});
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->sweep_ids.size(), 2u);
  EXPECT_EQ(r->runs, 3);
  EXPECT_EQ(Rows("runs"), 3);
  EXPECT_EQ(Rows("sweep_runs"), 4);
  EXPECT_EQ(store_->GetSweep(r->sweep_ids[1])->counts.total(), 2);
}

TEST_F(SubmissionTest, ResubmittingReusesRunsAndForceRequeuesDoneOnes) {
  auto first = SubmitBody(Sweep("one"));
  ASSERT_TRUE(first.ok());
  // Finish one run through the queue.
  LeaseQueue queue(store_.get(), &clock_);
  auto bed = queue.Lease({"w", "h", 1});
  ASSERT_TRUE(queue.PutBedRestart((*bed)->token, "x", Sha256Hex("x"), store_.dir().string()).ok());
  api::Completion bc;
  bc.ok = true;
  bc.bed_result = api::BedResult{};
  ASSERT_EQ(queue.Complete((*bed)->token, bc)->state, "done");
  auto run = queue.Lease({"w", "h", 1});
  api::Completion rc;
  rc.ok = true;
  rc.result = api::RunResult{};
  rc.result->uz = 0.25;
  ASSERT_EQ(queue.Complete((*run)->token, rc)->state, "done");

  auto second = SubmitBody(Sweep("two"));
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(second->runs_new, 0);
  EXPECT_EQ(second->runs_reused, 1);
  EXPECT_EQ(second->runs_shared, 1);
  EXPECT_EQ(Rows("runs"), 2);
  EXPECT_EQ(Rows("beds"), 1);
  auto rows = store_->SweepResults(second->sweep_ids[0]);
  int with_result = 0;
  for (const ResultRow& row : *rows) with_result += row.result.has_value();
  EXPECT_EQ(with_result, 1);

  auto forced = SubmitBody(Sweep("three"), /*force=*/true);
  ASSERT_TRUE(forced.ok());
  EXPECT_EQ(forced->runs_requeued, 1);
  EXPECT_EQ(Rows("runs"), 2);
  auto detail = store_->GetRun((*run)->id);
  EXPECT_EQ(detail->summary.state, JobState::kQueued);
  EXPECT_EQ(detail->summary.attempts, 0);
  ASSERT_TRUE(detail->result.has_value());  // the old result stays until replaced
  EXPECT_EQ(detail->result->result.uz, 0.25);
  auto again = queue.Lease({"w", "h", 1});
  ASSERT_TRUE(again->has_value());
  rc.result->uz = 0.5;
  ASSERT_EQ(queue.Complete((*again)->token, rc)->state, "done");
  EXPECT_EQ(Rows("results"), 1);
  EXPECT_EQ(store_->GetRun((*run)->id)->result->result.uz, 0.5);
}

TEST_F(SubmissionTest, IdempotencyKeyReplaysSameBodyAndRefusesAnother) {
  auto first = SubmitBody(Sweep("s"), false, "key-1");
  ASSERT_TRUE(first.ok());
  auto rows = AllRows();
  auto replay = SubmitBody(Sweep("s"), false, "key-1");
  ASSERT_TRUE(replay.ok());
  EXPECT_TRUE(replay->replayed);
  EXPECT_EQ(replay->sweep_ids, first->sweep_ids);
  EXPECT_EQ(AllRows(), rows);
  auto other = SubmitBody(Sweep("s", {-80, 40}), false, "key-1");
  EXPECT_EQ(other.status().code(), StatusCode::kConflict);
  EXPECT_EQ(other.status().field(), "Idempotency-Key");
  EXPECT_EQ(AllRows(), rows);
  // Replicates and a precision target are part of the request: another K is another request.
  nlohmann::json replicated = Sweep("s");
  replicated["replicates"] = 2;
  EXPECT_EQ(SubmitBody(replicated, false, "key-1").status().code(), StatusCode::kConflict);
  nlohmann::json targeted = Sweep("s");
  targeted["precision"] = {{"uz_abs", 0.01}, {"max_duration_s", 1}};
  EXPECT_EQ(SubmitBody(targeted, false, "key-1").status().code(), StatusCode::kConflict);
  EXPECT_EQ(AllRows(), rows);
  EXPECT_EQ(SubmitBody(Sweep("s"), false, "bad key").status().field(), "Idempotency-Key");
}

TEST_F(SubmissionTest, RefusedSubmissionLeavesTheDatabaseAsItWas) {
  ASSERT_TRUE(SubmitBody(Sweep("ok")).ok());
  auto rows = AllRows();
  nlohmann::json bad = Sweep("bad");
  bad["base"]["A"] = -1;
  auto r = SubmitBody(bad);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(r.status().field(), "base.A");
  nlohmann::json two = {{"sweeps", {Sweep("fine"), bad}}};
  auto r2 = SubmitBody(two);
  EXPECT_FALSE(r2.ok());
  EXPECT_EQ(r2.status().field(), "sweeps[1].base.A");
  auto dup = SubmitBody({{"sweeps", {Sweep("same"), Sweep("same")}}});
  EXPECT_EQ(dup.status().field(), "sweeps[1].name");
  nlohmann::json huge = Sweep("huge");
  huge["axes"] = {{{"param", "Omega"}, {"range", {{"from", -4000}, {"to", 4000}, {"step", 0.01}}}}};
  EXPECT_FALSE(SubmitBody(huge).ok());
  EXPECT_EQ(AllRows(), rows);
}

TEST_F(SubmissionTest, ParseSubmitRequestForms) {
  EXPECT_TRUE(ParseSubmitRequest(Sweep("a")).ok());
  nlohmann::json forced = Sweep("a");
  forced["force"] = true;
  auto f = ParseSubmitRequest(forced);
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  EXPECT_TRUE(f->force);
  forced["force"] = "yes";
  EXPECT_EQ(ParseSubmitRequest(forced).status().field(), "force");
  auto c = ParseSubmitRequest({{"campaign", "paper-58"}, {"scale", "smoke"}});
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(*c->campaign, "paper-58");
  EXPECT_EQ(ParseSubmitRequest({{"campaign", "paper-58"}, {"x", 1}}).status().field(), "x");
  EXPECT_EQ(ParseSubmitRequest({{"campaign", "paper-58"}, {"scale", "huge"}}).status().field(), "scale");
  EXPECT_FALSE(ParseSubmitRequest(nlohmann::json::array()).ok());
}

TEST_F(SubmissionTest, CampaignSubmissionAndScheduledSlotIsUnique) {
  SubmitRequest req;
  req.campaign = "paper-58";
  req.scale = "paper";
  req.trigger = "schedule";
  req.due_time = 1.7e9 + 7200;
  auto r = Submit(*store_, req, kTestEngine, clock_.Now());
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_TRUE(r->campaign_run_id.has_value());
  EXPECT_EQ(r->runs, 58);
  EXPECT_EQ(Rows("runs"), 58);
  auto cr = store_->GetCampaignRun(*r->campaign_run_id);
  ASSERT_TRUE(cr.ok());
  EXPECT_EQ(cr->trigger, "schedule");
  EXPECT_EQ(cr->counts.queued, 58);
  EXPECT_EQ(cr->sweep_ids, r->sweep_ids);
  auto rows = AllRows();
  auto again = Submit(*store_, req, kTestEngine, clock_.Now() + 5);
  ASSERT_TRUE(again.ok());
  EXPECT_TRUE(again->replayed);
  EXPECT_EQ(again->campaign_run_id, r->campaign_run_id);
  EXPECT_EQ(AllRows(), rows);
  // The campaign run records the built-in definition it ran (version 0); the built-in campaign
  // itself is not stored.
  EXPECT_EQ(cr->campaign_version, 0);
  EXPECT_EQ(cr->definition, *BuiltinCampaignDefinition("paper-58"));
  EXPECT_EQ(cr->definition_sha256, DefinitionSha256(*BuiltinCampaignDefinition("paper-58")));
  EXPECT_FALSE(store_->GetCampaign("paper-58")->has_value());
  SubmitRequest unknown;
  unknown.campaign = "nope";
  EXPECT_EQ(Submit(*store_, unknown, kTestEngine, 0).status().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace sandswim
