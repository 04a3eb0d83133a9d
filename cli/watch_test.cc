#include "cli/watch.h"

#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli/fake_client_test_util.h"

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

json MakeRun(int64_t id, const std::string& state, double sim_time = 0, double started = 0, double finished = 0) {
  json r = {{"id", id},
            {"state", state},
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

TEST(WatchTest, ReportsFailuresInTheLastSnapshot) {
  auto s = TwoRunScenario(/*one_fails=*/true);
  std::ostringstream out;
  auto last = Watch(s->client, Target{Target::Kind::kSweep, 1}, WatchOptions{}, s->clock, out);
  ASSERT_TRUE(last.ok());
  EXPECT_EQ(last->counts.failed, 1);
  ASSERT_EQ(last->failed.size(), 1u);
  EXPECT_EQ(last->failed[0].reason, "engine_error: Lost atoms");
}

TEST(WatchTest, DaemonErrorEndsTheWatch) {
  FakeClient client;  // knows no sweep
  std::ostringstream out;
  FakeClock clock;
  auto last = Watch(client, Target{Target::Kind::kSweep, 5}, WatchOptions{}, clock, out);
  ASSERT_FALSE(last.ok());
  EXPECT_EQ(last.status().code(), StatusCode::kNotFound);
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
  client.runs = {MakeRun(1, "running", 2.0)};
  auto s = FetchSnapshot(client, Target{Target::Kind::kCampaignRun, 3});
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_EQ(s->running.size(), 1u);
  EXPECT_THAT(s->title, HasSubstr("cr:3 paper-58"));
}

}  // namespace
}  // namespace sandswim::cli
