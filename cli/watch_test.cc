#include "cli/watch.h"

#include <algorithm>
#include <map>
#include <mutex>
#include <sstream>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "cli/fake_client_test_util.h"
#include "tests/fixture_file.h"

namespace sandswim::cli {
namespace {

using json = nlohmann::json;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// A sweep that goes queued -> running -> done over `phases` polls; each sleep of its clock (a
// FakeClock's: it moves by the time slept) is one phase.
struct Scenario {
  class PhaseClock : public FakeClock {
   public:
    explicit PhaseClock(Scenario* s) : s_(s) {}
    void SleepFor(double seconds) override {
      FakeClock::SleepFor(seconds);
      if (s_->phase + 1 < s_->phases.size()) s_->phases[++s_->phase](s_->client);
    }

   private:
    Scenario* s_;
  };
  FakeClient client;
  size_t phase = 0;
  std::vector<std::function<void(FakeClient&)>> phases;
  PhaseClock clock{this};
};

// A run of sweep 1 (the sweeps it is in: `sweeps`).
json MakeRun(int64_t id, const std::string& state, double sim_time = 0, double started = 0, double finished = 0,
             std::vector<int64_t> sweeps = {1}) {
  json r = {{"id", id},
            {"state", state},
            {"sweeps", sweeps},
            {"point", {{"mode", "vibration"}, {"A", 0.03}, {"f", 3}, {"duration_s", 4}}},
            {"run_duration_s", 4.0},
            {"progress", {{"sim_time_s", sim_time}, {"so_z", 0.4}, {"step", 0}}},
            {"worker", "n1:1"}};
  if (finished > 0) {
    r["started_at"] = started;
    r["finished_at"] = finished;
  }
  if (state == "failed") r["last_error"] = {{"kind", "engine_error"}, {"message", "Lost atoms"}};
  return r;
}

void Phase(FakeClient& c, std::vector<json> runs) {
  json counts = {{"queued", 0}, {"running", 0}, {"done", 0}, {"failed", 0}, {"cancelled", 0}};
  for (const json& r : runs)
    counts[r["state"].get<std::string>()] = counts[r["state"].get<std::string>()].get<int>() + 1;
  c.sweeps[1] = {{"id", 1}, {"name", "s"}, {"scale", "smoke"}, {"counts", counts}};
  c.runs = runs;
}

std::unique_ptr<Scenario> TwoRunScenario(bool one_fails) {
  auto s = std::make_unique<Scenario>();
  s->phases = {
      [](FakeClient& c) {
        Phase(c, {MakeRun(1, "running", 1.0), MakeRun(2, "queued")});
      },
      [](FakeClient& c) {
        Phase(c, {MakeRun(1, "running", 3.0), MakeRun(2, "queued")});
      },
      [](FakeClient& c) {
        Phase(c, {MakeRun(1, "done", 4, 100, 110), MakeRun(2, "running", 2.0)});
      },
      [one_fails](FakeClient& c) {
        Phase(c, {MakeRun(1, "done", 4, 100, 110), one_fails ? MakeRun(2, "failed") : MakeRun(2, "done", 4, 110, 120)});
      },
  };
  s->phases[0](s->client);
  return s;
}

TEST(WatchTest, PipedWritesOneLinePerChangeAtMostEveryInterval) {
  auto s = TwoRunScenario(/*one_fails=*/false);
  std::ostringstream out;
  WatchOptions options;
  options.interval_s = 1;
  options.line_interval_s = 5;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, options, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.done, 2);
  // First poll (t=0) and the final line; the changes in between came faster than 5 s.
  EXPECT_EQ(out.str(),
            "sweep 1 s (scale smoke): 0/2 done, 1 running, 1 queued, 0 failed, 0 cancelled; "
            "ETA unknown (the daemon gives none: older than its cost model?)\n"
            "sweep 1 s (scale smoke): 2/2 done, 0 running, 0 queued, 0 failed, 0 cancelled; finished\n");
  EXPECT_EQ(out.str().find('\x1b'), std::string::npos);
}

TEST(WatchTest, PipedRepeatsNothingThatDidNotChange) {
  auto s = std::make_unique<Scenario>();
  // The same state for many polls, then done.
  for (int i = 0; i < 30; ++i) s->phases.push_back([](FakeClient& c) { Phase(c, {MakeRun(1, "running", 1.0)}); });
  s->phases.push_back([](FakeClient& c) { Phase(c, {MakeRun(1, "done", 4, 0, 10)}); });
  s->phases[0](s->client);
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok());
  std::string text = out.str();
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 2);
}

TEST(WatchTest, TerminalRedrawsInPlace) {
  auto s = TwoRunScenario(/*one_fails=*/false);
  std::ostringstream out;
  WatchOptions options;
  options.tty = true;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, options, s->clock, out);
  ASSERT_TRUE(last.ok());
  std::string text = out.str();
  // Frame 1 has 3 lines (title, counts, one run); the cursor goes back up over them.
  EXPECT_THAT(text, StartsWith("sweep 1 s (scale smoke)\n"));
  EXPECT_THAT(text, HasSubstr("\x1b[3F\x1b[J"));
  EXPECT_THAT(text, HasSubstr("[#####...............]  25%"));
  EXPECT_THAT(text, HasSubstr("[###############.....]  75%"));
}

// The board counts failures without naming them: a watch that ends with failures reads them once
// and lists them after its last line (piped) or frame (terminal).
TEST(WatchTest, ListsTheFailedRunsAtTheEnd) {
  for (bool tty : {false, true}) {
    auto s = TwoRunScenario(/*one_fails=*/true);
    std::ostringstream out;
    WatchOptions options;
    options.tty = tty;
    auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, options, s->clock, out);
    ASSERT_TRUE(last.ok());
    EXPECT_EQ(last->counts.failed, 1);
    ASSERT_EQ(last->failed.size(), 1u);
    EXPECT_EQ(last->failed[0].reason, "engine_error: Lost atoms");
    EXPECT_THAT(out.str(), ::testing::EndsWith("1 failed, 0 cancelled; finished\n"
                                               "failed:\n"
                                               "  run 2  vibration A=0.03 f=3 T=4s\n"
                                               "    engine_error: Lost atoms\n"))
        << (tty ? "terminal" : "piped");
  }
}

// A target that has finished is not made a failed watch by a failure to read its failures: the
// watch says so and ends as the target did.
TEST(WatchTest, AFailureToListTheFailuresIsSaidNotMadeTheWatchs) {
  auto s = TwoRunScenario(/*one_fails=*/true);
  s->phases.back() = [](FakeClient& c) {
    Phase(c, {MakeRun(1, "done", 4, 100, 110), MakeRun(2, "failed")});
    c.runs_refusal = Status::Unavailable("the daemon went away");
  };
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.failed, 1);
  EXPECT_TRUE(last->failed.empty());
  EXPECT_THAT(out.str(), HasSubstr("(its 1 failed run(s) could not be listed: unavailable: the daemon went away; "
                                   "`sandswim status 1` lists them)\n"));
}

TEST(WatchTest, DaemonErrorEndsTheWatch) {
  FakeClient client;  // knows no sweep
  std::ostringstream out;
  FakeClock clock;
  auto last = Watch(client, Target{Target::Kind::kSweep, 5}, WatchOptions{}, clock, out);
  ASSERT_FALSE(last.ok());
  EXPECT_EQ(last.status().code(), StatusCode::kNotFound);
}

// A daemon that stops answering mid-watch (restarting: the board and every route refused) costs
// those refreshes only: the last frame stays, the outage is said once, and the watch ends as the
// target does once the daemon answers again.
std::unique_ptr<Scenario> RestartScenario(int refreshes_down) {
  auto s = std::make_unique<Scenario>();
  s->phases.push_back([](FakeClient& c) { Phase(c, {MakeRun(1, "running", 1.0), MakeRun(2, "queued")}); });
  for (int i = 0; i < refreshes_down; ++i) {
    s->phases.push_back([](FakeClient& c) {
      c.down = Status::Unavailable("no daemon at http://fake (connection refused)");
    });
  }
  s->phases.push_back([](FakeClient& c) {
    c.down = Status::Ok();
    Phase(c, {MakeRun(1, "done", 4, 100, 110), MakeRun(2, "running", 2.0)});
  });
  s->phases.push_back([](FakeClient& c) { Phase(c, {MakeRun(1, "done", 4, 100, 110), MakeRun(2, "failed")}); });
  s->phases[0](s->client);
  return s;
}

TEST(WatchTest, ADaemonThatStopsAnsweringCostsThoseRefreshesOnly) {
  auto s = RestartScenario(/*refreshes_down=*/3);
  std::ostringstream out, notices;
  WatchOptions options;
  options.notices = &notices;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, options, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.done, 1);
  EXPECT_EQ(last->counts.failed, 1);
  ASSERT_EQ(last->failed.size(), 1u) << "listed once the daemon answered again";
  EXPECT_EQ(s->client.live_calls, 6) << "every refresh asked, the three refused ones too";
  // The first refresh at 22:13:20 UTC (the fake clock's 1.7e9 s), the daemon gone from the next.
  EXPECT_EQ(notices.str(), "daemon unreachable since 22:13:21 UTC; retrying\ndaemon answers again\n");
  EXPECT_THAT(out.str(), StartsWith("sweep 1 s (scale smoke): 0/2 done, 1 running, 1 queued"));
  EXPECT_THAT(out.str(), HasSubstr("1 failed, 0 cancelled; finished\nfailed:\n  run 2"));
}

// On a terminal the outage is a line under the last frame, replaced by the next frame.
TEST(WatchTest, OnATerminalTheOutageIsSaidUnderTheLastFrame) {
  auto s = RestartScenario(/*refreshes_down=*/2);
  std::ostringstream out;
  WatchOptions options;
  options.tty = true;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, options, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  const std::string text = out.str();
  const std::string first = "sweep 1 s (scale smoke)\n";
  ASSERT_THAT(text, StartsWith(first));
  const size_t frame_end = text.find("\x1b[");
  ASSERT_NE(frame_end, std::string::npos);
  const std::string frame = text.substr(0, frame_end);  // 3 lines: title, counts, one run
  EXPECT_THAT(text, HasSubstr("\x1b[3F\x1b[J" + frame + "daemon unreachable since 22:13:21 UTC; retrying\n\x1b[4F"))
      << "the same frame with the outage under it, said once, then the next frame over all 4 lines";
  size_t said = 0;
  for (size_t at = text.find("unreachable"); at != std::string::npos; at = text.find("unreachable", at + 1)) ++said;
  EXPECT_EQ(said, 1u);
}

// A daemon that stays away past --give-up-after ends the watch with what to do next.
TEST(WatchTest, ADaemonAwayPastTheDeadlineEndsTheWatchSayingWhatToDo) {
  auto s = RestartScenario(/*refreshes_down=*/1000);
  std::ostringstream out, notices;
  WatchOptions options;
  options.notices = &notices;
  options.give_up_after_s = 30;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, options, s->clock, out);
  ASSERT_FALSE(last.ok());
  EXPECT_EQ(last.status().code(), StatusCode::kUnavailable);
  EXPECT_THAT(last.status().reason(), HasSubstr("has not answered since 22:13:21 UTC (30 s; last: no daemon at"));
  EXPECT_THAT(last.status().reason(), HasSubstr("`sandswim watch 1` follows it again (--give-up-after S waits longer)"));
  EXPECT_EQ(s->clock.Monotonic(), 31) << "one refresh shown, then 30 s of refused ones a second apart";
  EXPECT_EQ(notices.str(), "daemon unreachable since 22:13:21 UTC; retrying\n");
}

// Unreachable at the first refresh: nothing to keep on screen, most likely a wrong address; and an
// answer that says no (a 500) is no outage: both end the watch at once.
TEST(WatchTest, AnUnreachableFirstRefreshOrARefusalEndsTheWatchAtOnce) {
  for (bool first : {true, false}) {
    auto s = RestartScenario(/*refreshes_down=*/1);
    if (first) {
      s->client.down = Status::Unavailable("no daemon at http://fake (connection refused)");
    } else {
      s->phases[1] = [](FakeClient& c) { c.down = Status::Internal("boom"); };
    }
    std::ostringstream out;
    auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
    ASSERT_FALSE(last.ok());
    EXPECT_EQ(last.status().code(), first ? StatusCode::kUnavailable : StatusCode::kInternal);
    EXPECT_EQ(s->client.live_calls, first ? 1 : 2);
  }
}

// A daemon on loopback whose progress board shows campaign run cr:7 (three sweeps, `done` runs
// done, one more running for three polls, then done), among 50 other sweeps. It counts every
// request by path and answers an unchanged board's If-None-Match with 304.
class BoardDaemon {
 public:
  explicit BoardDaemon(int done) : done_(done) {
    server_.Get("/api/v1/live", [this](const httplib::Request& req, httplib::Response& res) {
      std::lock_guard<std::mutex> lock(mu_);
      const int phase = std::min(live_requests_++, 4);
      const int version = std::min(phase, 3) == 2 ? 1 : std::min(phase, 3);  // phases 1 and 2 alike
      const std::string etag = "\"live-" + std::to_string(version) + "\"";
      res.set_header("ETag", etag);
      if (req.get_header_value("If-None-Match") == etag) {
        ++not_modified_;
        res.status = 304;
        return;
      }
      res.set_content(Board(version).dump(), "application/json");
    });
    server_.set_pre_routing_handler([this](const httplib::Request& req, httplib::Response&) {
      std::lock_guard<std::mutex> lock(mu_);
      ++requests_[req.path];
      return httplib::Server::HandlerResponse::Unhandled;
    });
    port_ = server_.bind_to_any_port("127.0.0.1");
    thread_ = std::thread([this] { server_.listen_after_bind(); });
  }
  ~BoardDaemon() {
    server_.stop();
    thread_.join();
  }
  std::string url() const { return "http://127.0.0.1:" + std::to_string(port_); }
  std::map<std::string, int> requests() {
    std::lock_guard<std::mutex> lock(mu_);
    return requests_;
  }
  int not_modified() {
    std::lock_guard<std::mutex> lock(mu_);
    return not_modified_;
  }

 private:
  // Version 0..2: one run in flight (at 1, 2, 2 s of 4); 3: all done.
  json Board(int version) const {
    const bool finished = version == 3;
    json counts = {{"queued", 0}, {"running", finished ? 0 : 1}, {"done", done_ + (finished ? 1 : 0)},
                   {"failed", 0}, {"cancelled", 0}};
    json board = {{"version", version + 1}, {"time", 1.7e9}, {"runs", counts}};
    board["campaign_runs"] = json::array({{{"id", 7},
                                           {"campaign", "paper-58"},
                                           {"scale", "smoke"},
                                           {"trigger", "manual"},
                                           {"sweeps", {1, 2, 3}},
                                           {"counts", counts}}});
    if (!finished) board["campaign_runs"][0]["eta"] = {
        {"s", 120}, {"rel_error", 0.2}, {"low_s", 98.2}, {"high_s", 146.6}, {"basis", "3 runs"}};
    board["sweeps"] = json::array();
    for (int id = 53; id >= 1; --id) {
      board["sweeps"].push_back({{"id", id}, {"name", "s" + std::to_string(id)}, {"scale", "smoke"}, {"counts", counts}});
    }
    board["running"] = json::array();
    if (!finished) {
      json run = MakeRun(900, "running", version == 0 ? 1.0 : 2.0);
      run["sweeps"] = {2};
      board["running"].push_back(run);
      json other = MakeRun(901, "running", 1.0);  // another campaign's
      other["sweeps"] = {40};
      board["running"].push_back(other);
    }
    return board;
  }

  const int done_;
  httplib::Server server_;
  int port_ = 0;
  std::thread thread_;
  std::mutex mu_;
  int live_requests_ = 0;
  int not_modified_ = 0;
  std::map<std::string, int> requests_;
};

// However many runs a campaign has done, a refresh of watch is one request (the board), never a
// request per run or per sweep; an unchanged board is a 304.
TEST(WatchTest, ARefreshIsOneRequestForTheBoardWhateverTheRunsDone) {
  std::map<int, std::map<std::string, int>> by_done;
  for (int done : {10, 5000}) {
    BoardDaemon daemon(done);
    ClientOptions o;
    o.server = daemon.url();
    o.token = "t";
    std::unique_ptr<DaemonClient> client = NewDaemonClient(o);
    std::ostringstream out;
    FakeClock clock;  // a refresh a second of it
    auto last = Watch(*client, Target{Target::Kind::kCampaignRun, 7}, WatchOptions{}, clock, out);
    const int refreshes = 1 + static_cast<int>(clock.Monotonic());
    ASSERT_TRUE(last.ok()) << last.status().ToString();
    EXPECT_EQ(last->counts.done, done + 1);
    EXPECT_EQ(daemon.requests(), (std::map<std::string, int>{{"/api/v1/live", refreshes}})) << done << " runs done";
    EXPECT_EQ(refreshes, 4);
    EXPECT_EQ(daemon.not_modified(), 1) << "the unchanged board came as a 304";
    EXPECT_EQ(out.str(), "campaign run cr:7 paper-58 (scale smoke, manual): " + std::to_string(done) + "/" +
                             std::to_string(done + 1) + " done, 1 running, 0 queued, 0 failed, 0 cancelled; ETA 2m00s (1m38s-2m27s)\n"
                             "campaign run cr:7 paper-58 (scale smoke, manual): " + std::to_string(done + 1) + "/" +
                             std::to_string(done + 1) + " done, 0 running, 0 queued, 0 failed, 0 cancelled; finished\n");
    by_done[done] = daemon.requests();
  }
  EXPECT_EQ(by_done[10], by_done[5000]);
}

// The board's runs in flight are the target's (by the sweeps each is in), with the title, counts
// and ETA the target's own routes give; a target the board does not list is no snapshot.
TEST(SnapshotTest, TheBoardShowsTheTargetsRunsInFlight) {
  FakeClient client;
  client.campaign_runs[3] = {
      {"id", 3},          {"campaign", "paper-58"},
      {"scale", "smoke"}, {"trigger", "manual"},
      {"sweeps", {1, 2}}, {"counts", {{"queued", 0}, {"running", 1}, {"done", 0}, {"failed", 0}, {"cancelled", 0}}},
      {"eta", {{"s", 60}, {"rel_error", 0.1}, {"basis", "b"}}}};
  json mine = MakeRun(1, "running", 2.0), theirs = MakeRun(2, "running", 1.0);
  mine["sweeps"] = {2};
  theirs["sweeps"] = {9};
  client.runs = {mine, theirs};
  auto board = client.Live();
  ASSERT_TRUE(board.ok());
  std::vector<int64_t> sweeps;
  auto view = SnapshotFromBoard(*board, Target{Target::Kind::kCampaignRun, 3}, &sweeps);
  ASSERT_TRUE(view.ok()) << view.status().ToString();
  ASSERT_TRUE(view->has_value());
  auto routes = FetchSnapshot(client, Target{Target::Kind::kCampaignRun, 3});
  ASSERT_TRUE(routes.ok());
  const Snapshot& s = **view;
  EXPECT_EQ(s.title, routes->title);
  EXPECT_EQ(s.counts.running, 1);
  ASSERT_EQ(s.running.size(), 1u);
  EXPECT_EQ(s.running[0].id, 1);
  EXPECT_EQ(s.running[0].sim_time_s, 2.0);
  ASSERT_TRUE(s.eta.has_value());
  EXPECT_EQ(s.eta->s, 60);
  EXPECT_EQ(sweeps, (std::vector<int64_t>{1, 2}));
  BoardMiss miss = BoardMiss::kNone;
  auto absent = SnapshotFromBoard(*board, Target{Target::Kind::kSweep, 77}, nullptr, &miss);
  ASSERT_TRUE(absent.ok());
  EXPECT_FALSE(absent->has_value());
  EXPECT_EQ(miss, BoardMiss::kThisRefresh) << "no sweep on the board: 77 may be newer";
}

// A daemon without the board (or a target older than it shows) is followed through its own routes.
TEST(WatchTest, WithoutTheBoardWatchFollowsTheTargetsRoutes) {
  auto s = TwoRunScenario(/*one_fails=*/false);
  s->client.serves_board = false;
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.done, 2);
  EXPECT_EQ(s->client.live_calls, 1) << "asked once, then not again";
}

// A target newer than the board (a sweep just submitted; the daemon rebuilds the board at most
// once a tick) is read from its own routes for that refresh only: the next refresh asks the board
// again, and finds it there.
TEST(WatchTest, ATargetNewerThanTheBoardIsLookedForAgain) {
  auto s = TwoRunScenario(/*one_fails=*/false);
  s->client.sweeps[0] = {{"id", 0}, {"name", "older"}, {"scale", "smoke"}, {"counts", json::object()}};
  int stale = 2;  // the first two boards were built before sweep 1
  s->client.edit_board = [&stale](json& board) {
    if (stale-- <= 0) return;
    json& sweeps = board["sweeps"];
    sweeps.erase(std::remove_if(sweeps.begin(), sweeps.end(), [](const json& e) { return e["id"] == 1; }),
                 sweeps.end());
    board["running"] = json::array();
  };
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.done, 2);
  EXPECT_EQ(s->client.live_calls, 4) << "the board, every refresh";
  // Two refreshes through the routes (a GetSweep and 2 ListRuns each); the other two from the board.
  EXPECT_EQ(s->client.route_calls, 2 * 3);
}

// A board the daemon failed to rebuild ("stale": true) shows the target as it was: each refresh
// it is stale reads the target's routes instead, so the watch ends when the target does.
TEST(WatchTest, AStaleBoardIsAMissForThatRefresh) {
  auto s = TwoRunScenario(/*one_fails=*/false);
  json frozen;
  int boards = 0;
  s->client.edit_board = [&](json& board) {
    if (boards++ == 0) {
      frozen = board;  // the last board the daemon could build: sweep 1 running
    } else if (boards < 20) {  // (bounded, so that a watch blind to the mark ends and fails below)
      board = frozen;
      board["stale"] = true;
      board["built_at"] = 1.7e9;
    }
  };
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.done, 2);
  EXPECT_EQ(s->client.live_calls, 4) << "ended with the target, not with the board";
  EXPECT_EQ(s->client.route_calls, 3 * 3) << "the three refreshes after the first through the routes";

  BoardMiss miss = BoardMiss::kNone;
  frozen["stale"] = true;
  auto view = SnapshotFromBoard(frozen, Target{Target::Kind::kSweep, 1}, nullptr, &miss);
  ASSERT_TRUE(view.ok());
  EXPECT_FALSE(view->has_value());
  EXPECT_EQ(miss, BoardMiss::kThisRefresh);
  frozen["stale"] = false;  // (a daemon may say so outright)
  view = SnapshotFromBoard(frozen, Target{Target::Kind::kSweep, 1}, nullptr, &miss);
  ASSERT_TRUE(view.ok());
  EXPECT_TRUE(view->has_value());
}

// A target older than everything the board lists will not be on it: the board is asked once.
TEST(WatchTest, ATargetOlderThanTheBoardIsFollowedThroughItsRoutes) {
  auto s = TwoRunScenario(/*one_fails=*/false);
  s->client.edit_board = [](json& board) {
    board["sweeps"] = json::array({{{"id", 5}, {"name", "newer"}, {"scale", "smoke"}, {"counts", json::object()}}});
  };
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok()) << last.status().ToString();
  EXPECT_EQ(last->counts.done, 2);
  EXPECT_EQ(s->client.live_calls, 1);
}

// Only a daemon without a board (404, or the 503 of one serving no live feed) turns the board off;
// a board request that fails otherwise (busy, a 500) while the routes answer costs the board that
// refresh only.
TEST(WatchTest, OnlyADaemonWithoutABoardTurnsTheBoardOff) {
  for (const Status& failure : {Status::Unavailable("this daemon serves no live feed"),
                                Status::NotFound("no route GET /api/v1/live")}) {
    auto s = TwoRunScenario(/*one_fails=*/false);
    s->client.live_refusals = {failure};
    std::ostringstream out;
    auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
    ASSERT_TRUE(last.ok()) << last.status().ToString();
    EXPECT_EQ(s->client.live_calls, 1) << failure.ToString();
  }
  // (A daemon that refuses connections refuses its routes too: ADaemonThatStopsAnsweringCostsThoseRefreshesOnly.)
  for (const Status& failure : {Status::Unavailable("too many connections"), Status::Internal("boom")}) {
    auto s = TwoRunScenario(/*one_fails=*/false);
    s->client.live_refusals = {failure};
    std::ostringstream out;
    auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
    ASSERT_TRUE(last.ok()) << last.status().ToString();
    EXPECT_EQ(last->counts.done, 2);
    EXPECT_EQ(s->client.live_calls, 4) << failure.ToString() << ": the board again at the next refresh";
    EXPECT_EQ(s->client.route_calls, 3) << "one refresh through the routes";
  }
}

// The runs in flight of a campaign run are grouped by sweep, in the campaign run's order of its
// sweeps (a run in two of them under the first), on the board as through the routes.
TEST(SnapshotTest, RunsInFlightAreGroupedBySweep) {
  FakeClient client;
  client.campaign_runs[3] = {
      {"id", 3},          {"campaign", "paper-58"},
      {"scale", "smoke"}, {"trigger", "manual"},
      {"sweeps", {4, 2}}, {"counts", {{"queued", 0}, {"running", 4}, {"done", 0}, {"failed", 0}, {"cancelled", 0}}}};
  client.runs = {MakeRun(10, "running", 1, 0, 0, {2}), MakeRun(11, "running", 1, 0, 0, {4}),
                 MakeRun(12, "running", 1, 0, 0, {2, 4}), MakeRun(13, "running", 1, 0, 0, {2}),
                 MakeRun(14, "running", 1, 0, 0, {9})};
  auto ids = [](const Snapshot& s) {
    std::vector<int64_t> out;
    for (const RunInFlight& r : s.running) out.push_back(r.id);
    return out;
  };
  auto board = client.Live();
  ASSERT_TRUE(board.ok());
  auto view = SnapshotFromBoard(*board, Target{Target::Kind::kCampaignRun, 3});
  ASSERT_TRUE(view.ok() && view->has_value());
  auto routes = FetchSnapshot(client, Target{Target::Kind::kCampaignRun, 3});
  ASSERT_TRUE(routes.ok());
  EXPECT_EQ(ids(**view), (std::vector<int64_t>{11, 12, 10, 13}));
  EXPECT_EQ(ids(**view), ids(*routes));
  const std::string frame = RenderWatchFrame(**view, RenderOptions{});
  EXPECT_LT(frame.find("run 12"), frame.find("run 10")) << frame;
}

// The daemon's own board (tests/fixtures/live_board.json: GET /api/v1/live recorded, and checked
// against what the route serves by server_tests' RoutesTest.TheLiveBoardIsTheOneRecordedForTheCli):
// campaign run cr:1 of sweeps 1 (Omega -80, 80) and 2 (Omega 80, 120), the Omega 80 run in both,
// its three runs in flight.
TEST(SnapshotTest, ReadsTheDaemonsRecordedBoard) {
  const json board = json::parse(sandswim::testing::Fixture("live_board.json"), nullptr, false);
  ASSERT_TRUE(board.is_object()) << "tests/fixtures/live_board.json";
  auto ids = [](const Snapshot& s) {
    std::vector<int64_t> out;
    for (const RunInFlight& r : s.running) out.push_back(r.id);
    return out;
  };
  std::vector<int64_t> sweeps;
  auto cr = SnapshotFromBoard(board, Target{Target::Kind::kCampaignRun, 1}, &sweeps);
  ASSERT_TRUE(cr.ok()) << cr.status().ToString();
  ASSERT_TRUE(cr->has_value());
  const Snapshot& s = **cr;
  EXPECT_EQ(s.title, "campaign run cr:1 shared-omega (scale smoke, manual)");
  EXPECT_EQ(s.counts.running, 3);
  EXPECT_EQ(s.counts.total(), 3);
  EXPECT_EQ(sweeps, (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(ids(s), (std::vector<int64_t>{1, 2, 3}));
  ASSERT_EQ(s.running.size(), 3u);
  EXPECT_EQ(s.running[1].sim_time_s, 0.5);
  EXPECT_EQ(s.running[1].duration_s, 2.0);
  EXPECT_EQ(s.running[1].worker, "w2:1");
  EXPECT_EQ(s.running[1].point, "oscillatory A=0.03 f=3 Omega=80 T=2s");
  ASSERT_TRUE(s.eta.has_value()) << "the campaign run's ETA";
  EXPECT_GT(s.eta->s, 0);
  EXPECT_GT(s.eta->rel_error, 0);
  EXPECT_THAT(RenderWatchLine(s), HasSubstr(": 0/3 done, 3 running, 0 queued, 0 failed, 0 cancelled; ETA "));

  // Each sweep: its own runs in flight, the shared one in both.
  auto low = SnapshotFromBoard(board, Target{Target::Kind::kSweep, 1});
  auto high = SnapshotFromBoard(board, Target{Target::Kind::kSweep, 2});
  ASSERT_TRUE(low.ok() && low->has_value() && high.ok() && high->has_value());
  EXPECT_EQ(ids(**low), (std::vector<int64_t>{1, 2}));
  EXPECT_EQ(ids(**high), (std::vector<int64_t>{2, 3}));
  EXPECT_EQ((*high)->title, "sweep 2 high (scale smoke)");

  // Not on it: sweep 3 may be newer than the board; nothing is older than sweep 1.
  BoardMiss miss = BoardMiss::kNone;
  auto newer = SnapshotFromBoard(board, Target{Target::Kind::kSweep, 3}, nullptr, &miss);
  ASSERT_TRUE(newer.ok());
  EXPECT_FALSE(newer->has_value());
  EXPECT_EQ(miss, BoardMiss::kThisRefresh);
}

// The recorded board with its sweep-2-only run renumbered below the others and listed first (as
// a board in id order would list it): cr:1 still shows sweep 1's runs first, so the grouping is by
// sweep, not the board's or the ids' order.
TEST(SnapshotTest, GroupsTheRecordedBoardBySweepNotById) {
  json board = json::parse(sandswim::testing::Fixture("live_board.json"), nullptr, false);
  ASSERT_TRUE(board.is_object()) << "tests/fixtures/live_board.json";
  json& running = board["running"];
  ASSERT_EQ(running.size(), 3u);
  ASSERT_EQ(running[2]["sweeps"], json({2})) << "run 3, in sweep 2 only";
  json moved = running[2];
  moved["id"] = 0;
  running.erase(running.begin() + 2);
  running.insert(running.begin(), moved);
  auto cr = SnapshotFromBoard(board, Target{Target::Kind::kCampaignRun, 1});
  ASSERT_TRUE(cr.ok() && cr->has_value());
  std::vector<int64_t> ids;
  for (const RunInFlight& r : (*cr)->running) ids.push_back(r.id);
  EXPECT_EQ(ids, (std::vector<int64_t>{1, 2, 0}));
}

TEST(SnapshotTest, ParsesTargets) {
  auto sweep = ParseTarget("12");
  ASSERT_TRUE(sweep.ok());
  EXPECT_EQ(sweep->kind, Target::Kind::kSweep);
  EXPECT_EQ(sweep->id, 12);
  auto cr = ParseTarget("cr:7");
  ASSERT_TRUE(cr.ok());
  EXPECT_EQ(cr->kind, Target::Kind::kCampaignRun);
  EXPECT_EQ(cr->ToString(), "cr:7");
  EXPECT_TRUE(ParseTarget("sweep:3").ok());
  for (const char* bad : {"", "abc", "0", "-1", "cr:", "cr:x", "12x"}) {
    auto t = ParseTarget(bad);
    ASSERT_FALSE(t.ok()) << bad;
    EXPECT_EQ(t.status().field(), "SWEEP");
  }
}

TEST(SnapshotTest, CampaignRunDeduplicatesSharedRuns) {
  FakeClient client;
  client.campaign_runs[3] = {
      {"id", 3},          {"campaign", "paper-58"},
      {"scale", "smoke"}, {"trigger", "manual"},
      {"sweeps", {1, 2}}, {"counts", {{"queued", 0}, {"running", 1}, {"done", 0}, {"failed", 0}, {"cancelled", 0}}}};
  client.runs = {MakeRun(1, "running", 2.0, 0, 0, {1, 2})};
  auto s = FetchSnapshot(client, Target{Target::Kind::kCampaignRun, 3});
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->running.size(), 1u);
  EXPECT_THAT(s->title, HasSubstr("cr:3 paper-58"));
}

}  // namespace
}  // namespace sandswim::cli
