#include "server/store/campaigns.h"

#include <stdlib.h>

#include <filesystem>

#include <gtest/gtest.h>

#include "server/jobs/submission.h"
#include "server/store/schedule_table.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

class CampaignsTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(store_); }
  testing::TempStore store_{"campaigns"};
};

TEST_F(CampaignsTest, TheBuiltInOneWhenNoneIsStored) {
  auto found = FindCampaign(*store_, "paper-58");
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_FALSE(found->stored);
  EXPECT_EQ(found->campaign.sweeps.size(), BuiltinCampaign("paper-58")->sweeps.size());
  EXPECT_EQ(found->definition, *BuiltinCampaignDefinition("paper-58"));
  EXPECT_EQ(found->schedule, found->campaign.schedule);
}

TEST_F(CampaignsTest, AStoredOneWinsWithItsOwnColumns) {
  nlohmann::json definition = *BuiltinCampaignDefinition("paper-58");
  definition["scale"] = "mini";
  definition["drift_tolerance_mps"] = 0.25;
  StoredCampaign row;
  row.name = "paper-58";
  row.definition = definition;
  row.schedule = "0 3 * * *";
  ASSERT_TRUE(PutCampaign(*store_, row).ok());
  auto found = FindCampaign(*store_, "paper-58");
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_TRUE(found->stored);
  EXPECT_EQ(found->campaign.scale, "mini");
  EXPECT_EQ(found->schedule, "0 3 * * *");
  // The tolerance has one home, the definition (campaigns.h).
  EXPECT_EQ(found->campaign.drift_tolerance_mps, 0.25);
}

TEST_F(CampaignsTest, AnUnknownNameIsNotFoundAndNamesTheBuiltInOnes) {
  auto found = FindCampaign(*store_, "no-such", "campaigns[0]");
  ASSERT_FALSE(found.ok());
  EXPECT_EQ(found.status().code(), StatusCode::kNotFound);
  EXPECT_EQ(found.status().field(), "campaigns[0]");
  EXPECT_NE(found.status().reason().find("paper-58"), std::string::npos) << found.status().reason();
}

TEST_F(CampaignsTest, AStoredDefinitionThatNoLongerParsesIsCorruption) {
  StoredCampaign row;
  row.name = "broken";
  row.definition = nlohmann::json{{"name", "broken"}, {"sweeps", 7}};
  ASSERT_TRUE(PutCampaign(*store_, row).ok());
  auto found = FindCampaign(*store_, "broken");
  ASSERT_FALSE(found.ok());
  EXPECT_EQ(found.status().code(), StatusCode::kCorruption);
}

// A small campaign of one's own, as written and as resolved alike.
NewCampaignVersion Mine(double now, double amplitude = 0.03) {
  nlohmann::json sweep = {{"name", "one"},
                          {"base", {{"mode", "oscillatory"}, {"A", amplitude}, {"f", 3}, {"Omega", -80}, {"duration_s", 5}}},
                          {"axes", nlohmann::json::array()}};
  NewCampaignVersion v;
  v.name = "mine";
  v.definition = {{"name", "mine"}, {"description", "mine"}, {"scale", "smoke"}, {"sweeps", {sweep}}};
  v.resolved = v.definition;
  v.now = now;
  return v;
}

TEST_F(CampaignsTest, EveryChangeIsANewVersionAndAnEqualOneIsNot) {
  auto first = PutCampaignVersion(*store_, Mine(10));
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  EXPECT_EQ(first->version, 1);
  EXPECT_TRUE(first->created);
  EXPECT_FALSE(first->unchanged);
  auto same = PutCampaignVersion(*store_, Mine(20));
  ASSERT_TRUE(same.ok());
  EXPECT_EQ(same->version, 1);
  EXPECT_TRUE(same->unchanged);
  EXPECT_FALSE(same->created);
  auto second = PutCampaignVersion(*store_, Mine(30, 0.02));
  ASSERT_TRUE(second.ok());
  EXPECT_EQ(second->version, 2);
  EXPECT_FALSE(second->unchanged);

  auto found = FindCampaign(*store_, "mine");
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_EQ(found->version, 2);
  EXPECT_EQ(found->definition, Mine(0, 0.02).resolved);
  auto versions = ListCampaignVersions(*store_, "mine");
  ASSERT_TRUE(versions.ok());
  ASSERT_EQ(versions->size(), 2u);
  EXPECT_EQ((*versions)[0].version, 1);
  EXPECT_EQ((*versions)[0].created_at, 10);
  EXPECT_EQ((*versions)[0].resolved, Mine(0).resolved);
  EXPECT_NE((*versions)[0].definition_sha256, (*versions)[1].definition_sha256);
  EXPECT_EQ((*versions)[1].definition_sha256, DefinitionSha256(Mine(0, 0.02).resolved));
  EXPECT_EQ(GetCampaignVersion(*store_, "mine", 1)->value().resolved, Mine(0).resolved);
  EXPECT_FALSE(GetCampaignVersion(*store_, "mine", 3)->has_value());
}

TEST_F(CampaignsTest, DeletingRemovesTheScheduleInOneTransactionAndKeepsTheVersions) {
  ASSERT_TRUE(PutCampaignVersion(*store_, Mine(10)).ok());
  {
    auto t = store_->db().Begin();
    ASSERT_TRUE(schedules::RegisterSchedule(*t, "mine", "smoke", "0 2 * * *", 10).ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  ASSERT_TRUE(DeleteCampaign(*store_, "mine", 20).ok());
  EXPECT_FALSE(store_->GetCampaign("mine")->has_value());
  EXPECT_EQ(*store_->db().CountRows("campaign_schedules"), 0);
  EXPECT_EQ(ListCampaignVersions(*store_, "mine")->size(), 1u);
  auto again = DeleteCampaign(*store_, "mine", 30);
  EXPECT_EQ(again.code(), StatusCode::kNotFound);
  EXPECT_EQ(again.field(), "name");
  // Stored again: it goes on from its last version.
  auto back = PutCampaignVersion(*store_, Mine(40));
  ASSERT_TRUE(back.ok());
  EXPECT_TRUE(back->created);
  EXPECT_EQ(back->version, 2);
}

TEST_F(CampaignsTest, ARefusedDeleteChangesNothing) {
  NewCampaignVersion v = Mine(10);
  ASSERT_TRUE(PutCampaignVersion(*store_, v).ok());
  {
    auto t = store_->db().Begin();
    ASSERT_TRUE(schedules::RegisterSchedule(*t, "mine", "smoke", "0 2 * * *", 10).ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  SubmitRequest request;
  request.campaign = "mine";
  auto submitted = Submit(*store_, request, "engine", 15);
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  const int64_t events = *store_->db().CountRows("events");
  Status refused = DeleteCampaign(*store_, "mine", 20);
  EXPECT_EQ(refused.code(), StatusCode::kConflict);
  EXPECT_EQ(refused.field(), "name");
  EXPECT_NE(refused.reason().find("campaign run " + std::to_string(*submitted->campaign_run_id)), std::string::npos)
      << refused.reason();
  EXPECT_TRUE(store_->GetCampaign("mine")->has_value());
  EXPECT_EQ(*store_->db().CountRows("campaign_schedules"), 1);
  EXPECT_EQ(*store_->db().CountRows("events"), events);
  // The campaign run recorded what it ran.
  auto run = store_->GetCampaignRun(*submitted->campaign_run_id);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->campaign_version, 1);
  EXPECT_EQ(run->definition, v.resolved);
  EXPECT_EQ(run->definition_sha256, DefinitionSha256(v.resolved));

  // A later campaign run sharing those queued runs is the one named (before: the oldest, which may
  // have finished long ago and had its runs requeued by a forced rerun).
  auto again = Submit(*store_, request, "engine", 16);
  ASSERT_TRUE(again.ok()) << again.status().ToString();
  refused = DeleteCampaign(*store_, "mine", 20);
  EXPECT_NE(refused.reason().find("campaign run " + std::to_string(*again->campaign_run_id) + " "), std::string::npos)
      << refused.reason();
}

// A database of schema 12 with a stored campaign and a campaign run of it: after the migration the
// campaign is at version 1 with its definition, and the old campaign run says it recorded none.
TEST_F(CampaignsTest, CampaignsStoredBeforeVersionsBecomeVersionOne) {
  const std::string path = (store_.dir() / "old.db").string();
  nlohmann::json definition = Mine(0).definition;
  {
    auto s = Store::Open(path);
    ASSERT_TRUE(s.ok());
    auto t = (*s)->db().Begin();
    ASSERT_TRUE(t->Exec("DROP TABLE campaign_versions; ALTER TABLE campaigns DROP COLUMN version;"
                        "ALTER TABLE campaign_runs DROP COLUMN campaign_version;"
                        "ALTER TABLE campaign_runs DROP COLUMN definition;"
                        "ALTER TABLE campaign_runs DROP COLUMN definition_sha256;"
                        "ALTER TABLE campaign_schedules DROP COLUMN source;"
                        "ALTER TABLE beds DROP COLUMN ranks;"
                        "DROP TABLE campaign_rounds; DROP TABLE campaign_run_verdicts; DROP TABLE campaign_run_charges; DROP TABLE campaign_run_replacements;"
                        "ALTER TABLE beds DROP COLUMN heartbeat_at; DROP TABLE run_progress;"
                        "DROP INDEX leases_by_job; ALTER TABLE leases DROP COLUMN closed_at; "
                        "ALTER TABLE leases DROP COLUMN sim_time_s;"
                        "ALTER TABLE leases DROP COLUMN payer_campaign_run_id; ALTER TABLE leases DROP COLUMN payer_decided;"
                        "ALTER TABLE runs DROP COLUMN dt_s;"
                        "DELETE FROM schema_migrations WHERE version >= 13; PRAGMA user_version = 12;")
                    .ok());
    Statement st = t->Prepare(
        "INSERT INTO campaigns (name, definition, schedule, drift_tolerance_mps, updated_at) VALUES ('mine', ?, NULL, 0, 7)");
    st.Bind(1, definition.dump());
    ASSERT_TRUE(st.Run().ok());
    ASSERT_TRUE(t->Exec("INSERT INTO campaign_runs (campaign, scale, trigger, created_at) "
                        "VALUES ('mine', 'smoke', 'manual', 8)")
                    .ok());
    ASSERT_TRUE(t->Exec("INSERT INTO campaign_schedules (campaign, scale, cron, first_seen_at, updated_at) "
                        "VALUES ('mine', 'smoke', '0 2 * * *', 7, 7)")
                    .ok());
    ASSERT_TRUE(t->Commit().ok());
  }
  auto s = Store::Open(path);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ((*s)->db().schema_version(), static_cast<int>(Migrations().size()));  // every migration applied
  auto found = FindCampaign(**s, "mine");
  ASSERT_TRUE(found.ok()) << found.status().ToString();
  EXPECT_EQ(found->version, 1);
  auto versions = ListCampaignVersions(**s, "mine");
  ASSERT_EQ(versions->size(), 1u);
  EXPECT_EQ((*versions)[0].definition, definition);
  EXPECT_EQ((*versions)[0].resolved, definition);
  EXPECT_EQ((*versions)[0].created_at, 7);
  auto runs = (*s)->ListCampaignRuns("mine");
  ASSERT_EQ(runs->size(), 1u);
  EXPECT_FALSE((*runs)[0].campaign_version.has_value());
  EXPECT_TRUE((*runs)[0].definition_sha256.empty());
  // The next change is version 2.
  auto next = PutCampaignVersion(**s, Mine(9, 0.02));
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(next->version, 2);
}

}  // namespace
}  // namespace sandswim
