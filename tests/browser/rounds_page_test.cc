// The rounds of an adaptive campaign run on the dashboard's campaign-run page, in a real headless
// Chromium, against a real sandswimd whose scheduler tick runs the rounds (server/jobs/rounds.h)
// and a real sandswim-worker on the TRUTH engine (tests/truth/: a known law, so the rounds have
// something to decide). The page is opened before any run has started and follows the rounds
// through the live feed, without a reload, until they stop; then each row is checked against
// GET /api/v1/campaign-runs/{id}.
//
// Screenshots: build/tests/browser/output/dashboard-rounds.png (the rounds) and
// dashboard-rounds-claims.png (the claims, frozen ones with their round), and the report's rounds,
// dashboard-rounds-report.png.
#include <stdlib.h>
#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/browser/webdriver.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim::testing {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;

constexpr char kRoundsToken[] = "fedcba9876543210fedcba9876543210";

// Two sign claims: S1 on a slow rise (rotation alone, 5 mm/s under the truth law: one bed at the
// scale's target leaves it open, as in tests/truth/truth_engine_daemon_test.cc) and S2 on a fast
// one (oscillation with Omega < 0).
json AdaptiveSigns() {
  return {{"description", "two signs, in rounds"},
          {"scale", "smoke"},
          {"sweeps",
           {{{"name", "rotation"}, {"base", {{"mode", "rotation"}, {"omega", 80}, {"axis", "x"}, {"duration_s", 2}}}},
            {{"name", "shaken"},
             {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -40}, {"duration_s", 2}}}}}},
          {"claims",
           {{{"id", "S1"},
             {"title", "Rotation alone rises"},
             {"source", "the abstract's three modes"},
             {"paper", {{"text", "the displacement in z is always upward"}}},
             {"rule", {{"kind", "sign"}, {"sweeps", {"rotation"}}, {"expect", "rise"}}}},
            {{"id", "S2"},
             {"title", "Shaken with Omega < 0 rises"},
             {"source", "Sec. 3.2"},
             {"paper", {{"text", "rose with negative Omega"}}},
             {"rule", {{"kind", "sign"}, {"sweeps", {"shaken"}}, {"expect", "rise"}}}}}},
          {"adaptive", {{"budget_core_h", 20}, {"max_rounds", 3}}}};
}

TEST(RoundsPageTest, TheCampaignRunPageFollowsItsRoundsUntilTheyStop) {
  std::string why;
  if (!BrowserAvailable(&why)) GTEST_SKIP() << why;
  const std::string out = SANDSWIM_BROWSER_TEST_DIR;
  std::filesystem::create_directories(out);
  const std::string dir = CacheDir() + "/dashboard-rounds";
  std::filesystem::remove_all(dir);
  setenv("SANDSWIM_TOKEN", kRoundsToken, 1);
  setenv("SANDSWIM_TRUTH_LAW", "paper", 1);
  setenv("SANDSWIM_TRUTH_SEED", "11", 1);
  unsetenv("SANDSWIM_TRUTH_PACE");
  Daemon daemon(dir + "/daemon", {"--scheduler-tick", "1"});
  int status = 0;
  const json put = daemon.Put("/api/v1/campaigns/signs", AdaptiveSigns(), &status);
  ASSERT_EQ(status, 201) << put.dump();
  const json submitted = daemon.Post("/api/v1/campaigns/signs/runs", json::object(), &status);
  ASSERT_EQ(status, 201) << submitted.dump();
  const int64_t id = submitted.value("id", int64_t{0});
  const std::string page = "/campaign-runs/" + std::to_string(id);

  // Opened before a run has started (as a user who has just submitted it).
  Browser browser(out);
  browser.Navigate(daemon.url() + page + "?token=" + kRoundsToken);
  ASSERT_TRUE(browser.WaitUntil("document.querySelector('#live-status').classList.contains('live')", 20))
      << browser.Text("#live-status");
  ASSERT_TRUE(browser.WaitUntil("!!document.querySelector('#rounds')", 20)) << browser.Text("#main");
  EXPECT_THAT(browser.Text("#rounds"), HasSubstr("Budget 20 core-h, at most 3 rounds"));
  EXPECT_THAT(browser.Text("#rounds-stop"), ::testing::Not(HasSubstr("Stopped")));

  std::unique_ptr<ChildProcess> worker =
      StartWorker(daemon, dir + "/worker", 2, {"--launcher", "direct", "--engine", SANDSWIM_TRUTH_ENGINE_PATH});
  // The page follows the rounds through the live feed until they stop: no reload.
  const bool stopped =
      browser.WaitUntil("/Stopped after round/.test(document.querySelector('#rounds-stop').textContent)", 400);
  worker->Stop();
  const json info = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id));
  ASSERT_TRUE(stopped) << browser.Text("#rounds") << "\n" << info.dump(1);
  const json& rounds = info["rounds"];
  ASSERT_TRUE(rounds.is_array() && !rounds.empty()) << info.dump(1);
  ASSERT_TRUE(rounds.back()["stop_reason"].is_string()) << info.dump(1);

  // One row a round, each as the API has it: its state, every reason it added, its core-hours,
  // the budget left, each claim's state after its look (frozen ones with their round).
  ASSERT_EQ(browser.Script("return document.querySelectorAll('#rounds-table tbody tr').length;").get<size_t>(),
            rounds.size())
      << browser.Text("#rounds");
  for (size_t i = 0; i < rounds.size(); ++i) {
    const json& r = rounds[i];
    const std::string row = "#rounds-table tbody tr:nth-child(" + std::to_string(i + 1) + ")";
    const std::string text = browser.Text(row);
    EXPECT_EQ(browser.Attribute(row, "data-round"), std::to_string(r["round"].get<int>()));
    EXPECT_THAT(text, HasSubstr(i + 1 == rounds.size() ? "stopped" : "finished")) << text;
    for (const json& a : r["actions"]) EXPECT_THAT(text, HasSubstr(a["reason"].get<std::string>())) << text;
    // Core-hours as num() prints them: three significant digits.
    const double left = r["budget_left_core_h"].get<double>();
    const std::string left_text = browser.Script("return num(arguments[0]);", json::array({left})).get<std::string>();
    EXPECT_EQ(browser.Text(row + " td:nth-child(6)"), left_text);
    ASSERT_TRUE(r["claims_after"].is_array()) << r.dump();
    for (const json& c : r["claims_after"]) {
      std::string state = c["claim"].get<std::string>() + " " + c["verdict"].get<std::string>();
      if (c.contains("frozen_at_round"))
        state += " (frozen at round " + std::to_string(c["frozen_at_round"].get<int>()) + ")";
      EXPECT_THAT(text, HasSubstr(state)) << text;
    }
  }
  EXPECT_THAT(browser.Text("#rounds-stop"), HasSubstr(rounds.back()["stop_reason"].get<std::string>()));
  // The runs table, read again at the last look: the campaign run's runs as they are now.
  const json results = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id) + "/results");
  ASSERT_TRUE(browser.WaitUntil(
      "document.querySelectorAll('#runs tbody tr').length === " + std::to_string(results["results"].size()) +
          " && ![...document.querySelectorAll('#runs tbody td[data-key=state]')]"
          ".some(td => /queued|running/.test(td.textContent))",
      20))
      << browser.Text("#runs") << "\n"
      << results.dump(1);
  // The claims table, drawn again after the last look, shows each frozen verdict with its round.
  const json claims = daemon.Get("/api/v1/campaign-runs/" + std::to_string(id) + "/claims");
  ASSERT_EQ(claims["adaptive"], true) << claims.dump();
  bool any_frozen = false;
  for (const json& c : claims["claims"]) {
    ASSERT_TRUE(
        browser.WaitUntil("!!document.querySelector('#claims-table') && document.querySelector('#claims-table')"
                          ".textContent.includes(" +
                              c["verdict_text"].dump() + ")",
                          20))
        << c["verdict_text"] << " not in " << browser.Text("#claims");
    if (c["frozen_at_round"].is_number()) {
      any_frozen = true;
      EXPECT_THAT(c["verdict_text"].get<std::string>(), HasSubstr("(frozen at round "));
    }
  }
  EXPECT_TRUE(any_frozen) << "no claim was decided: " << claims.dump(1);
  browser.Script("document.querySelector('#claims').scrollIntoView(); return 0;");
  browser.Screenshot(out + "/dashboard-rounds-claims.png");
  browser.Script("document.querySelector('#rounds').scrollIntoView(); return 0;");
  browser.Screenshot(out + "/dashboard-rounds.png");

  // The report's rounds section, as the daemon serves it (its link on the page).
  browser.Navigate(daemon.url() + "/api/v1/campaign-runs/" + std::to_string(id) +
                   "/report?access_token=" + kRoundsToken);
  ASSERT_TRUE(browser.WaitUntil("!!document.querySelector('#rounds-table')", 30)) << browser.Text("body");
  EXPECT_EQ(browser.Script("return document.querySelectorAll('#rounds-table tr[id^=round-]').length;").get<size_t>(),
            rounds.size());
  EXPECT_THAT(browser.Text("#rounds-stop"), HasSubstr(rounds.back()["stop_reason"].get<std::string>()));
  browser.Script("document.querySelector('#rounds').scrollIntoView(); return 0;");
  browser.Screenshot(out + "/dashboard-rounds-report.png");
  browser.Navigate(daemon.url() + page);
  ASSERT_TRUE(browser.WaitUntil("!!document.querySelector('#rounds-table')", 20)) << browser.Text("#main");

  // Every server string of a round is escaped: markup in a reason, a claim, a verdict or the stop
  // reason is shown as text, never made into elements or run.
  const json hostile = browser.Script(R"JS(
    const evil = '<img src=x onerror="window.pwned=1">';
    const box = document.createElement('div');
    box.id = 'hostile';
    box.innerHTML = roundsHtml({budget_core_h: 1, max_rounds: evil}, [{round: evil, finished_at: 1, core_h_planned: 1,
      core_h_spent: 1, budget_left_core_h: 0, actions: [{reason: evil}], claims_after: [{claim: evil, verdict: evil,
      frozen_at_round: evil}], stop_reason: evil}]);
    document.body.appendChild(box);
    return {images: box.querySelectorAll('img').length, text: box.textContent};
  )JS");
  EXPECT_EQ(hostile["images"], 0) << hostile.dump();
  EXPECT_THAT(hostile["text"].get<std::string>(), HasSubstr("<img src=x onerror=\"window.pwned=1\">"));
  EXPECT_TRUE(browser.Script("return window.pwned === undefined;").get<bool>());
  EXPECT_THAT(browser.ConsoleErrors(), ::testing::IsEmpty());
  unsetenv("SANDSWIM_TOKEN");
}

}  // namespace
}  // namespace sandswim::testing
