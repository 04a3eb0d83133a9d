// The campaigns resource served for real: a campaign of one's own stored, versioned,
// run, scheduled and deleted over HTTP, every refusal naming its field and storing nothing.
#include <stdlib.h>

#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "platform/clock.h"
#include "server/dashboard/live_feed.h"
#include "server/http/loopback_server_test_util.h"
#include "server/jobs/lease_queue.h"
#include "server/store/store.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

using json = nlohmann::json;
using ::testing::HasSubstr;

constexpr const char* kToken = "s3cret";

// Two points on one bed at smoke, and the claim that one rises and the other sinks.
json Mine(double amplitude = 0.03) {
  return {{"description", "my own study"},
          {"scale", "smoke"},
          {"sweeps",
           {{{"name", "signs"},
             {"base", {{"mode", "oscillatory"}, {"A", amplitude}, {"f", 3}, {"Omega", -80}, {"duration_s", 0.3}}},
             {"axes", {{{"param", "Omega"}, {"values", {-80, 80}}}}}}}},
          {"claims",
           {{{"id", "S1"},
             {"title", "Omega < 0 rises, Omega > 0 sinks"},
             {"source", "my own hunch"},
             {"paper", {{"text", "not from a paper: what I expect"}}},
             {"rule", {{"kind", "sign"}, {"sweeps", {"signs"}}, {"expect", "against_Omega"}}}}}}};
}

class CampaignRoutesTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(store_);
    dir_ = store_.dir().string();
    clock_.Set(1.8e9);
    leases_ = std::make_unique<LeaseQueue>(store_.get(), &clock_, LeaseQueueOptions{});
    deps_.store = store_.get();
    deps_.leases = leases_.get();
    deps_.clock = &clock_;
    deps_.data_dir = dir_ + "/data";
    deps_.engine_version = "LIGGGHTS (Version test)";
    deps_.token = kToken;
    server_ = std::make_unique<LoopbackServer>(deps_);
    client_ = &server_->client();
    client_->set_bearer_token_auth(kToken);
  }
  void TearDown() override {
    server_.reset();
    leases_.reset();
  }

  httplib::Result Put(const std::string& path, const std::string& body) {
    return client_->Put(path.c_str(), body, "application/json");
  }
  httplib::Result Post(const std::string& path, const std::string& body) {
    return client_->Post(path.c_str(), body, "application/json");
  }
  httplib::Result Get(const std::string& path) { return client_->Get(path.c_str()); }
  httplib::Result Delete(const std::string& path) { return client_->Delete(path.c_str()); }
  static json Body(const httplib::Result& r) { return json::parse(r->body); }

  std::map<std::string, int64_t> AllRows() {
    std::map<std::string, int64_t> rows;
    for (const char* t : {"campaigns", "campaign_versions", "campaign_schedules", "campaign_runs", "sweeps", "runs",
                          "events"}) {
      rows[t] = *store_->db().CountRows(t);
    }
    return rows;
  }

  std::string dir_;
  FakeClock clock_;
  testing::TempStore store_{"campaign-routes", "test.db"};
  std::unique_ptr<LeaseQueue> leases_;
  Deps deps_;
  std::unique_ptr<LoopbackServer> server_;
  httplib::Client* client_ = nullptr;
};

TEST_F(CampaignRoutesTest, PutMakesVersionsAndGetShowsThem) {
  auto created = Put("/api/v1/campaigns/mine", Mine().dump());
  ASSERT_EQ(created->status, 201) << created->body;
  EXPECT_EQ(created->get_header_value("Location"), "/api/v1/campaigns/mine");
  json body = Body(created);
  EXPECT_EQ(body["version"], 1);
  EXPECT_EQ(body["unchanged"], false);
  EXPECT_EQ(body["planned_runs"]["smoke"], 2);
  EXPECT_TRUE(body["planned_runs"].contains("paper"));

  auto same = Put("/api/v1/campaigns/mine", Mine().dump());
  ASSERT_EQ(same->status, 200) << same->body;
  EXPECT_EQ(Body(same)["version"], 1);
  EXPECT_EQ(Body(same)["unchanged"], true);
  clock_.Advance(60);
  auto edited = Put("/api/v1/campaigns/mine", Mine(0.02).dump());
  ASSERT_EQ(edited->status, 200) << edited->body;
  EXPECT_EQ(Body(edited)["version"], 2);
  EXPECT_EQ(Body(edited)["unchanged"], false);

  auto got = Get("/api/v1/campaigns/mine");
  ASSERT_EQ(got->status, 200) << got->body;
  json campaign = Body(got);
  EXPECT_EQ(campaign["name"], "mine");
  EXPECT_EQ(campaign["version"], 2);
  EXPECT_EQ(campaign["builtin"], false);
  EXPECT_EQ(campaign["definition"], Mine(0.02));  // as written: no name
  EXPECT_EQ(campaign["resolved"]["name"], "mine");
  EXPECT_EQ(campaign["extends"], nullptr);
  EXPECT_EQ(campaign["schedule"], nullptr);
  ASSERT_EQ(campaign["versions"].size(), 2u);
  EXPECT_EQ(campaign["versions"][0]["version"], 1);
  EXPECT_EQ(campaign["versions"][1]["created_at"], clock_.Now());
  EXPECT_NE(campaign["versions"][0]["definition_sha256"], campaign["versions"][1]["definition_sha256"]);
  EXPECT_TRUE(campaign["runs"].empty());
  auto first = Get("/api/v1/campaigns/mine?version=1");
  ASSERT_EQ(first->status, 200) << first->body;
  EXPECT_EQ(Body(first)["definition"], Mine());
  auto none = Get("/api/v1/campaigns/mine?version=7");
  EXPECT_EQ(none->status, 404);
  EXPECT_EQ(Body(none)["field"], "version");
  auto unknown = Get("/api/v1/campaigns/nobody");
  EXPECT_EQ(unknown->status, 404);
  EXPECT_EQ(Body(unknown)["field"], "name");

  auto list = Get("/api/v1/campaigns");
  ASSERT_EQ(list->status, 200);
  bool listed = false;
  const json campaigns = Body(list)["campaigns"];
  for (const json& c : campaigns) {
    if (c["name"] == "mine") {
      listed = true;
      EXPECT_EQ(c["version"], 2);
      EXPECT_EQ(c["builtin"], false);
    }
    if (c["name"] == "paper-58") {
      EXPECT_EQ(c["version"], 0);
    }
  }
  EXPECT_TRUE(listed) << list->body;
}

TEST_F(CampaignRoutesTest, RefusalsNameTheFieldAndStoreNothing) {
  const auto before = AllRows();
  auto bad_json = Put("/api/v1/campaigns/mine", "{\"scale\": ");
  EXPECT_EQ(bad_json->status, 400);
  auto builtin = Put("/api/v1/campaigns/paper-58", Mine().dump());
  EXPECT_EQ(builtin->status, 409);
  EXPECT_EQ(Body(builtin)["field"], "name");
  EXPECT_THAT(Body(builtin)["detail"].get<std::string>(), HasSubstr("\"extends\": \"paper-58\""));
  json renamed = Mine();
  renamed["name"] = "other";
  auto mismatch = Put("/api/v1/campaigns/mine", renamed.dump());
  EXPECT_EQ(mismatch->status, 422);
  EXPECT_EQ(Body(mismatch)["field"], "name");
  auto too_long = Put("/api/v1/campaigns/" + std::string(65, 'a'), Mine().dump());
  EXPECT_EQ(too_long->status, 422);
  EXPECT_EQ(Body(too_long)["field"], "name");
  json bad_value = Mine();
  bad_value["sweeps"][0]["axes"][0]["values"] = json::array({-80, "fast"});
  auto value = Put("/api/v1/campaigns/mine", bad_value.dump());
  EXPECT_EQ(value->status, 422) << value->body;
  EXPECT_THAT(Body(value)["field"].get<std::string>(), HasSubstr("sweeps[0].axes[0].values")) << value->body;
  json bad_rule = Mine();
  bad_rule["claims"][0]["rule"]["kind"] = "telepathy";
  auto rule = Put("/api/v1/campaigns/mine", bad_rule.dump());
  EXPECT_EQ(rule->status, 422) << rule->body;
  EXPECT_THAT(Body(rule)["field"].get<std::string>(), HasSubstr("claims[0].rule")) << rule->body;
  EXPECT_THAT(Body(rule)["detail"].get<std::string>(), HasSubstr("telepathy")) << rule->body;
  auto base = Put("/api/v1/campaigns/mine", R"({"extends": "no-such-campaign"})");
  EXPECT_EQ(base->status, 422) << base->body;
  EXPECT_EQ(Body(base)["field"], "extends");
  // 400 x 400 points: past the submission cap at its own scale, said at PUT.
  json big = Mine();
  json many = json::array();
  for (int i = 0; i < 400; ++i) many.push_back(0.01 + i * 1e-4);
  json omegas = json::array();
  for (int i = 0; i < 400; ++i) omegas.push_back(-100 + i * 0.5);
  big["sweeps"][0]["axes"] = {{{"param", "A"}, {"values", many}}, {{"param", "Omega"}, {"values", omegas}}};
  big["sweeps"][0]["combine"] = "product";
  big.erase("claims");
  auto capped = Put("/api/v1/campaigns/mine", big.dump());
  EXPECT_EQ(capped->status, 422) << capped->body;
  EXPECT_THAT(Body(capped)["detail"].get<std::string>(), HasSubstr("100000")) << capped->body;
  EXPECT_EQ(AllRows(), before);
}

// "Run paper-58 on three beds": one's own copy that sets its replicates.
TEST_F(CampaignRoutesTest, ACopyOfABuiltInCampaignOverridesItsFields) {
  auto put = Put("/api/v1/campaigns/paper-58-x3", R"({"extends": "paper-58", "replicates": 3, "scale": "smoke"})");
  ASSERT_EQ(put->status, 201) << put->body;
  EXPECT_EQ(Body(put)["planned_runs"]["smoke"], 3 * 58);
  auto got = Get("/api/v1/campaigns/paper-58-x3");
  ASSERT_EQ(got->status, 200);
  json c = Body(got);
  EXPECT_EQ(c["extends"], "paper-58");
  EXPECT_EQ(c["extends_version"], 0);
  EXPECT_EQ(c["resolved"]["replicates"], 3);
  EXPECT_EQ(c["resolved"]["name"], "paper-58-x3");
  EXPECT_EQ(c["resolved"]["sweeps"].size(), 10u);
}

// What PUT said when it stored a version (the base's claims its sweeps can no longer judge, left
// out) is what GET shows for that version, also after a newer version without "extends" (before,
// GET always answered "notes": []).
TEST_F(CampaignRoutesTest, GetShowsTheNotesPutGave) {
  auto put = Put("/api/v1/campaigns/two-sweeps",
                 R"({"extends": "paper-58", "sweeps": ["baseline", "Omega-sweep"], "scale": "smoke"})");
  ASSERT_EQ(put->status, 201) << put->body;
  const json notes = Body(put)["notes"];
  ASSERT_FALSE(notes.empty()) << put->body;
  EXPECT_THAT(notes.dump(), HasSubstr("claim F4 of paper-58 left out"));
  auto got = Get("/api/v1/campaigns/two-sweeps");
  ASSERT_EQ(got->status, 200) << got->body;
  EXPECT_EQ(Body(got)["notes"], notes);

  json own = Body(got)["resolved"];
  own.erase("claims");
  clock_.Advance(60);
  auto second = Put("/api/v1/campaigns/two-sweeps", own.dump());
  ASSERT_EQ(second->status, 200) << second->body;
  EXPECT_TRUE(Body(second)["notes"].empty());
  EXPECT_TRUE(Body(Get("/api/v1/campaigns/two-sweeps"))["notes"].empty());
  auto first = Get("/api/v1/campaigns/two-sweeps?version=1");
  ASSERT_EQ(first->status, 200) << first->body;
  EXPECT_EQ(Body(first)["notes"], notes);
  // A built-in campaign has none.
  EXPECT_TRUE(Body(Get("/api/v1/campaigns/paper-58"))["notes"].empty());
}

TEST_F(CampaignRoutesTest, RunsRecordTheirVersionAndDeleteWaitsForThem) {
  ASSERT_EQ(Put("/api/v1/campaigns/mine", Mine().dump())->status, 201);
  auto unknown_field = Post("/api/v1/campaigns/mine/runs", R"({"scael": "mini"})");
  EXPECT_EQ(unknown_field->status, 400);
  EXPECT_EQ(Body(unknown_field)["field"], "scael");
  auto run = Post("/api/v1/campaigns/mine/runs", "{}");
  ASSERT_EQ(run->status, 201) << run->body;
  const int64_t id = Body(run)["id"].get<int64_t>();
  EXPECT_EQ(run->get_header_value("Location"), "/api/v1/campaign-runs/" + std::to_string(id));
  auto info = Get("/api/v1/campaign-runs/" + std::to_string(id));
  ASSERT_EQ(info->status, 200);
  EXPECT_EQ(Body(info)["campaign_version"], 1);
  EXPECT_EQ(Body(info)["definition_sha256"].get<std::string>().size(), 64u);
  auto page = Body(Get("/api/v1/campaigns/mine"));
  ASSERT_EQ(page["runs"].size(), 1u);
  EXPECT_EQ(page["runs"][0]["id"], id);
  EXPECT_EQ(page["runs"][0]["status"], "queued");
  ASSERT_EQ(Put("/api/v1/campaigns/mine/schedule", R"({"cron": "0 2 * * *"})")->status, 200);

  const auto before = AllRows();
  auto refused = Delete("/api/v1/campaigns/mine");
  EXPECT_EQ(refused->status, 409) << refused->body;
  EXPECT_THAT(Body(refused)["detail"].get<std::string>(), HasSubstr("campaign run " + std::to_string(id)));
  EXPECT_EQ(AllRows(), before);
  const json sweeps = Body(info)["sweeps"];
  for (const json& sweep : sweeps) {
    ASSERT_EQ(Post("/api/v1/sweeps/" + std::to_string(sweep.get<int64_t>()) + "/cancel", "")->status, 200);
  }
  auto deleted = Delete("/api/v1/campaigns/mine");
  EXPECT_EQ(deleted->status, 204) << deleted->body;
  EXPECT_EQ(Get("/api/v1/campaigns/mine")->status, 404);
  EXPECT_EQ(*store_->db().CountRows("campaign_schedules"), 0);  // in the same transaction
  EXPECT_EQ(Get("/api/v1/campaign-runs/" + std::to_string(id))->status, 200);
  EXPECT_EQ(Get("/api/v1/campaigns/mine?version=1")->status, 200);
  EXPECT_EQ(Delete("/api/v1/campaigns/mine")->status, 404);
  EXPECT_EQ(Delete("/api/v1/campaigns/paper-58")->status, 409);
}

TEST_F(CampaignRoutesTest, SchedulesAreStoredAndRemoved) {
  ASSERT_EQ(Put("/api/v1/campaigns/mine", Mine().dump())->status, 201);
  auto bad = Put("/api/v1/campaigns/mine/schedule", R"({"cron": "at two"})");
  EXPECT_EQ(bad->status, 422);
  EXPECT_EQ(Body(bad)["field"], "cron");
  auto bad_scale = Put("/api/v1/campaigns/mine/schedule", R"({"cron": "0 2 * * *", "scale": "huge"})");
  EXPECT_EQ(bad_scale->status, 422);
  EXPECT_EQ(Body(bad_scale)["field"], "scale");
  EXPECT_EQ(Put("/api/v1/campaigns/nobody/schedule", R"({"cron": "0 2 * * *"})")->status, 404);
  EXPECT_EQ(*store_->db().CountRows("campaign_schedules"), 0);
  auto put = Put("/api/v1/campaigns/mine/schedule", R"({"cron": "30 1 * * *"})");
  ASSERT_EQ(put->status, 200) << put->body;
  EXPECT_EQ(Body(put)["campaign"], "mine");
  EXPECT_EQ(Body(put)["scale"], "smoke");
  EXPECT_GT(Body(put)["next_due"].get<double>(), clock_.Now());
  json page = Body(Get("/api/v1/campaigns/mine"));
  EXPECT_EQ(page["schedule"]["cron"], "30 1 * * *");
  EXPECT_EQ(Put("/api/v1/campaigns/paper-58/schedule", R"({"cron": "0 3 * * *", "scale": "smoke"})")->status, 200);
  EXPECT_EQ(Delete("/api/v1/campaigns/mine/schedule")->status, 204);
  EXPECT_EQ(Get("/api/v1/campaigns/mine")->status, 200);
  EXPECT_EQ(Body(Get("/api/v1/campaigns/mine"))["schedule"], nullptr);
  auto again = Delete("/api/v1/campaigns/mine/schedule");
  EXPECT_EQ(again->status, 404);
  EXPECT_EQ(Body(again)["field"], "schedule");
}

TEST_F(CampaignRoutesTest, WritesNeedTheToken) {
  httplib::Client plain("127.0.0.1", server_->port());
  EXPECT_EQ(plain.Put("/api/v1/campaigns/mine", Mine().dump(), "application/json")->status, 401);
  EXPECT_EQ(plain.Post("/api/v1/campaigns/mine/runs", "{}", "application/json")->status, 401);
  EXPECT_EQ(plain.Put("/api/v1/campaigns/mine/schedule", R"({"cron": "0 2 * * *"})", "application/json")->status, 401);
  EXPECT_EQ(plain.Delete("/api/v1/campaigns/mine/schedule")->status, 401);
  EXPECT_EQ(plain.Delete("/api/v1/campaigns/mine")->status, 401);
  EXPECT_EQ(plain.Get("/api/v1/campaigns/mine")->status, 401);
  // A read's ?access_token= carries no write.
  EXPECT_EQ(plain.Put("/api/v1/campaigns/mine?access_token=s3cret", Mine().dump(), "application/json")->status, 401);
  EXPECT_EQ(*store_->db().CountRows("campaign_versions"), 0);
}

}  // namespace
}  // namespace sandswim
