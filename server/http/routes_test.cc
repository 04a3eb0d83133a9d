// The REST API end to end in one process: a real httplib::Server on 127.0.0.1 (ephemeral port),
// a real SQLite file in a temp directory, and httplib::Client as the caller.
#include "server/http/routes.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdlib.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "core/keys.h"
#include "core/point.h"
#include "core/result_table.h"
#include "core/sweep.h"
#include "platform/data_dir.h"
#include "platform/http_status.h"
#include "server/http/loopback_server_test_util.h"
#include "server/http/result_rows.h"
#include "server/dashboard/live_feed.h"
#include "server/store/temp_store_test_util.h"
#include "tests/fixture_file.h"

namespace sandswim {
namespace {

using json = nlohmann::json;
using ::testing::HasSubstr;

const char* kExampleSweep = R"({"name": "omega-sign", "scale": "smoke",
  "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
  "axes": [{"param": "Omega", "values": [-80, 80]}],
  "combine": "product"})";

class RoutesTest : public ::testing::Test {
 protected:
  void SetUp() override { Start(""); }

  // The daemon (re)started on the test's store file.
  void Start(const std::string& token) {
    ASSERT_TRUE(store_.Reopen());
    dir_ = store_.dir().string();
    leases_ = std::make_unique<LeaseQueue>(store_.get(), &clock_, LeaseQueueOptions{});
    deps_.store = store_.get();
    deps_.leases = leases_.get();
    deps_.clock = &clock_;
    deps_.data_dir = dir_ + "/data";
    deps_.engine_version = "LIGGGHTS (Version test)";
    deps_.token = token;
    live_ = std::make_unique<LiveFeed>(store_.get(), &clock_, /*tick_s=*/0.05, /*max_streams=*/2);
    leases_->SetProgressObserver([this](int64_t run, const api::Heartbeat& b) { live_->RecordBeat(run, b.sim_time_s, b.so_z); });
    deps_.live = live_.get();
    server_ = std::make_unique<LoopbackServer>(deps_);
    client_ = &server_->client();
  }

  void TearDown() override { Shutdown(); }

  void Shutdown() {
    if (!server_) return;
    live_->Stop();
    server_.reset();
    live_.reset();
    client_ = nullptr;
    leases_.reset();
    store_.reset();
  }

  httplib::Result Post(const std::string& path, const std::string& body, httplib::Headers headers = {}) {
    return client_->Post(path.c_str(), headers, body, "application/json");
  }

  json Body(const httplib::Result& r) { return json::parse(r->body); }

  int64_t Rows(const std::string& table) {
    auto n = store_->db().CountRows(table);
    EXPECT_TRUE(n.ok()) << n.status().ToString();
    return n.ok() ? *n : -1;
  }

  std::map<std::string, int64_t> AllRows() {
    std::map<std::string, int64_t> rows;
    for (const char* t : {"sweeps", "runs", "beds", "sweep_runs", "submissions", "campaign_runs"}) rows[t] = Rows(t);
    return rows;
  }

  int64_t SubmitExample() {
    auto r = Post("/api/v1/sweeps", kExampleSweep);
    EXPECT_EQ(r->status, 201) << r->body;
    return Body(r)["id"].get<int64_t>();
  }

  std::string dir_;
  FakeClock clock_;
  testing::TempStore store_{"routes", "test.db"};
  std::unique_ptr<LeaseQueue> leases_;
  std::unique_ptr<LiveFeed> live_;
  Deps deps_;
  std::unique_ptr<LoopbackServer> server_;
  httplib::Client* client_ = nullptr;
};

TEST_F(RoutesTest, SubmitExampleSweepAnswersCreatedWithLocationAndCounts) {
  auto r = Post("/api/v1/sweeps", kExampleSweep);
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 201) << r->body;
  int64_t id = Body(r)["id"].get<int64_t>();
  EXPECT_EQ(r->get_header_value("Location"), "/api/v1/sweeps/" + std::to_string(id));

  auto got = client_->Get(("/api/v1/sweeps/" + std::to_string(id)).c_str());
  ASSERT_EQ(got->status, 200);
  json sweep = Body(got);
  EXPECT_EQ(sweep["name"], "omega-sign");
  EXPECT_EQ(sweep["counts"]["queued"], 2);
  EXPECT_EQ(sweep["counts"]["running"], 0);
  EXPECT_EQ(sweep["counts"]["done"], 0);
  EXPECT_EQ(sweep["counts"]["failed"], 0);

  auto list = client_->Get("/api/v1/sweeps");
  ASSERT_EQ(list->status, 200);
  ASSERT_EQ(Body(list)["sweeps"].size(), 1u);
}

TEST_F(RoutesTest, ListRunsPagesWithCursorRoundTrip) {
  auto r = Post("/api/v1/sweeps", R"({"name": "omegas", "scale": "smoke",
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": 10, "duration_s": 0.3},
    "axes": [{"param": "Omega", "values": [10, 20, 40, 80, 160]}]})");
  ASSERT_EQ(r->status, 201) << r->body;
  int64_t sweep = Body(r)["id"].get<int64_t>();

  std::set<int64_t> seen;
  std::string cursor;
  int pages = 0;
  while (true) {
    std::string path = "/api/v1/runs?sweep=" + std::to_string(sweep) + "&state=queued&limit=2";
    if (!cursor.empty()) path += "&cursor=" + cursor;
    auto page = client_->Get(path.c_str());
    ASSERT_EQ(page->status, 200) << page->body;
    json body = Body(page);
    for (const auto& run : body["runs"]) EXPECT_TRUE(seen.insert(run["id"].get<int64_t>()).second);
    ++pages;
    ASSERT_LE(pages, 5);
    if (!body.contains("next_cursor") || body["next_cursor"].is_null()) break;
    ASSERT_TRUE(body["next_cursor"].is_string());
    cursor = body["next_cursor"].get<std::string>();
  }
  EXPECT_EQ(seen.size(), 5u);
  EXPECT_GE(pages, 3);

  auto bad = client_->Get("/api/v1/runs?limit=abc");
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(Body(bad)["field"], "limit");
  auto no_state = client_->Get("/api/v1/runs?state=bogus");
  EXPECT_EQ(no_state->status, 400);
  EXPECT_EQ(Body(no_state)["field"], "state");
}

struct BadInput {
  const char* name;
  std::string body;
  std::string field;
};

TEST_F(RoutesTest, BadInputGetsProblemNamingTheFieldAndChangesNothing) {
  SubmitExample();  // something in the database to stay untouched
  const std::string base = R"("base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3})";
  auto sweep = [&](const std::string& extra, const std::string& b) {
    return R"({"name": "bad", "scale": "smoke", )" + b + extra + "}";
  };
  auto with_base = [&](const std::string& fields) {
    return sweep("", R"("base": {"mode": "oscillatory", )" + fields + "}");
  };
  const std::vector<BadInput> cases = {
      {"malformed JSON", R"({"name": "bad", "scale": )", "body"},
      {"not an object", "[1, 2]", ""},
      {"unknown field", sweep(R"(, "colour": "red")", base), "colour"},
      {"wrong type", sweep(R"(, "axes": {"param": "A"})", base), "axes"},
      {"string where a number belongs", with_base(R"("A": "0.03", "f": 3, "Omega": -80, "duration_s": 0.3)"), "base.A"},
      {"deck injection in a number", with_base(R"("A": "0.03\nrun 1000000", "f": 3, "Omega": -80, "duration_s": 0.3)"),
       "base.A"},
      {"newline inside a value",
       with_base(R"("A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3, "axis": "x\nshell rm")"), "base.axis"},
      {"newline in the mode",
       sweep("", R"("base": {"mode": "oscillatory\nrun 1", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3})"),
       "base.mode"},
      {"newline in the name", R"({"name": "a\nb", "scale": "smoke", )" + base + "}", "name"},
      {"number too large (no NaN in JSON)", with_base(R"("A": 1e999, "f": 3, "Omega": -80, "duration_s": 0.3)"),
       "body"},
      {"negative A", with_base(R"("A": -0.03, "f": 3, "Omega": -80, "duration_s": 0.3)"), "base.A"},
      {"zero A", with_base(R"("A": 0, "f": 3, "Omega": -80, "duration_s": 0.3)"), "base.A"},
      {"negative f", with_base(R"("A": 0.03, "f": -3, "Omega": -80, "duration_s": 0.3)"), "base.f"},
      {"zero f", with_base(R"("A": 0.03, "f": 0, "Omega": -80, "duration_s": 0.3)"), "base.f"},
      {"Omega beyond its cap", with_base(R"("A": 0.03, "f": 3, "Omega": 5001, "duration_s": 0.3)"), "base.Omega"},
      {"Omega beyond its cap on an axis", sweep(R"(, "axes": [{"param": "Omega", "values": [80, 1e6]}])", base),
       "axes[0].values[1]"},
      {"past the run limit",
       sweep(R"(, "axes": [{"param": "Omega", "range": {"from": 1, "to": 400, "step": 1}},
                                                 {"param": "f", "range": {"from": 1, "to": 400, "step": 1}}])",
             base),
       "axes"},
      {"unknown scale", R"({"name": "bad", "scale": "galaxy", )" + base + "}", "scale"},
      {"unknown campaign", R"({"campaign": "nope"})", "campaign"},
      {"a key twice (which one wins is a parser's whim)", R"({"name": "bad", "name": "good", "scale": "smoke", )" + base + "}",
       "name"},
      {"a key twice inside base", sweep("", R"("base": {"mode": "oscillatory", "A": 0.03, "A": 9, "f": 3, "Omega": -80, "duration_s": 0.3})"),
       "A"},
      {"the name . (a URL normalises it away)", R"({"name": ".", "scale": "smoke", )" + base + "}", "name"},
      {"the name ..", R"({"name": "..", "scale": "smoke", )" + base + "}", "name"},
  };
  const auto before = AllRows();
  for (const BadInput& c : cases) {
    SCOPED_TRACE(c.name);
    auto r = Post("/api/v1/sweeps", c.body);
    ASSERT_TRUE(r);
    EXPECT_GE(r->status, 400);
    EXPECT_LT(r->status, 500);
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json");
    json problem = Body(r);
    EXPECT_EQ(problem["status"], r->status);
    EXPECT_TRUE(problem["type"].is_string());
    EXPECT_TRUE(problem["title"].is_string());
    EXPECT_TRUE(problem["detail"].is_string());
    if (!c.field.empty()) {
      EXPECT_THAT(problem["field"].get<std::string>(), HasSubstr(c.field)) << r->body;
    }
  }
  EXPECT_EQ(AllRows(), before);
}

// Routes whose body is optional take none or a JSON object, not a broken one; a lease request is
// held to its schema: ranks at least 1, no key it does not know.
TEST_F(RoutesTest, OptionalBodiesAndLeaseRequestsAreHeldToTheirSchemas) {
  const int64_t id = SubmitExample();
  const std::string cancel = "/api/v1/sweeps/" + std::to_string(id) + "/cancel";
  const auto before = AllRows();
  struct Case {
    std::string path, body, field;
  };
  const std::vector<Case> cases = {
      {cancel, "{", "body"},
      {cancel, "[1]", "body"},
      {cancel, R"({"a": 1, "a": 2})", "a"},
      {"/api/v1/backup", "{", "body"},
      {"/api/v1/leases", R"({"worker": "w", "host": "h", "ranks": 0})", "ranks"},
      {"/api/v1/leases", R"({"worker": "w", "host": "h", "ranks": -5})", "ranks"},
      {"/api/v1/leases", R"({"worker": "w", "host": "h", "ranks": 1, "priority": 9})", "priority"},
      {"/api/v1/leases", R"({"worker": "w", "worker": "x", "host": "h"})", "worker"},
      {"/api/v1/leases/abc/heartbeat", R"({"step": 1, "colour": "red"})", "colour"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.path + " " + c.body);
    auto r = Post(c.path, c.body);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json");
    EXPECT_EQ(Body(r)["field"], c.field) << r->body;
  }
  EXPECT_EQ(AllRows(), before);
  auto sweep = client_->Get(("/api/v1/sweeps/" + std::to_string(id)).c_str());
  EXPECT_EQ(Body(sweep)["counts"]["cancelled"], 0) << "a broken body cancelled the sweep";
  EXPECT_EQ(Rows("leases"), 0);
  EXPECT_EQ(Post(cancel, "{}")->status, 200);
  EXPECT_EQ(Post(cancel, "")->status, 200);
}

TEST_F(RoutesTest, HugeBodyIs413AndChangesNothing) {
  const auto before = AllRows();
  std::string huge = R"({"name": "huge", "pad": ")" + std::string(2 << 20, 'x') + R"("})";
  auto r = Post("/api/v1/sweeps", huge);
  ASSERT_TRUE(r) << "connection error " << static_cast<int>(r.error());
  EXPECT_EQ(r->status, 413);
  EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json");
  EXPECT_EQ(Body(r)["field"], "body");
  EXPECT_EQ(AllRows(), before);
  // The connection is still usable for the next request.
  EXPECT_EQ(client_->Get("/healthz")->status, 200);
}

TEST_F(RoutesTest, IdempotencyKeyReplaysTheSameId) {
  httplib::Headers key = {{"Idempotency-Key", "retry-7"}};
  auto first = Post("/api/v1/sweeps", kExampleSweep, key);
  ASSERT_EQ(first->status, 201) << first->body;
  auto second = Post("/api/v1/sweeps", kExampleSweep, key);
  ASSERT_EQ(second->status, 201) << second->body;
  EXPECT_EQ(Body(first)["id"], Body(second)["id"]);
  EXPECT_EQ(Body(second)["replayed"], true);
  EXPECT_EQ(first->get_header_value("Location"), second->get_header_value("Location"));
  EXPECT_EQ(Rows("sweeps"), 1);
  EXPECT_EQ(Rows("runs"), 2);

  // The same key with another body is a conflict, not a silent replay.
  std::string other = kExampleSweep;
  other.replace(other.find("omega-sign"), 10, "omega-two");
  auto clash = Post("/api/v1/sweeps", other, key);
  EXPECT_EQ(clash->status, 409);
  EXPECT_EQ(Body(clash)["field"], "Idempotency-Key");
  EXPECT_EQ(Rows("sweeps"), 1);
}

TEST_F(RoutesTest, CampaignSubmissionCreatesACampaignRun) {
  auto r = Post("/api/v1/sweeps", R"({"campaign": "paper-58", "scale": "smoke"})");
  ASSERT_EQ(r->status, 201) << r->body;
  json body = Body(r);
  EXPECT_EQ(body["campaign"], "paper-58");
  int64_t id = body["id"].get<int64_t>();
  EXPECT_EQ(r->get_header_value("Location"), "/api/v1/campaign-runs/" + std::to_string(id));
  EXPECT_FALSE(body["sweeps"].empty());
  EXPECT_EQ(Rows("runs"), 58);

  auto run = client_->Get(("/api/v1/campaign-runs/" + std::to_string(id)).c_str());
  ASSERT_EQ(run->status, 200);
  EXPECT_EQ(Body(run)["counts"]["queued"], 58);
  auto results = client_->Get(("/api/v1/campaign-runs/" + std::to_string(id) + "/results").c_str());
  ASSERT_EQ(results->status, 200);
  EXPECT_EQ(Body(results)["results"].size(), 58u);
  // The drive modes' figure (Fig. 2) needs a finished mode run; the coordinate is x or z.
  const std::string modes = "/api/v1/campaign-runs/" + std::to_string(id) + "/modes.svg";
  auto none_yet = client_->Get(modes.c_str());
  EXPECT_EQ(none_yet->status, 422) << none_yet->body;
  EXPECT_THAT(Body(none_yet)["detail"].get<std::string>(), HasSubstr("no finished run"));
  auto bad = client_->Get((modes + "?coordinate=y").c_str());
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(Body(bad)["field"], "coordinate");

  auto campaigns = client_->Get("/api/v1/campaigns");
  ASSERT_EQ(campaigns->status, 200);
  bool found = false;
  const json listed = Body(campaigns)["campaigns"];
  for (const auto& c : listed) found |= c["name"] == "paper-58" && c["builtin"] == true;
  EXPECT_TRUE(found) << campaigns->body;
}

// GET .../results: pages of `limit` rows after a cursor, linked by "next" and a Link header, the
// aggregates of the points of each page's runs, each over all its runs; CSV streamed whole. Bad paging is a 400 naming
// its parameter.
// The aggregates of `all` (a whole set's, in its order) whose points have a run among `rows`.
json AggregatesOfRuns(const json& all, const json& rows) {
  std::set<int64_t> runs;
  for (const json& row : rows) runs.insert(row["run_id"].get<int64_t>());
  json out = json::array();
  for (const json& a : all) {
    bool here = false;
    for (const json& v : a["values"]) here = here || runs.count(v["run_id"].get<int64_t>()) > 0;
    if (here) out.push_back(a);
  }
  return out;
}

TEST_F(RoutesTest, ResultsArePagedByACursorAndStreamedAsCsv) {
  auto r = Post("/api/v1/sweeps", R"({"campaign": "paper-58", "scale": "smoke"})");
  ASSERT_EQ(r->status, 201) << r->body;
  const std::string path = "/api/v1/campaign-runs/" + std::to_string(Body(r)["id"].get<int64_t>()) + "/results";
  const json whole = Body(client_->Get(path.c_str()));  // the default page holds all 58
  ASSERT_EQ(whole["results"].size(), 58u);
  EXPECT_TRUE(whole["next_cursor"].is_null());
  EXPECT_FALSE(whole.contains("next"));
  ASSERT_FALSE(whole["aggregates"].empty());

  std::vector<json> rows;
  std::string next = path + "?limit=7";
  int pages = 0;
  while (!next.empty() && ++pages <= 20) {
    auto page = client_->Get(next.c_str());
    ASSERT_EQ(page->status, 200) << page->body;
    const json body = Body(page);
    EXPECT_LE(body["results"].size(), 7u);
    EXPECT_EQ(body["aggregates"], AggregatesOfRuns(whole["aggregates"], body["results"]))
        << "a page's aggregates: those of its runs' points, each as over the whole set";
    EXPECT_EQ(body["aggregates_of"], routes::kAggregatesOf);
    for (const json& row : body["results"]) rows.push_back(row);
    next = body.value("next", "");
    if (!next.empty()) {
      EXPECT_EQ(page->get_header_value("Link"), "<" + next + ">; rel=\"next\"");
      EXPECT_EQ(next, path + "?cursor=" + body["next_cursor"].get<std::string>() + "&limit=7");
    } else {
      EXPECT_TRUE(body["next_cursor"].is_null());
      EXPECT_FALSE(page->has_header("Link"));
    }
  }
  EXPECT_EQ(pages, 9);  // 58 rows, 7 a page
  EXPECT_EQ(json(rows), whole["results"]) << "the pages hold the same rows in the same order";
  for (const json& row : rows) EXPECT_FALSE(row["sweeps"].empty());

  auto csv = client_->Get((path + "?format=csv").c_str());
  ASSERT_EQ(csv->status, 200);
  EXPECT_EQ(csv->get_header_value("Transfer-Encoding"), "chunked");
  EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 59);
  EXPECT_THAT(csv->body, HasSubstr(",sweeps\n"));

  const int64_t sweep = SubmitExample();  // 2 runs
  const std::string sweep_path = "/api/v1/sweeps/" + std::to_string(sweep) + "/results";
  const json first = Body(client_->Get((sweep_path + "?limit=1").c_str()));
  ASSERT_EQ(first["results"].size(), 1u);
  EXPECT_EQ(first["aggregates"].size(), 1u) << "the aggregates of the page's points, not of every run";
  const json second = Body(client_->Get(first["next"].get<std::string>().c_str()));
  ASSERT_EQ(second["results"].size(), 1u);
  EXPECT_NE(second["results"][0]["run_id"], first["results"][0]["run_id"]);
  EXPECT_TRUE(second["next_cursor"].is_null());

  for (const auto& [query, field] : std::vector<std::pair<std::string, std::string>>{
           {"?limit=0", "limit"}, {"?limit=10001", "limit"}, {"?limit=x", "limit"}, {"?cursor=", "cursor"},
           {"?cursor=abc", "cursor"}, {"?cursor=-1", "cursor"}, {"?cursor=3.4", "cursor"}}) {
    auto bad = client_->Get((sweep_path + query).c_str());
    EXPECT_EQ(bad->status, 400) << query;
    EXPECT_EQ(Body(bad)["field"], field) << query;
  }
  auto bad = client_->Get((path + "?cursor=12").c_str());  // a sweep's cursor on a campaign run
  EXPECT_EQ(bad->status, 400);
  EXPECT_EQ(Body(bad)["field"], "cursor");
  EXPECT_EQ(client_->Get("/api/v1/sweeps/999/results?format=csv")->status, 404);
  EXPECT_EQ(client_->Get("/api/v1/campaign-runs/999/results")->status, 404);
}

// A point whose replicate runs a page boundary splits: each page that holds one of its runs has
// its aggregate over all three beds, the same; the pages' aggregates, each point once, are the
// whole set's (what the CLI, the notebook client and the dashboard show, following the pages).
TEST_F(RoutesTest, APagesAggregatesAreOverAllOfItsPointsRuns) {
  auto r = Post("/api/v1/sweeps", R"({"name": "reps", "scale": "smoke", "replicates": 3,
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
    "axes": [{"param": "Omega", "values": [-80, 80]}], "combine": "product"})");
  ASSERT_EQ(r->status, 201) << r->body;
  const std::string path = "/api/v1/sweeps/" + std::to_string(Body(r)["id"].get<int64_t>()) + "/results";
  const json whole = Body(client_->Get(path.c_str()));
  ASSERT_EQ(whole["results"].size(), 6u);
  ASSERT_EQ(whole["aggregates"].size(), 2u);
  std::string next = path + "?limit=2";
  std::vector<size_t> per_page;
  json merged = json::array();
  std::set<int64_t> points;
  for (int pages = 0; !next.empty() && pages < 10; ++pages) {
    const json body = Body(client_->Get(next.c_str()));
    per_page.push_back(body["aggregates"].size());
    EXPECT_EQ(body["aggregates"], AggregatesOfRuns(whole["aggregates"], body["results"]));
    for (const json& a : body["aggregates"]) {
      EXPECT_EQ(a["replicates"], 3) << "a point's aggregate over some of its runs";
      if (points.insert(a["values"][0]["run_id"].get<int64_t>()).second) merged.push_back(a);
    }
    next = body.value("next", "");
  }
  EXPECT_EQ(per_page, (std::vector<size_t>{1, 2, 1})) << "runs 1-2 of point 1; 3 of 1 and 1 of 2; 2-3 of 2";
  EXPECT_EQ(merged, whole["aggregates"]);
}

class TokenRoutesTest : public RoutesTest {
 protected:
  void SetUp() override { Start("s3cret"); }
};

TEST_F(TokenRoutesTest, EveryRouteButThePublicOnesNeedsTheToken) {
  auto none = Post("/api/v1/sweeps", kExampleSweep);
  EXPECT_EQ(none->status, 401);
  EXPECT_EQ(none->get_header_value("Content-Type"), "application/problem+json");
  EXPECT_EQ(Body(none)["field"], "Authorization");
  auto wrong = Post("/api/v1/sweeps", kExampleSweep, {{"Authorization", "Bearer s3creT"}});
  EXPECT_EQ(wrong->status, 401);
  EXPECT_EQ(Rows("sweeps"), 0);
  EXPECT_EQ(Post("/api/v1/leases", "{}")->status, 401);
  EXPECT_EQ(Post("/api/v1/leases/abc/heartbeat", "{}")->status, 401);
  EXPECT_EQ(Post("/api/v1/leases/abc/complete", "{}")->status, 401);
  EXPECT_EQ(Post("/api/v1/sweeps/1/cancel", "")->status, 401);
  EXPECT_EQ(client_->Get("/api/v1/beds/1/restart")->status, 401);
  EXPECT_EQ(client_->Put("/api/v1/beds/1/restart?token=x", "bytes", "application/octet-stream")->status, 401);
  auto right = Post("/api/v1/sweeps", kExampleSweep, {{"Authorization", "Bearer s3cret"}});
  EXPECT_EQ(right->status, 201) << right->body;
  // Reads too, from loopback as from anywhere (a local proxy makes every client a loopback peer).
  for (const char* read : {"/api/v1/sweeps", "/api/v1/runs", "/api/v1/sweeps/1/results", "/metrics", "/api/v1/live"}) {
    auto r = client_->Get(read);
    EXPECT_EQ(r->status, 401) << read;
    EXPECT_EQ(Body(r)["field"], "Authorization") << read;
  }
  EXPECT_EQ(client_->Get("/api/v1/sweeps", {{"Authorization", "Bearer s3cret"}})->status, 200);
  // An image or a link of the dashboard carries it as ?access_token= (reads only).
  EXPECT_EQ(client_->Get("/api/v1/sweeps?access_token=s3cret")->status, 200);
  EXPECT_EQ(client_->Get("/api/v1/sweeps?access_token=s3creT")->status, 401);
  EXPECT_EQ(client_->Post("/api/v1/sweeps?access_token=s3cret", kExampleSweep, "application/json")->status, 401);
  EXPECT_EQ(client_->Get("/api/v1/beds/1/restart?access_token=s3cret")->status, 401) << "a worker call";
  // Public: health, the API's description, the dashboard's files (they hold no data).
  EXPECT_EQ(client_->Get("/healthz")->status, 200);
  EXPECT_EQ(client_->Get("/api/v1/openapi.json")->status, 200);
  EXPECT_EQ(client_->Get("/")->status, 200);
  EXPECT_EQ(client_->Get("/ui/app.js")->status, 200);
}

// What the daemon's reserve serves (ApiServer): the worker protocol only with the daemon's token,
// and /healthz. A client past its connections (one here) is served only those: a heartbeat with a
// wrong token is refused 429 there like any other request, with the right one it reaches its route.
TEST_F(TokenRoutesTest, TheReserveServesWorkerCallsOnlyWithTheToken) {
  ConnectionLimits limits;
  limits.max_connections_per_client = 1;
  ApiServer api(deps_, limits);
  auto port = api.Bind({"127.0.0.1", 0});
  ASSERT_TRUE(port.ok()) << port.status().ToString();
  std::thread serving([&] { api.Serve(); });
  auto connect_to = [&] {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<uint16_t>(*port));
    inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
    return fd;
  };
  auto ask = [&](const std::string& request_line, const std::string& auth) {
    const int fd = connect_to();
    const std::string head = request_line + "\r\nHost: 127.0.0.1:" + std::to_string(*port) + "\r\n" + auth +
                             "Content-Type: application/json\r\nContent-Length: 2\r\nConnection: close\r\n\r\n{}";
    send(fd, head.data(), head.size(), MSG_NOSIGNAL);
    std::string answer;
    char buf[4096];
    ssize_t n;
    while ((n = recv(fd, buf, sizeof buf, 0)) > 0) answer.append(buf, static_cast<size_t>(n));
    close(fd);
    return answer.substr(0, answer.find("\r\n"));
  };
  const int held = connect_to();  // the client's one connection
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  const std::string beat = "POST /api/v1/leases/abc/heartbeat HTTP/1.1";
  EXPECT_EQ(ask(beat, "Authorization: Bearer s3creT\r\n"), "HTTP/1.1 429 Too Many Requests");
  EXPECT_EQ(ask(beat, ""), "HTTP/1.1 429 Too Many Requests");
  EXPECT_EQ(ask(beat, "Authorization: Bearer s3cret\r\n"), "HTTP/1.1 409 Conflict") << "an unknown lease, at its route";
  EXPECT_EQ(ask("GET /healthz HTTP/1.1", ""), "HTTP/1.1 200 OK");
  close(held);
  api.Stop();
  serving.join();
}

// --public-reads: reads need no token; writes still do.
TEST_F(TokenRoutesTest, PublicReadsOpenReadsOnly) {
  Shutdown();
  deps_.public_reads = true;
  Start("s3cret");
  EXPECT_EQ(client_->Get("/api/v1/sweeps")->status, 200);
  EXPECT_EQ(client_->Get("/metrics")->status, 200);
  EXPECT_EQ(Post("/api/v1/sweeps", kExampleSweep)->status, 401);
  EXPECT_EQ(Post("/api/v1/leases", "{}")->status, 401);
  EXPECT_EQ(client_->Post("/api/v1/backup", "{}", "application/json")->status, 401);
}

// Wrong tokens: refused, counted, and after the first few each waits before its 401 (the waits
// are counted, not timed); the right token still passes at once.
TEST_F(TokenRoutesTest, WrongTokensAreCountedAndSlowedTheRightOneIsNot) {
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(client_->Get("/api/v1/sweeps", {{"Authorization", "Bearer guess" + std::to_string(i)}})->status, 401);
  }
  auto metrics = client_->Get("/metrics", {{"Authorization", "Bearer s3cret"}});
  ASSERT_EQ(metrics->status, 200);
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_auth_failures_total 5\n"));
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_auth_delayed_total 2\n"));  // the 4th and the 5th
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_auth_delay_seconds_total 0.75\n"));
  // A missing token is not a guess: not counted.
  EXPECT_EQ(client_->Get("/api/v1/sweeps")->status, 401);
  metrics = client_->Get("/metrics", {{"Authorization", "Bearer s3cret"}});
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_auth_failures_total 5\n"));
}

// The wrong-token throttle counts clients as the connection limits do: every loopback address is
// one client, unless the daemon counts them apart (--http-loopback-clients-apart). Three guesses
// from 127.0.0.2, then two from 127.0.0.3: the latter are slowed as the same client's 4th and 5th,
// or, apart, are a new client's first two.
TEST_F(TokenRoutesTest, TheWrongTokenThrottleCountsLoopbackClientsAsTheLimitsDo) {
  auto guess_from = [&](const char* address) {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in from{};
    from.sin_family = AF_INET;
    inet_pton(AF_INET, address, &from.sin_addr);
    EXPECT_EQ(bind(fd, reinterpret_cast<sockaddr*>(&from), sizeof from), 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<uint16_t>(server_->port()));
    inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof to), 0);
    const std::string head = "GET /api/v1/sweeps HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(server_->port()) +
                             "\r\nAuthorization: Bearer guess\r\nConnection: close\r\n\r\n";
    send(fd, head.data(), head.size(), MSG_NOSIGNAL);
    std::string answer;
    char buf[4096];
    ssize_t n;
    while ((n = recv(fd, buf, sizeof buf, 0)) > 0) answer.append(buf, static_cast<size_t>(n));
    close(fd);
    return answer.substr(0, answer.find("\r\n"));
  };
  auto delayed = [&] {
    auto metrics = client_->Get("/metrics", {{"Authorization", "Bearer s3cret"}});
    EXPECT_EQ(metrics->status, 200);
    const std::string key = "\nsandswim_auth_delayed_total ";
    const size_t at = metrics->body.find(key);
    return at == std::string::npos ? -1 : std::stoi(metrics->body.substr(at + key.size()));
  };
  for (bool apart : {false, true}) {
    if (apart) {
      Shutdown();
      deps_.loopback_clients_apart = true;
      Start("s3cret");
    }
    for (int i = 0; i < 3; ++i) EXPECT_EQ(guess_from("127.0.0.2"), "HTTP/1.1 401 Unauthorized") << apart;
    EXPECT_EQ(delayed(), 0) << apart;
    for (int i = 0; i < 2; ++i) EXPECT_EQ(guess_from("127.0.0.3"), "HTTP/1.1 401 Unauthorized") << apart;
    EXPECT_EQ(delayed(), apart ? 0 : 2) << (apart ? "127.0.0.3 was counted with 127.0.0.2 though set apart"
                                                  : "127.0.0.3 was not counted with 127.0.0.2");
  }
}

// A Host that does not name this daemon (a page on a rebound DNS name) gets 421 on every path,
// and nothing runs.
TEST_F(RoutesTest, AHostThatIsNotThisDaemonIsMisdirected) {
  for (const char* path : {"/api/v1/sweeps", "/healthz", "/", "/api/v1/openapi.json"}) {
    auto r = client_->Get(path, {{"Host", "evil.example"}});
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 421) << path;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json") << path;
    EXPECT_EQ(Body(r)["field"], "Host") << path;
  }
  auto post = Post("/api/v1/sweeps", kExampleSweep, {{"Host", "evil.example:" + std::to_string(server_->port())}});
  EXPECT_EQ(post->status, 421);
  EXPECT_EQ(Post("/api/v1/sweeps", kExampleSweep, {{"Host", "127.0.0.1:1"}})->status, 421) << "another port";
  EXPECT_EQ(Rows("sweeps"), 0);
  const std::string port = std::to_string(server_->port());
  for (const std::string& host : {"127.0.0.1:" + port, "localhost:" + port, "[::1]:" + port}) {
    EXPECT_EQ(client_->Get("/healthz", {{"Host", host}})->status, 200) << host;
  }
}

// A JSON route takes application/json only: a form or text/plain body (what a page of another
// site can send without a preflight) is 415, naming the header, and stores nothing.
TEST_F(RoutesTest, JsonRoutesTakeOnlyApplicationJson) {
  for (const char* type : {"text/plain", "application/x-www-form-urlencoded", "multipart/form-data; boundary=x", ""}) {
    auto r = client_->Post("/api/v1/sweeps", kExampleSweep, type);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 415) << type;
    EXPECT_EQ(Body(r)["field"], "Content-Type") << type;
  }
  EXPECT_EQ(client_->Post("/api/v1/sweeps/1/cancel", "{}", "text/plain")->status, 415);
  EXPECT_EQ(client_->Post("/api/v1/leases", "{}", "text/plain")->status, 415);
  EXPECT_EQ(Rows("sweeps"), 0);
  EXPECT_EQ(client_->Post("/api/v1/sweeps", kExampleSweep, "application/json; charset=utf-8")->status, 201);
}

// A write whose Origin or Sec-Fetch-Site says another site is refused (403), whatever its type;
// the daemon's own pages and programs (no such headers) may write.
TEST_F(RoutesTest, WritesFromPagesOfOtherSitesAreRefused) {
  const std::string own = "http://127.0.0.1:" + std::to_string(server_->port());
  for (const httplib::Headers& h : std::vector<httplib::Headers>{{{"Origin", "http://evil.example"}},
                                                                 {{"Origin", "http://127.0.0.1:1"}},
                                                                 {{"Origin", "null"}},
                                                                 {{"Sec-Fetch-Site", "cross-site"}},
                                                                 {{"Sec-Fetch-Site", "same-site"}},
                                                                 {{"Origin", own}, {"Sec-Fetch-Site", "cross-site"}}}) {
    auto r = Post("/api/v1/sweeps", kExampleSweep, h);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 403) << h.begin()->second;
    EXPECT_EQ(Body(r)["field"], "Origin");
    EXPECT_EQ(Body(r)["type"], "urn:sandswim:problem:permission-denied");
  }
  // Uploads keep their type but not another site's Origin.
  EXPECT_EQ(client_
                ->Put("/api/v1/beds/1/restart?token=x", {{"Origin", "http://evil.example"}}, "bytes",
                      "application/octet-stream")
                ->status,
            403);
  EXPECT_EQ(Rows("sweeps"), 0);
  EXPECT_EQ(Post("/api/v1/sweeps", kExampleSweep, {{"Origin", own}, {"Sec-Fetch-Site", "same-origin"}})->status, 201);
}

// No GET changes state: the backup is a POST (GET is no route); OPTIONS approves no other origin.
TEST_F(RoutesTest, BackupIsAPostAndOptionsApprovesNoOtherOrigin) {
  auto get = client_->Get("/api/v1/backup");
  EXPECT_EQ(get->status, 404);
  EXPECT_FALSE(std::filesystem::exists(DataDir(deps_.data_dir).Backups())) << "nothing was copied";
  auto post = client_->Post("/api/v1/backup", "{}", "application/json");
  EXPECT_EQ(post->status, 200);
  EXPECT_EQ(post->get_header_value("Content-Type"), "application/vnd.sqlite3");
  EXPECT_EQ(client_->Post("/api/v1/backup", "", "text/plain")->status, 415);

  auto options = client_->Options("/api/v1/sweeps", {{"Origin", "http://evil.example"},
                                                     {"Access-Control-Request-Method", "POST"},
                                                     {"Access-Control-Request-Headers", "content-type"}});
  ASSERT_TRUE(options);
  EXPECT_EQ(options->status, 204);
  EXPECT_EQ(options->get_header_value("Allow"), "GET, OPTIONS, POST");
  for (const auto& [name, value] : options->headers) {
    EXPECT_EQ(name.rfind("Access-Control-", 0), std::string::npos) << name << ": " << value;
  }
}

// Every response, the router's own 404 included, carries the browser-facing headers.
TEST_F(RoutesTest, EveryResponseCarriesTheSecurityHeaders) {
  SubmitExample();
  for (const char* path : {"/", "/ui/app.js", "/api/v1/sweeps", "/healthz", "/no/such/route", "/api/v1/sweeps/999"}) {
    auto r = client_->Get(path);
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->get_header_value("Content-Security-Policy"), "default-src 'self'; frame-ancestors 'none'") << path;
    EXPECT_EQ(r->get_header_value("X-Frame-Options"), "DENY") << path;
    EXPECT_EQ(r->get_header_value("X-Content-Type-Options"), "nosniff") << path;
    EXPECT_EQ(r->get_header_value("Referrer-Policy"), "no-referrer") << path;
    EXPECT_EQ(r->headers.count("X-Content-Type-Options"), 1u) << path;
  }
  auto refused = client_->Post("/api/v1/sweeps", "x", "text/plain");
  EXPECT_EQ(refused->get_header_value("X-Frame-Options"), "DENY");
}

// lease (bed) -> upload restart -> complete bed -> lease (run) -> heartbeat -> complete run ->
// the result is visible in GET /runs/{id} and the sweep's results as JSON and CSV.
// A run whose stored log tail is not valid UTF-8 (written by an older worker, or straight into
// the store) is still served, the bad bytes replaced by U+FFFD.
TEST_F(RoutesTest, RunWithInvalidUtf8InItsLogIsServed) {
  SubmitExample();
  for (int i = 0; i < 2; ++i) {  // the bed, then a run, completed in-process (no JSON on the way)
    auto g = leases_->Lease({"test:1", "test", 1});
    ASSERT_TRUE(g.ok() && g->has_value());
    api::Completion c;
    if ((*g)->kind == api::JobKind::kBed) {
      ASSERT_TRUE(leases_->PutBedRestart((*g)->token, "r", Sha256Hex("r"), deps_.data_dir).ok());
      c.ok = true;
      c.bed_result = api::BedResult{};
    } else {
      c.ok = false;
      c.failure = api::Failure{"deck_error", "ERROR: Invalid pair style \xF4oU`"};
      c.log_tail = "ERROR: Invalid pair style\n \xF4oU`\n";
    }
    auto done = leases_->Complete((*g)->token, c);
    ASSERT_TRUE(done.ok()) << done.status().ToString();
    if ((*g)->kind == api::JobKind::kRun) {
      auto got = client_->Get(("/api/v1/runs/" + std::to_string((*g)->id)).c_str());
      ASSERT_EQ(got->status, 200) << got->body;
      json run = Body(got);
      EXPECT_EQ(run["log_tail"], "ERROR: Invalid pair style\n \xEF\xBF\xBDoU`\n") << got->body;
    }
  }
}

TEST_F(RoutesTest, WorkerProtocolRoundTrip) {
  int64_t sweep = SubmitExample();
  auto lease = Post("/api/v1/leases", R"({"worker": "test:1", "host": "test", "ranks": 1})");
  ASSERT_EQ(lease->status, 200) << lease->body;
  api::LeaseGrant bed = Body(lease)["lease"].get<api::LeaseGrant>();
  ASSERT_EQ(bed.kind, api::JobKind::kBed);

  const std::string restart = "restart bytes \n\0 of a bed";
  const std::string sha = Sha256Hex(restart);
  std::string put_path = "/api/v1/beds/" + std::to_string(bed.id) + "/restart?token=" + bed.token;
  auto bad_sha =
      client_->Put(put_path.c_str(), {{"X-Sha256", std::string(64, '0')}}, restart, "application/octet-stream");
  EXPECT_EQ(bad_sha->status, 400);
  EXPECT_EQ(Body(bad_sha)["field"], "X-Sha256");
  auto put = client_->Put(put_path.c_str(), {{"X-Sha256", sha}}, restart, "application/octet-stream");
  ASSERT_EQ(put->status, 200) << put->body;

  api::Completion bed_done;
  bed_done.ok = true;
  bed_done.bed_result = api::BedResult{
      3700,         0.0,          0.22,         true,        1e-4, sha, static_cast<int64_t>(restart.size()),
      std::nullopt, std::nullopt, std::nullopt, std::nullopt};
  auto completed_bed = Post("/api/v1/leases/" + bed.token + "/complete", json(bed_done).dump());
  ASSERT_EQ(completed_bed->status, 200) << completed_bed->body;
  EXPECT_EQ(Body(completed_bed)["state"], "done");

  auto download = client_->Get(("/api/v1/beds/" + std::to_string(bed.id) + "/restart").c_str());
  ASSERT_EQ(download->status, 200) << download->body;
  EXPECT_EQ(download->body, restart);
  EXPECT_EQ(download->get_header_value("X-Sha256"), sha);

  auto run_lease = Post("/api/v1/leases", R"({"worker": "test:1"})");
  ASSERT_EQ(run_lease->status, 200) << run_lease->body;
  api::LeaseGrant run = Body(run_lease)["lease"].get<api::LeaseGrant>();
  ASSERT_EQ(run.kind, api::JobKind::kRun);
  ASSERT_TRUE(run.bed.has_value());
  EXPECT_EQ(run.bed->sha256, sha);

  auto beat =
      Post("/api/v1/leases/" + run.token + "/heartbeat", R"({"sim_time_s": 0.1, "so_z": 0.001, "step": 10000})");
  ASSERT_EQ(beat->status, 200) << beat->body;
  EXPECT_EQ(Body(beat)["cancel"], false);
  auto lost = Post("/api/v1/leases/deadbeef/heartbeat", "{}");
  EXPECT_EQ(lost->status, 409);
  // The dashboard hears of the beat: the run's trail, and the live snapshot's running run.
  const std::string trail_path = "/api/v1/runs/" + std::to_string(run.id) + "/trail";
  json trail = Body(client_->Get(trail_path.c_str()));
  EXPECT_EQ(trail["t"], json({0.1})) << trail.dump();
  EXPECT_EQ(trail["z"], json({0.001})) << trail.dump();
  clock_.Advance(0.08);  // a tick (0.05 s) later, by the feed's clock
  json board = Body(client_->Get("/api/v1/live"));
  ASSERT_EQ(board["running"].size(), 1u) << board.dump();
  EXPECT_EQ(board["running"][0]["id"], run.id);
  EXPECT_EQ(board["running"][0]["progress"]["sim_time_s"], 0.1);
  EXPECT_EQ(board["running"][0]["trail_points"], 1);
  EXPECT_EQ(board["running"][0]["sweeps"], json::array({sweep})) << "the sweeps it is in, for watch";

  api::Completion done;
  done.ok = true;
  done.result = api::RunResult{};
  done.result->uz = -0.0123;
  done.result->stop_reason = "duration";
  done.trajectory = api::Trajectory{{0, 0.1, 0.2}, {0, 0, 0}, {0, 0.01, 0}, {0, -0.001, -0.002}};
  done.execution.engine_version = "LIGGGHTS (Version test)";
  done.log_tail = "Loop time of 1.0\n";
  auto completed = Post("/api/v1/leases/" + run.token + "/complete", json(done).dump());
  ASSERT_EQ(completed->status, 200) << completed->body;
  clock_.Advance(0.08);  // a tick (0.05 s) later
  EXPECT_TRUE(Body(client_->Get("/api/v1/live"))["running"].empty());
  EXPECT_TRUE(Body(client_->Get(trail_path.c_str()))["t"].empty()) << "trails end with their run";
  EXPECT_EQ(Body(completed)["state"], "done");
  auto again = Post("/api/v1/leases/" + run.token + "/complete", json(done).dump());
  ASSERT_EQ(again->status, 200);
  EXPECT_EQ(Body(again)["state"], "duplicate");

  auto got = client_->Get(("/api/v1/runs/" + std::to_string(run.id)).c_str());
  ASSERT_EQ(got->status, 200);
  json detail = Body(got);
  EXPECT_EQ(detail["state"], "done");
  EXPECT_DOUBLE_EQ(detail["result"]["uz"].get<double>(), -0.0123);
  EXPECT_EQ(detail["trajectory"]["z"].size(), 3u);
  EXPECT_THAT(detail["deck"].get<std::string>(), HasSubstr("LIGGGHTS"));
  EXPECT_THAT(detail["log_tail"].get<std::string>(), HasSubstr("Loop time"));

  std::string results_path = "/api/v1/sweeps/" + std::to_string(sweep) + "/results";
  auto results = client_->Get(results_path.c_str());
  ASSERT_EQ(results->status, 200);
  json rows = Body(results)["results"];
  ASSERT_EQ(rows.size(), 2u);
  int with_uz = 0;
  for (const auto& row : rows) {
    EXPECT_EQ(row["mode"], "oscillatory");
    if (!row["Uz"].is_null()) {
      ++with_uz;
      EXPECT_DOUBLE_EQ(row["Uz"].get<double>(), -0.0123);
      EXPECT_EQ(row["run_id"], run.id);
    }
  }
  EXPECT_EQ(with_uz, 1);

  for (const auto& csv : {client_->Get((results_path + "?format=csv").c_str()),
                          client_->Get(results_path.c_str(), {{"Accept", "text/csv"}})}) {
    ASSERT_EQ(csv->status, 200);
    EXPECT_THAT(csv->get_header_value("Content-Type"), HasSubstr("text/csv"));
    EXPECT_THAT(csv->body, HasSubstr("run_id,key,state,mode,A,f,Omega"));
    EXPECT_THAT(csv->body, HasSubstr(",-0.0123,"));
    EXPECT_EQ(std::count(csv->body.begin(), csv->body.end(), '\n'), 3);
  }
}

// A run's materials where its results are: its JSON row carries those not Table 1's (a Table 1 row
// is what it always was); its CSV row all ten, named with their units, at the end.
TEST_F(RoutesTest, ResultsCarryTheirPointsMaterials) {
  auto r = Post("/api/v1/sweeps", R"({"name": "density", "scale": "smoke",
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3, "grain_youngs": 1e8},
    "axes": [{"param": "so_density", "values": [2500, 5000]}], "combine": "product"})");
  ASSERT_EQ(r->status, 201) << r->body;
  const std::string path = "/api/v1/sweeps/" + std::to_string(Body(r)["id"].get<int64_t>()) + "/results";
  json rows = Body(client_->Get(path.c_str()))["results"];
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_FALSE(rows[0].contains("so_density")) << rows[0];  // Table 1's
  EXPECT_EQ(rows[1]["so_density"], 5000.0);
  EXPECT_EQ(rows[0]["grain_youngs"], 1e8);
  EXPECT_EQ(rows[1]["grain_youngs"], 1e8);
  EXPECT_FALSE(rows[1].contains("so_diameter"));

  auto csv = client_->Get((path + "?format=csv").c_str());
  ASSERT_EQ(csv->status, 200);
  std::istringstream lines(csv->body);
  std::string header, row1, row2;
  std::getline(lines, header);
  std::getline(lines, row1);
  std::getline(lines, row2);
  auto cells = [](const std::string& line) {
    std::vector<std::string> out;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) out.push_back(cell);
    if (!line.empty() && line.back() == ',') out.push_back("");
    return out;
  };
  const std::vector<std::string> names = cells(header);
  ASSERT_EQ(names.size(), ResultCsvColumns().size());
  EXPECT_THAT(header, HasSubstr(",engine_version,so_density_kg_m3,so_diameter_m,so_friction,so_restitution,"
                                "grain_diameter_m,grain_density_kg_m3,grain_friction,grain_restitution,"
                                "grain_youngs_Pa,grain_poisson"));
  auto at = [&](const std::string& line, const std::string& column) {
    const size_t i = std::find(names.begin(), names.end(), column) - names.begin();
    const std::vector<std::string> c = cells(line);
    return i < c.size() ? c[i] : std::string("(none)");
  };
  EXPECT_EQ(at(row1, "so_density_kg_m3"), "2500.0");
  EXPECT_EQ(at(row2, "so_density_kg_m3"), "5000.0");
  EXPECT_EQ(at(row1, "grain_youngs_Pa"), "100000000.0");
  EXPECT_EQ(at(row2, "so_diameter_m"), "0.12");
  EXPECT_EQ(at(row2, "grain_poisson"), "0.25");
}

TEST_F(RoutesTest, CancelStopsQueuedRuns) {
  int64_t sweep = SubmitExample();
  auto r = Post("/api/v1/sweeps/" + std::to_string(sweep) + "/cancel", "");
  ASSERT_EQ(r->status, 200) << r->body;
  EXPECT_EQ(Body(r)["counts"]["cancelled"], 2);
  EXPECT_EQ(Post("/api/v1/sweeps/999/cancel", "")->status, 404);
}

TEST_F(RoutesTest, UnknownRoutesAndIdsAreProblems) {
  auto none = client_->Get("/api/v1/nothing");
  EXPECT_EQ(none->status, 404);
  EXPECT_EQ(none->get_header_value("Content-Type"), "application/problem+json");
  auto missing = client_->Get("/api/v1/runs/12345");
  EXPECT_EQ(missing->status, 404);
  EXPECT_EQ(missing->get_header_value("Content-Type"), "application/problem+json");
  auto huge_id = client_->Get("/api/v1/sweeps/99999999999999999999999");
  EXPECT_EQ(huge_id->status, 400);
  EXPECT_EQ(Body(huge_id)["field"], "id");
}

TEST_F(RoutesTest, HealthzAndMetrics) {
  SubmitExample();
  auto health = client_->Get("/healthz");
  ASSERT_EQ(health->status, 200);
  EXPECT_EQ(Body(health)["status"], "ok");
  auto metrics = client_->Get("/metrics");
  ASSERT_EQ(metrics->status, 200);
  EXPECT_THAT(metrics->get_header_value("Content-Type"), HasSubstr("text/plain"));
  EXPECT_THAT(metrics->body, HasSubstr("# TYPE sandswim_runs gauge"));
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_runs{state=\"queued\"} 2\n"));
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_http_requests_total{code=\"201\"} 1\n"));
}

// schema/openapi.json describes every route of the table, and nothing else.
TEST_F(RoutesTest, OpenApiDescribesExactlyTheRouteTable) {
  auto r = client_->Get("/api/v1/openapi.json");
  ASSERT_EQ(r->status, 200);
  json doc = Body(r);
  EXPECT_EQ(doc["openapi"].get<std::string>().substr(0, 2), "3.");
  std::set<std::string> described;
  for (const auto& [path, item] : doc["paths"].items()) {
    for (const auto& [method, op] : item.items()) {
      if (method == "parameters") continue;
      std::string upper = method;
      for (char& ch : upper) ch = static_cast<char>(std::toupper(ch));
      described.insert(upper + " " + path);
      EXPECT_TRUE(op.contains("responses")) << upper << " " << path;
    }
  }
  std::set<std::string> routed;
  for (const RouteInfo& route : RouteTable()) {
    routed.insert(route.method + " " + route.path);
    // Every described route answers something other than the router's own 404.
  }
  EXPECT_EQ(described, routed);
  // Caps stated in the description are the ones the code enforces.
  EXPECT_EQ(doc["x-caps"]["max_runs_per_submission"], kMaxRunsPerSubmission);
  EXPECT_EQ(doc["x-caps"]["max_amplitude_m"], kMaxAmplitudeM);
  EXPECT_EQ(doc["x-caps"]["max_frequency_hz"], kMaxFrequencyHz);
  EXPECT_EQ(doc["x-caps"]["max_angular_velocity_rad_s"], kMaxAngularVelocity);
  EXPECT_EQ(doc["x-caps"]["max_duration_s"], kMaxDurationS);
  EXPECT_EQ(doc["x-caps"]["max_json_body_bytes"], kMaxJsonBodyBytes);
  EXPECT_EQ(doc["x-caps"]["max_restart_body_bytes"], kMaxRestartBodyBytes);
  EXPECT_EQ(doc["components"]["schemas"]["Point"]["properties"]["Omega"]["maximum"], kMaxAngularVelocity);
}

// Every column of the results table is described, and every number of a point, a result row and
// an aggregate states its unit (x-unit): the Python client (cli/python) names its DataFrame
// columns with them, so a field added without one would reach a notebook without its unit.
TEST_F(RoutesTest, OpenApiDescribesEveryResultColumnWithItsUnit) {
  auto r = client_->Get("/api/v1/openapi.json");
  ASSERT_EQ(r->status, 200);
  const json schemas = Body(r)["components"]["schemas"];
  const json& row = schemas["ResultRow"]["properties"];
  for (const std::string& column : ResultColumns()) EXPECT_TRUE(row.contains(column)) << column;
  for (const char* name : {"Point", "ResultRow", "PointAggregate"}) {
    for (const auto& [field, property] : schemas[name]["properties"].items()) {
      if (property.value("type", "") != "number") continue;
      EXPECT_TRUE(property.contains("x-unit")) << name << "." << field << " is a number without x-unit";
    }
  }
  EXPECT_EQ(row["Uz"]["x-unit"], "m/s");
}

// Every route of the table is served (none falls through to the router's 404).
TEST_F(RoutesTest, EveryRouteInTheTableIsServed) {
  SubmitExample();
  for (const RouteInfo& route : RouteTable()) {
    std::string path = route.path;
    for (const auto& [param, value] :
         {std::pair<std::string, std::string>{"{id}", "1"}, {"{token}", "nope"}, {"{name}", "paper-58"}, {"{n}", "0"}}) {
      auto at = path.find(param);
      if (at != std::string::npos) path.replace(at, param.size(), value);
    }
    if (path == "/api/v1/live/events") {  // a stream: read its first event, then hang up
      std::string first;
      httplib::Result r = client_->Get(path.c_str(), [&](const char* data, size_t n) {
        first.append(data, n);
        return first.find("\n\n") == std::string::npos;
      });
      EXPECT_THAT(first, HasSubstr("event: board")) << path;
      continue;
    }
    httplib::Result r = route.method == "GET"    ? client_->Get(path.c_str())
                        : route.method == "POST" ? client_->Post(path.c_str(), "{}", "application/json")
                                                 : client_->Put(path.c_str(), "x", "application/octet-stream");
    ASSERT_TRUE(r) << route.method << " " << path;
    EXPECT_LT(r->status, 500) << route.method << " " << path << ": " << r->body;
    if (r->status == 404) {
      EXPECT_THAT(r->body, ::testing::Not(HasSubstr("no route"))) << route.method << " " << path;
    }
  }
}

// The dashboard: one page at every dashboard path, its files under /ui/, nothing else.
TEST_F(RoutesTest, DashboardPagesAndFiles) {
  for (const char* path : {"/", "/campaign-runs/3", "/sweeps/1", "/runs/12", "/beds", "/beds/2", "/submit", "/campaigns",
                           "/campaigns/paper-58", "/campaigns/my.own_copy-2/edit", "/new-campaign", "/api-reference",
                           "/api-reference/sweeps", "/help", "/help/docs/index.md", "/help/docs/how-to/sweeps.md"}) {
    auto r = client_->Get(path);
    ASSERT_EQ(r->status, 200) << path;
    EXPECT_EQ(r->get_header_value("Content-Type"), "text/html; charset=utf-8") << path;
    EXPECT_THAT(r->body, HasSubstr("<script src=\"/ui/app.js\"></script>")) << path;
  }
  // The docs, compiled in: a help page's Markdown, and a 404 for a page that is not there.
  auto help = client_->Get("/help-files/docs/index.md");
  ASSERT_EQ(help->status, 200);
  EXPECT_EQ(help->get_header_value("Content-Type"), "text/markdown; charset=utf-8");
  EXPECT_THAT(help->body, HasSubstr("# sandswim documentation"));
  EXPECT_EQ(client_->Get("/help-files/docs/../README.md")->status, 404);
  EXPECT_EQ(client_->Get("/help-files/docs/no-such-page.md")->status, 404);
  auto js = client_->Get("/ui/app.js");
  ASSERT_EQ(js->status, 200);
  EXPECT_EQ(js->get_header_value("Content-Type"), "text/javascript; charset=utf-8");
  EXPECT_THAT(js->body, HasSubstr("/api/v1/live/events"));
  auto uplot = client_->Get("/ui/uPlot.iife.min.js");
  ASSERT_EQ(uplot->status, 200);
  EXPECT_GT(uplot->body.size(), 10000u);
  EXPECT_EQ(client_->Get("/ui/uPlot.min.css")->get_header_value("Content-Type"), "text/css; charset=utf-8");
  for (const char* path : {"/ui/nope.js", "/runs/abc", "/sweeps/1/x", "/ui/..%2Fapp.js", "/campaigns/a/b", "/campaigns/a b"}) {
    auto r = client_->Get(path);
    EXPECT_EQ(r->status, 404) << path;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json") << path;
  }
}

// Responses are compressed with gzip even for a client that prefers brotli (the library's brotli
// took 41 s on a 10,000-run result table).
TEST_F(RoutesTest, CompressesWithGzipNotBrotli) {
  client_->set_decompress(false);
  auto r = client_->Get("/api/v1/openapi.json", {{"Accept-Encoding", "gzip, deflate, br"}});
  ASSERT_EQ(r->status, 200);
  EXPECT_EQ(r->get_header_value("Content-Encoding"), "gzip");
  auto plain = client_->Get("/api/v1/openapi.json", {{"Accept-Encoding", "br"}});
  ASSERT_EQ(plain->status, 200);
  EXPECT_EQ(plain->get_header_value("Content-Encoding"), "");
  EXPECT_NO_THROW(json::parse(plain->body));
  client_->set_decompress(true);
}

// The live snapshot: shared, versioned by content (an ETag answers 304 while nothing changes), a
// new version once something does; at most max_streams event streams (2 here), then 503.
TEST_F(RoutesTest, LiveSnapshotVersionsAndStreamLimit) {
  auto first = client_->Get("/api/v1/live");
  ASSERT_EQ(first->status, 200) << first->body;
  const std::string etag = first->get_header_value("ETag");
  ASSERT_FALSE(etag.empty());
  clock_.Advance(0.08);  // a tick (0.05 s) later
  auto same = client_->Get("/api/v1/live", {{"If-None-Match", etag}});
  EXPECT_EQ(same->status, 304) << "nothing changed: " << same->body;
  SubmitExample();
  clock_.Advance(0.08);  // a tick (0.05 s) later
  auto changed = client_->Get("/api/v1/live", {{"If-None-Match", etag}});
  ASSERT_EQ(changed->status, 200);
  json board = Body(changed);
  EXPECT_GT(board["version"].get<uint64_t>(), Body(first)["version"].get<uint64_t>());
  EXPECT_EQ(board["runs"]["queued"], 2) << board.dump();
  ASSERT_EQ(board["sweeps"].size(), 1u);
  EXPECT_EQ(board["sweeps"][0]["counts"]["queued"], 2);
  EXPECT_FALSE(board["sweeps"][0].contains("spec")) << "the feed carries progress, not specs";

  // Two streams hold the two slots; a third is refused and told to poll.
  std::vector<std::thread> readers;
  std::atomic<int> events{0};
  for (int i = 0; i < 2; ++i) {
    readers.emplace_back([&, port = server_->port()] {
      httplib::Client c("127.0.0.1", port);
      c.set_read_timeout(30, 0);
      c.Get("/api/v1/live/events", [&](const char* data, size_t n) {
        if (std::string(data, n).find("event: board") != std::string::npos) events.fetch_add(1);
        return true;
      });
    });
  }
  for (int i = 0; i < 100 && live_->open_streams() < 2; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(live_->open_streams(), 2);
  auto refused = client_->Get("/api/v1/live/events");
  EXPECT_EQ(refused->status, 503);
  EXPECT_EQ(refused->get_header_value("Retry-After"), "10");
  EXPECT_THAT(Body(refused)["detail"].get<std::string>(), HasSubstr("poll GET /api/v1/live"));
  // A change reaches both streams as a new event.
  SubmitExample();
  for (int i = 0; i < 100 && events.load() < 4; ++i) {
    clock_.Advance(0.05);  // a tick, by the feed's clock: the streams' next look rebuilds
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // the stream threads' turn
  }
  EXPECT_GE(events.load(), 4) << "each stream: the snapshot at connection, then the change";
  live_->Stop();  // streams end; the readers return
  for (std::thread& t : readers) t.join();
  for (int i = 0; i < 100 && live_->open_streams() > 0; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(live_->open_streams(), 0) << "each stream gave its slot back";
}

// The queue cap: a submission that would pass it is refused with the count and the cap, and
// stores nothing; one that only shares runs already queued passes.
TEST_F(RoutesTest, ASubmissionPastTheQueueCapIsRefusedAndStoresNothing) {
  Shutdown();
  deps_.max_queued_runs = 2;
  Start("");
  SubmitExample();  // two runs: at the cap
  const auto before = AllRows();
  auto more = Post("/api/v1/sweeps", R"({"name": "more", "scale": "smoke",
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -40, "duration_s": 0.3}})");
  ASSERT_TRUE(more);
  EXPECT_EQ(more->status, 503) << more->body;
  EXPECT_EQ(more->get_header_value("Content-Type"), "application/problem+json");
  EXPECT_TRUE(more->has_header("Retry-After"));
  const std::string detail = Body(more)["detail"].get<std::string>();
  EXPECT_THAT(detail, HasSubstr("2 runs are queued or running"));
  EXPECT_THAT(detail, HasSubstr("cap of 2"));
  EXPECT_EQ(AllRows(), before) << "a refused submission stores nothing";
  std::string same = kExampleSweep;
  same.replace(same.find("omega-sign"), 10, "omega-again");
  auto shared = Post("/api/v1/sweeps", same);
  EXPECT_EQ(shared->status, 201) << "runs already queued are shared, not added: " << shared->body;
  EXPECT_EQ(Body(shared)["runs_shared"], 2);
}

// f = 1e-300 once made a 5e303-step period (converted to long long: undefined) and
// duration_s = 1e-300 a 0-step deck: both are refused naming the field, and nothing is stored.
TEST_F(RoutesTest, ATinyFrequencyOrDurationIsRefusedNamingItsField) {
  const auto before = AllRows();
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"base.f", R"("f": 1e-300, "duration_s": 0.3)"},
      {"base.duration_s", R"("f": 3, "duration_s": 1e-300)"},
      {"base.f", R"("f": 1e-6, "duration_s": 0.3)"},
      {"base.duration_s", R"("f": 3, "duration_s": 0.0009)"},
  };
  for (const auto& [field, values] : cases) {
    auto r = Post("/api/v1/sweeps", R"({"name": "tiny", "scale": "smoke", "base": {"mode": "oscillatory",
      "A": 0.03, "Omega": -80, )" + values + "}}");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 400) << values << ": " << r->body;
    EXPECT_EQ(Body(r)["field"], field) << r->body;
  }
  EXPECT_EQ(AllRows(), before);
}

// An upload under a token that is not a current lease -- or a bed lease used on another bed's
// path -- is answered at once: 300 MB are announced, 64 KiB sent, and no upload file is made.
TEST_F(RoutesTest, AnUploadUnderAWrongLeaseIsRefusedBeforeItsBodyIsRead) {
  SubmitExample();
  auto lease = Post("/api/v1/leases", R"({"worker": "test:1", "host": "test", "ranks": 1})");
  ASSERT_EQ(lease->status, 200) << lease->body;
  api::LeaseGrant bed = Body(lease)["lease"].get<api::LeaseGrant>();
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  auto put = [&](const std::string& path) {
    const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<uint16_t>(server_->port()));
    inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
    EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    const std::string head = "PUT " + path + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(server_->port()) +
                             "\r\nX-Sha256: " + std::string(64, '0') +
                             "\r\nContent-Type: application/octet-stream\r\nContent-Length: 300000000\r\n\r\n" +
                             std::string(64 * 1024, 'x');
    send(fd, head.data(), head.size(), MSG_NOSIGNAL);
    std::string answer;
    for (int i = 0; i < 300; ++i) {  // until the daemon closes, at most 30 s
      pollfd p{fd, POLLIN, 0};
      if (poll(&p, 1, 100) <= 0) continue;
      char buf[4096];
      const ssize_t n = recv(fd, buf, sizeof buf, 0);
      if (n <= 0) break;
      answer.append(buf, static_cast<size_t>(n));
    }
    close(fd);
    return answer;
  };
  const std::string bogus(32, 'f');
  const std::string wrong_token = put("/api/v1/beds/" + std::to_string(bed.id) + "/restart?token=" + bogus);
  EXPECT_THAT(wrong_token, ::testing::StartsWith("HTTP/1.1 409")) << wrong_token.substr(0, 400);
  EXPECT_THAT(wrong_token, HasSubstr("unknown lease token"));
  const std::string other_bed = put("/api/v1/beds/" + std::to_string(bed.id + 1) + "/restart?token=" + bed.token);
  EXPECT_THAT(other_bed, ::testing::StartsWith("HTTP/1.1 409")) << other_bed.substr(0, 400);
  EXPECT_THAT(other_bed, HasSubstr("not bed " + std::to_string(bed.id + 1)));
  const std::string snapshot = put("/api/v1/leases/" + bogus + "/snapshots/0");
  EXPECT_THAT(snapshot, ::testing::StartsWith("HTTP/1.1 409")) << snapshot.substr(0, 400);
  std::error_code ec;
  const bool any_upload = std::filesystem::exists(DataDir(deps_.data_dir).Uploads(), ec) &&
                          !std::filesystem::is_empty(DataDir(deps_.data_dir).Uploads(), ec);
  EXPECT_FALSE(any_upload) << "a refused upload reached the disk";
  // The lease itself still uploads on its own bed's path.
  const std::string restart = "restart bytes";
  auto ok = client_->Put(("/api/v1/beds/" + std::to_string(bed.id) + "/restart?token=" + bed.token).c_str(),
                         {{"X-Sha256", Sha256Hex(restart)}}, restart, "application/octet-stream");
  ASSERT_TRUE(ok);
  EXPECT_EQ(ok->status, 200) << ok->body;
}

// Worker names past the cap are refused naming the field; a long failure message is cut, not
// refused (a completion is never lost to its log).
TEST_F(RoutesTest, WorkerProtocolStringsAreCapped) {
  SubmitExample();
  auto long_name = Post("/api/v1/leases", json{{"worker", std::string(100000, 'w')}}.dump());
  EXPECT_EQ(long_name->status, 400);
  EXPECT_EQ(Body(long_name)["field"], "worker");
  auto long_host = Post("/api/v1/leases", json{{"worker", "w:1"}, {"host", std::string(300, 'h')}}.dump());
  EXPECT_EQ(long_host->status, 400);
  EXPECT_EQ(Body(long_host)["field"], "host");
  auto lease = Post("/api/v1/leases", R"({"worker": "test:1", "host": "test", "ranks": 1})");
  ASSERT_EQ(lease->status, 200) << lease->body;
  api::LeaseGrant bed = Body(lease)["lease"].get<api::LeaseGrant>();
  api::Completion failed;
  failed.ok = false;
  failed.failure = api::Failure{"deck_error", std::string(200000, 'e')};
  auto completed = Post("/api/v1/leases/" + bed.token + "/complete", json(failed).dump());
  EXPECT_EQ(completed->status, 200) << completed->body.substr(0, 300);
}

TEST(RoutesUnitTest, StatusTableAndProblemShape) {
  EXPECT_EQ(HttpStatusFor(StatusCode::kInvalidArgument), 400);
  EXPECT_EQ(HttpStatusFor(StatusCode::kUnauthenticated), 401);
  EXPECT_EQ(HttpStatusFor(StatusCode::kNotFound), 404);
  EXPECT_EQ(HttpStatusFor(StatusCode::kConflict), 409);
  EXPECT_EQ(HttpStatusFor(StatusCode::kFailedPrecondition), 422);
  EXPECT_EQ(HttpStatusFor(StatusCode::kUnavailable), 503);
  EXPECT_EQ(HttpStatusFor(StatusCode::kInternal), 500);
  json p = ProblemFor(Status::InvalidArgument("base.A", "must be > 0"), 400);
  EXPECT_EQ(p["status"], 400);
  EXPECT_EQ(p["field"], "base.A");
  EXPECT_EQ(p["title"], "Bad Request");
  EXPECT_THAT(p["detail"].get<std::string>(), HasSubstr("must be > 0"));
  EXPECT_THAT(p["type"].get<std::string>(), HasSubstr("invalid"));
}

TEST(RoutesUnitTest, ListenAddressAndPolicy) {
  auto a = ParseListenAddress("127.0.0.1:8640");
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->host, "127.0.0.1");
  EXPECT_EQ(a->port, 8640);
  auto v6 = ParseListenAddress("[::1]:0");
  ASSERT_TRUE(v6.ok());
  EXPECT_EQ(v6->host, "::1");
  EXPECT_EQ(v6->port, 0);
  EXPECT_FALSE(ParseListenAddress("localhost").ok());
  EXPECT_FALSE(ParseListenAddress("127.0.0.1:99999").ok());
  EXPECT_EQ(ParseListenAddress("0.0.0.0:x").status().field(), "--listen");

  EXPECT_TRUE(IsLoopbackHost("127.0.0.1"));
  EXPECT_TRUE(IsLoopbackHost("127.1.2.3"));
  EXPECT_TRUE(IsLoopbackHost("::1"));
  EXPECT_TRUE(IsLoopbackHost("localhost"));
  EXPECT_FALSE(IsLoopbackHost("0.0.0.0"));
  EXPECT_FALSE(IsLoopbackHost("192.168.1.4"));

  EXPECT_TRUE(CheckListenPolicy({"127.0.0.1", 1}, false).ok());
  Status refused = CheckListenPolicy({"0.0.0.0", 1}, false);
  EXPECT_FALSE(refused.ok());
  EXPECT_EQ(refused.field(), "--listen");
  EXPECT_THAT(refused.reason(), HasSubstr("--no-token"));
  // Off loopback with a token: HTTPS, or plain HTTP only when the operator says so.
  Status plain = CheckListenPolicy({"0.0.0.0", 1}, true);
  EXPECT_FALSE(plain.ok());
  EXPECT_THAT(plain.reason(), HasSubstr("--tls self-signed"));
  EXPECT_TRUE(CheckListenPolicy({"0.0.0.0", 1}, true, /*tls=*/true).ok());
  EXPECT_TRUE(CheckListenPolicy({"0.0.0.0", 1}, true, /*tls=*/false, /*plain_http_ok=*/true).ok());
  EXPECT_TRUE(CheckListenPolicy({"127.0.0.1", 1}, true).ok());
}

// Whether every value `recorded` holds is one `served` holds at the same place (objects: each key
// of `recorded`; arrays: the same length, element by element; else equal). `served` may carry more.
void ExpectRecordedIn(const json& recorded, const json& served, const std::string& at = "") {
  if (recorded.is_object()) {
    ASSERT_TRUE(served.is_object()) << at << " is no object";
    for (const auto& [key, value] : recorded.items()) {
      ASSERT_TRUE(served.contains(key)) << at << "/" << key << " is not served";
      ExpectRecordedIn(value, served[key], at + "/" + key);
    }
  } else if (recorded.is_array()) {
    ASSERT_TRUE(served.is_array()) << at << " is no array";
    ASSERT_EQ(recorded.size(), served.size()) << at;
    for (size_t i = 0; i < recorded.size(); ++i) ExpectRecordedIn(recorded[i], served[i], at + "/" + std::to_string(i));
  } else {
    EXPECT_EQ(recorded, served) << at;
  }
}

// tests/fixtures/live_board.json is this daemon's GET /api/v1/live, recorded: a campaign run of
// two sweeps that share a run (Omega 80), its bed done and its three runs in flight (cli_tests
// feed the recording to `watch`'s reading of the board, snapshot.h SnapshotFromBoard). The ETAs'
// "basis" sentences are left out of the recording (prose that changes with the cost model; the
// CLI shows it as it comes). The board served must still hold everything recorded; if its form
// changed on purpose, record it again from this test's message (and run cli_tests).
TEST_F(RoutesTest, TheLiveBoardIsTheOneRecordedForTheCli) {
  const json definition = json::parse(R"({"description": "two sweeps sharing Omega 80", "scale": "smoke",
    "sweeps": [{"name": "low", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 2},
                "axes": [{"param": "Omega", "values": [-80, 80]}]},
               {"name": "high", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": 80, "duration_s": 2},
                "axes": [{"param": "Omega", "values": [80, 120]}]}]})");
  auto stored = client_->Put("/api/v1/campaigns/shared-omega", definition.dump(), "application/json");
  ASSERT_EQ(stored->status, 201) << stored->body;
  auto started = Post("/api/v1/campaigns/shared-omega/runs", R"({"scale": "smoke"})");
  ASSERT_EQ(started->status, 201) << started->body;
  auto bed = leases_->Lease({"w1:1", "w1", 1});
  ASSERT_TRUE(bed.ok() && bed->has_value() && (*bed)->kind == api::JobKind::kBed);
  ASSERT_TRUE(leases_->PutBedRestart((*bed)->token, "r", Sha256Hex("r"), deps_.data_dir).ok());
  api::Completion bed_done;
  bed_done.ok = true;
  bed_done.bed_result = api::BedResult{};
  ASSERT_TRUE(leases_->Complete((*bed)->token, bed_done).ok());
  for (int i = 0; i < 3; ++i) {
    clock_.Advance(1);
    auto run = leases_->Lease({"w" + std::to_string(i + 1) + ":1", "w" + std::to_string(i + 1), 1});
    ASSERT_TRUE(run.ok() && run->has_value() && (*run)->kind == api::JobKind::kRun) << i;
    ASSERT_TRUE(leases_->Heartbeat((*run)->token, {0.25 * (i + 1), 0.1 - 0.01 * i, 1000 * (i + 1)}).ok());
  }
  clock_.Advance(0.08);  // a tick (0.05 s) later, by the feed's clock
  auto live = client_->Get("/api/v1/live");
  ASSERT_EQ(live->status, 200) << live->body;
  const json served = Body(live);
  const json recorded = json::parse(testing::Fixture("live_board.json"), nullptr, /*allow_exceptions=*/false);
  ASSERT_TRUE(recorded.is_object()) << "no tests/fixtures/live_board.json; the board served:\n" << served.dump(2);
  ExpectRecordedIn(recorded, served);
  if (::testing::Test::HasFailure()) ADD_FAILURE() << "the board served:\n" << served.dump(2);
}

}  // namespace
}  // namespace sandswim
