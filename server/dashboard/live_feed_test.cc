#include "server/dashboard/live_feed.h"

#include <stdlib.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <thread>
#include <vector>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "server/jobs/submission.h"
#include "server/store/campaigns.h"
#include "server/store/rounds.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

class LiveFeedTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(store_); }
  FakeClock clock_;
  testing::TempStore store_{"live", "test.db"};
};

// However many pages ask at once, one snapshot is built per tick, and all get the same one.
TEST_F(LiveFeedTest, ManyReadersShareOneBuildPerTick) {
  LiveFeed feed(store_.get(), &clock_, /*tick_s=*/60);
  std::vector<std::thread> pages;
  std::atomic<uint64_t> versions{0};
  for (int i = 0; i < 50; ++i) {
    pages.emplace_back([&] { versions.fetch_add(feed.Current()->version); });
  }
  for (std::thread& t : pages) t.join();
  EXPECT_EQ(feed.builds(), 1u);
  EXPECT_EQ(versions.load(), 50 * feed.Current()->version) << "all on the one version";
}

// A build that finds what the last found keeps its version: waiters hear only of changes.
TEST_F(LiveFeedTest, AnUnchangedBoardKeepsItsVersion) {
  LiveFeed feed(store_.get(), &clock_, /*tick_s=*/0.01);
  const uint64_t v = feed.Current()->version;
  clock_.Advance(0.02);                            // ticks pass (the feed's clock says when)
  auto later = feed.WaitNewer(v, /*wait_s=*/0.1);  // a rebuild, and nothing changes
  EXPECT_EQ(later->version, v);
  EXPECT_GE(feed.builds(), 2u);
  feed.Stop();
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(feed.WaitNewer(v, 60)->version, v);
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(1)) << "a stopped feed does not wait";
}

// A rebuild that fails serves the last content marked stale, with when it was read, under a new
// version (a client holding the last ETag hears of it); the next good build drops the mark under
// another version. A snapshot that never failed carries neither field.
TEST_F(LiveFeedTest, ABoardItCannotRebuildIsMarkedStale) {
  LiveFeed feed(store_.get(), &clock_, /*tick_s=*/1);
  const double read_at = clock_.Now();
  const auto fresh = feed.Current();
  const json first = json::parse(fresh->json);
  EXPECT_FALSE(first.contains("stale"));
  EXPECT_FALSE(first.contains("built_at"));
  auto exec = [&](const char* sql) { return store_->db().Write([&](Transaction& t) { return t.Exec(sql); }); };
  ASSERT_TRUE(exec("ALTER TABLE sweeps RENAME TO sweeps_away").ok());  // every read of the board fails
  clock_.Advance(2);
  const auto stale = feed.Current();
  const json board = json::parse(stale->json);
  EXPECT_EQ(board.value("stale", false), true) << stale->json;
  EXPECT_DOUBLE_EQ(board.value("built_at", 0.0), read_at);
  EXPECT_DOUBLE_EQ(board.value("time", 0.0), clock_.Now());
  EXPECT_EQ(board["sweeps"], first["sweeps"]) << "the last content, kept";
  EXPECT_GT(stale->version, fresh->version);
  clock_.Advance(2);
  EXPECT_EQ(feed.Current()->version, stale->version) << "still stale: no change";
  ASSERT_TRUE(exec("ALTER TABLE sweeps_away RENAME TO sweeps").ok());
  clock_.Advance(2);
  const auto again = feed.Current();
  const json recovered = json::parse(again->json);
  EXPECT_FALSE(recovered.contains("stale")) << again->json;
  EXPECT_FALSE(recovered.contains("built_at"));
  EXPECT_GT(again->version, stale->version);
}

// A trail keeps one point per newer beat; past kMaxTrailPoints it halves its resolution, keeping
// the whole run.
TEST_F(LiveFeedTest, TrailsKeepNewerBeatsAndThinOut) {
  LiveFeed feed(store_.get(), &clock_);
  feed.RecordBeat(7, 0.1, -0.01);
  feed.RecordBeat(7, 0.1, -0.02);  // the same beat again (a retried request)
  EXPECT_EQ(feed.TrailOf(7).t, std::vector<double>({0.1}));
  EXPECT_EQ(feed.TrailOf(7).z, std::vector<double>({-0.01}));
  feed.RecordBeat(7, 0.02, -0.03);  // earlier: the run's next attempt starts a trail of its own
  EXPECT_EQ(feed.TrailOf(7).t, std::vector<double>({0.02}));
  EXPECT_TRUE(feed.TrailOf(8).t.empty());
  for (size_t i = 1; i < LiveFeed::kMaxTrailPoints + 10; ++i) feed.RecordBeat(9, 0.001 * i, 0);
  const LiveFeed::Trail trail = feed.TrailOf(9);
  EXPECT_LT(trail.t.size(), LiveFeed::kMaxTrailPoints);
  EXPECT_GT(trail.t.size(), LiveFeed::kMaxTrailPoints / 2 - 1);
  EXPECT_DOUBLE_EQ(trail.t.front(), 0.001);
  EXPECT_DOUBLE_EQ(trail.t.back(), 0.001 * (LiveFeed::kMaxTrailPoints + 9)) << "the latest point is kept";
  for (size_t i = 1; i < trail.t.size(); ++i) EXPECT_GT(trail.t[i], trail.t[i - 1]);
  // No such run is running: the next snapshot drops its trail.
  feed.Current();
  EXPECT_TRUE(feed.TrailOf(9).t.empty());
}

// A trail no beat reached for ten minutes ends at the next beat of any run; a quieter one stays.
TEST_F(LiveFeedTest, ATrailNoBeatReachedForTenMinutesEnds) {
  LiveFeed feed(store_.get(), &clock_);
  feed.RecordBeat(1, 0.1, 0.001);
  feed.RecordBeat(2, 0.1, 0.002);
  clock_.Advance(300);
  feed.RecordBeat(2, 0.2, 0.003);  // run 2 beats again five minutes on; run 1 has gone quiet
  EXPECT_EQ(feed.TrailOf(1).t.size(), 1u) << "five minutes quiet: kept";
  clock_.Advance(LiveFeed::kTrailIdleS - 300 + 1);  // run 1: ten minutes and a second; run 2: five
  feed.RecordBeat(3, 0.1, 0.004);
  EXPECT_TRUE(feed.TrailOf(1).t.empty()) << "ten minutes without a beat: the trail ends";
  EXPECT_EQ(feed.TrailOf(2).t.size(), 2u);
  EXPECT_EQ(feed.TrailOf(3).t.size(), 1u);
  clock_.Set(clock_.Now() - 3600);  // a wall clock set back an hour does not move the rule
  clock_.Advance(300);
  feed.RecordBeat(3, 0.2, 0.005);
  clock_.Advance(LiveFeed::kTrailIdleS - 300 + 1);  // run 2: over ten minutes quiet; run 3: five
  feed.RecordBeat(3, 0.3, 0.006);
  EXPECT_TRUE(feed.TrailOf(2).t.empty());
  EXPECT_EQ(feed.TrailOf(3).t.size(), 3u);
}

TEST_F(LiveFeedTest, StreamsAreCapped) {
  LiveFeed feed(store_.get(), &clock_, 1.0, /*max_streams=*/2);
  EXPECT_TRUE(feed.OpenStream());
  EXPECT_TRUE(feed.OpenStream());
  EXPECT_FALSE(feed.OpenStream());
  EXPECT_EQ(feed.open_streams(), 2);
  feed.CloseStream();
  EXPECT_TRUE(feed.OpenStream());
  feed.CloseStream();
  feed.CloseStream();
  feed.Stop();
  EXPECT_FALSE(feed.OpenStream()) << "a stopped feed opens no stream";
  EXPECT_EQ(feed.open_streams(), 0);
}

TEST_F(LiveFeedTest, StreamsAreCappedPerClient) {
  LiveFeed feed(store_.get(), &clock_, 1.0, /*max_streams=*/10, /*sweeps=*/50, /*campaign_runs=*/20,
                /*max_streams_per_client=*/2);
  EXPECT_TRUE(feed.OpenStream("127.0.0.1"));
  EXPECT_TRUE(feed.OpenStream("127.0.0.1"));
  EXPECT_FALSE(feed.OpenStream("127.0.0.1")) << "a third from one client";
  EXPECT_TRUE(feed.OpenStream("127.0.0.2")) << "another client has its own";
  EXPECT_EQ(feed.open_streams(), 3);
  feed.CloseStream("127.0.0.1");
  EXPECT_TRUE(feed.OpenStream("127.0.0.1"));
  for (const char* client : {"127.0.0.1", "127.0.0.1", "127.0.0.2"}) feed.CloseStream(client);
  EXPECT_EQ(feed.open_streams(), 0);
}

// An adaptive campaign run carries how far its rounds are -- planned, looked at, stopped -- so that
// its page reads them again only when the daemon has planned a round or taken a look; a
// fixed-design campaign run carries nothing of the kind.
TEST_F(LiveFeedTest, AnAdaptiveCampaignRunSaysHowFarItsRoundsAre) {
  using nlohmann::json;
  json definition = json::parse(R"({"description": "signs", "scale": "smoke",
    "sweeps": [{"name": "signs", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 2},
                "axes": [{"param": "Omega", "values": [-80, 80]}]}]})");
  int64_t ids[2] = {0, 0};
  for (int adaptive = 0; adaptive < 2; ++adaptive) {
    StoredCampaign c;
    c.name = adaptive ? "in-rounds" : "fixed";
    c.definition = definition;
    c.definition["name"] = c.name;
    if (adaptive) {
      c.definition["claims"] = json::parse(R"([{"id": "S1", "title": "signs", "source": "test", "paper": {"text": "t"},
        "rule": {"kind": "sign", "sweeps": ["signs"], "expect": "against_Omega"}}])");
      c.definition["adaptive"] = {{"budget_core_h", 1000}, {"max_rounds", 2}};
    }
    ASSERT_TRUE(PutCampaign(*store_, c).ok());
    SubmitRequest request;
    request.campaign = c.name;
    auto submitted = Submit(*store_, request, "LIGGGHTS (Version live test)", clock_.Now());
    ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
    ids[adaptive] = *submitted->campaign_run_id;
  }
  LiveFeed feed(store_.get(), &clock_, /*tick_s=*/0.01);
  auto rounds_of = [&](int64_t id) {
    clock_.Advance(0.02);
    const json snap = json::parse(feed.Current()->json);
    for (const json& c : snap["campaign_runs"])
      if (c["id"] == id) return c.contains("rounds") ? c["rounds"] : json("absent");
    return json("not shown");
  };
  EXPECT_EQ(rounds_of(ids[0]), "absent");
  EXPECT_EQ(rounds_of(ids[1]), json({{"rounds", 0}, {"looks", 0}, {"stopped", false}}));
  rounds::RoundRow first;
  first.campaign_run_id = ids[1];
  first.round = 1;
  first.planned_at = clock_.Now();
  ASSERT_TRUE(store_->db().Write([&](Transaction& t) { return rounds::InsertRound(t, first); }).ok());
  const uint64_t before = feed.Current()->version;
  EXPECT_EQ(rounds_of(ids[1]), json({{"rounds", 1}, {"looks", 0}, {"stopped", false}}));
  EXPECT_GT(feed.Current()->version, before) << "a page hears of a planned round";
  ASSERT_TRUE(store_->db()
                  .Write([&](Transaction& t) {
                    return rounds::FinishRound(t, ids[1], 1, clock_.Now(), 0.5, json::array(),
                                               std::string("every claim runs can decide is decided"));
                  })
                  .ok());
  EXPECT_EQ(rounds_of(ids[1]), json({{"rounds", 1}, {"looks", 1}, {"stopped", true}}));
}

}  // namespace
}  // namespace sandswim
