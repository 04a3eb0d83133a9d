// The web dashboard (server/dashboard/) in a real headless Chromium, against a real sandswimd with
// a token and a real sandswim-worker whose engine is the STAND-IN (tests/bench/stand_in_engine.cc,
// named as such: it simulates nothing; its dump grows over SANDSWIM_STAND_IN_SECONDS as a real
// engine's does). The dashboard with a real smoke run: e2e_test.cc.
//
// Screenshots are test outputs, under build/tests/browser/output/ (dashboard-*.png).
#include <stdlib.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tests/browser/webdriver.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim::testing {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;

// 128 bits or more, as sandswimd requires of a token it is given.
constexpr char kDashToken[] = "0123456789abcdef0123456789abcdef";

// Console errors since entry `from`, less the network errors of refusals a test provoked on
// purpose (Chromium logs every 4xx answer to a fetch as an error).
std::vector<std::string> ErrorsSince(Browser& browser, size_t from, const std::vector<std::string>& expected_statuses) {
  std::vector<std::string> out;
  const std::vector<std::string> all = browser.ConsoleErrors();
  for (size_t i = from; i < all.size(); ++i) {
    bool expected = false;
    for (const std::string& s : expected_statuses) expected = expected || all[i].find("status of " + s) != std::string::npos;
    if (!expected) out.push_back(all[i]);
  }
  return out;
}

class DashboardTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    std::string why;
    if (!BrowserAvailable(&why)) return;
    out_ = new std::string(SANDSWIM_BROWSER_TEST_DIR);
    std::filesystem::create_directories(*out_);
    const std::string dir = CacheDir() + "/dashboard";
    std::filesystem::remove_all(dir);
    setenv("SANDSWIM_TOKEN", kDashToken, 1);     // the daemon, its worker and this test's REST calls
    setenv("SANDSWIM_STAND_IN_SECONDS", "6", 1);  // long enough to watch a run go
    daemon_ = new Daemon(dir + "/daemon", {"--lease-ttl", "6"});
    int status = 0;
    // Submitted first, so run first (oldest first): the sweep whose runs the tests watch.
    json sweep = daemon_->Post("/api/v1/sweeps", OmegaSweep("dash-omega", {-80, -40, 40, 80}, 1.5), &status);
    ASSERT_EQ(status, 201) << sweep.dump();
    sweep_id_ = sweep["id"].get<int64_t>();
    json campaign = daemon_->Post("/api/v1/sweeps", {{"campaign", "paper-58"}, {"scale", "smoke"}}, &status);
    ASSERT_EQ(status, 201) << campaign.dump();
    campaign_run_id_ = campaign["id"].get<int64_t>();
    campaign_sweep_id_ = campaign["sweeps"][0].get<int64_t>();
    worker_ = StartWorker(*daemon_, dir + "/worker", 2,
                          {"--launcher", "direct", "--engine", SANDSWIM_STAND_IN_ENGINE_PATH, "--heartbeat", "0.3"})
                  .release();
    browser_ = new Browser(*out_);
  }
  static void TearDownTestSuite() {
    delete browser_;
    if (worker_ != nullptr) worker_->Stop();
    delete worker_;
    delete daemon_;
    delete out_;
    unsetenv("SANDSWIM_TOKEN");
  }
  // The 1-based line of `text` where `needle` is, searched from where `after` is.
  static int LineOf(const std::string& text, const std::string& needle, const std::string& after = "") {
    const size_t at = text.find(needle, after.empty() ? 0 : text.find(after));
    int line = 1;
    for (size_t i = 0; i < at && i < text.size(); ++i) line += text[i] == '\n';
    return line;
  }
  void SetUp() override {
    std::string why;
    if (!BrowserAvailable(&why)) GTEST_SKIP() << why;
    ASSERT_NE(browser_, nullptr);
    // A fresh tab state: no token, no draft (cleared on a file of the daemon's origin that runs no
    // script, so no request of a page goes out meanwhile).
    browser_->Navigate(daemon_->url() + "/ui/app.css");
    browser_->Script("sessionStorage.clear();");
    errors_before_ = browser_->ConsoleErrors().size();
  }
  // This test's console errors (see ErrorsSince).
  std::vector<std::string> UnexpectedErrors(Browser& browser, const std::vector<std::string>& expected_statuses = {}) {
    return ErrorsSince(browser, errors_before_, expected_statuses);
  }
  // As a user reaches the dashboard: by the link with ?token= that sandswimd prints, which the page
  // keeps for the tab and takes out of the address at once.
  void Open(const std::string& path) {
    browser_->Navigate(daemon_->url() + path + "?token=" + kDashToken);
    ASSERT_EQ(browser_->Script("return location.search;").get<std::string>(), "") << "the token stayed in the address";
    ASSERT_TRUE(browser_->WaitUntil("document.querySelector('#live-status').classList.contains('live')", 20))
        << "the live stream did not connect: " << browser_->Text("#live-status");
  }
  void Shot(const std::string& name) { browser_->Screenshot(*out_ + "/dashboard-" + name + ".png"); }
  // Puts `text` in the editor's text area as typing would (the page keeps its draft on input).
  void SetEditorText(const std::string& css, const std::string& text) {
    browser_->Script("const a = document.querySelector(arguments[0]); a.value = arguments[1];"
                     "a.dispatchEvent(new Event('input'));",
                     json::array({css, text}));
  }

  size_t errors_before_ = 0;
  static std::string* out_;
  static Daemon* daemon_;
  static ChildProcess* worker_;
  static Browser* browser_;
  static int64_t sweep_id_, campaign_run_id_, campaign_sweep_id_;
};
std::string* DashboardTest::out_ = nullptr;
Daemon* DashboardTest::daemon_ = nullptr;
ChildProcess* DashboardTest::worker_ = nullptr;
Browser* DashboardTest::browser_ = nullptr;
int64_t DashboardTest::sweep_id_ = 0, DashboardTest::campaign_run_id_ = 0, DashboardTest::campaign_sweep_id_ = 0;

// The campaign run's page lists every one of its runs (as many rows as the API counts), filters
// and sorts them, and shows the claims' verdicts.
TEST_F(DashboardTest, CampaignPageListsItsRunsFiltersAndSorts) {
  const json info = daemon_->Get("/api/v1/campaign-runs/" + std::to_string(campaign_run_id_));
  const int total = info["counts"]["queued"].get<int>() + info["counts"]["running"].get<int>() +
                    info["counts"]["done"].get<int>() + info["counts"]["failed"].get<int>();
  ASSERT_EQ(total, 58) << info.dump();
  Open("/campaign-runs/" + std::to_string(campaign_run_id_));
  ASSERT_TRUE(browser_->WaitUntil("document.querySelectorAll('#runs tbody tr').length === 58", 20))
      << browser_->Text("#main");
  ASSERT_TRUE(browser_->WaitUntil("document.querySelectorAll('#claims-table tbody tr').length === 6", 20))
      << browser_->Text("#claims");
  EXPECT_THAT(browser_->Text("#claims-table"), HasSubstr("F1"));
  // Each verdict beside its rule's error rates at this design (paper-58 at smoke, one bed: the
  // committed calibration's), its parts' behind a disclosure.
  EXPECT_THAT(browser_->Text("#claims-table"), HasSubstr("false holds <="));
  EXPECT_THAT(browser_->Text("#claims"), HasSubstr("Error rates at this design: paper-58 at smoke, K = 1 bed"));
  browser_->Script("document.querySelectorAll('#claims details.parts').forEach(d => d.open = true); return 0;");
  EXPECT_THAT(browser_->Text("#claims-table"), HasSubstr("at this design"));
  browser_->Script("document.querySelector('#claims').scrollIntoView(); return 0;");
  Shot("claims");
  // Filter: the Omega sweep's 16 points (the baseline's two are also the Omega sweep's).
  browser_->Type("#runs .table-filter", "Omega-sweep");
  ASSERT_TRUE(browser_->WaitUntil("document.querySelectorAll('#runs tbody tr').length === 16", 5))
      << browser_->Text(".table-count");
  // Sort by Omega, twice: ascending, then descending.
  browser_->Click("#runs th[data-key='Omega']");
  const json ascending = browser_->Script(
      "return [...document.querySelectorAll('#runs tbody td[data-key=Omega]')].map(td => Number(td.textContent));");
  browser_->Click("#runs th[data-key='Omega']");
  const json descending = browser_->Script(
      "return [...document.querySelectorAll('#runs tbody td[data-key=Omega]')].map(td => Number(td.textContent));");
  ASSERT_EQ(ascending.size(), 16u);
  EXPECT_EQ(ascending.front().get<double>(), -1280);
  EXPECT_EQ(ascending.back().get<double>(), 1280);
  EXPECT_EQ(descending.front().get<double>(), 1280);
  browser_->Script("window.scrollTo(0, 0);");
  Shot("campaign");
  EXPECT_THAT(UnexpectedErrors(*browser_), ::testing::IsEmpty());
}

// A running run's page shows its simulated time and z(t) growing, and then its result, without a
// reload (a mark left on the window survives).
TEST_F(DashboardTest, RunningRunProgressesOnScreenWithoutReload) {
  int64_t run_id = 0;
  for (int i = 0; i < 200 && run_id == 0; ++i) {
    const json board = daemon_->Get("/api/v1/live");
    for (const json& r : board["running"]) {
      const double t = r["progress"]["sim_time_s"].get<double>();
      if (t > 0 && t < 0.6 * r["run_duration_s"].get<double>()) {
        run_id = r["id"].get<int64_t>();
      }
    }
    if (run_id == 0) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_NE(run_id, 0) << "no run was seen early in its run";
  Open("/runs/" + std::to_string(run_id));
  browser_->Script("window.__sameDocument = 42;");
  ASSERT_TRUE(browser_->WaitUntil("/ of 1.5 s simulated/.test(document.querySelector('#sim-time').textContent)", 10));
  const std::string first = browser_->Text("#sim-time");
  ASSERT_TRUE(browser_->WaitUntil(
      "document.querySelector('#sim-time').textContent !== " + json(first).dump() + " && !!document.querySelector('#zt-plot canvas')",
      15))
      << first;
  const int points = browser_->Script("return document.querySelector('#zt-plot .u-over') ? 1 : 0;").get<int>();
  EXPECT_EQ(points, 1) << "z(t) is drawn";
  Shot("run-live");
  // The run ends: its result appears in place.
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#result')", 30)) << browser_->Text("#main");
  EXPECT_EQ(browser_->Script("return window.__sameDocument;").get<int>(), 42) << "the page was reloaded";
  EXPECT_THAT(browser_->Text("#run-state"), HasSubstr("done"));
  EXPECT_THAT(browser_->Text("#result"), HasSubstr("U_z"));
  Shot("run-done");
  EXPECT_THAT(UnexpectedErrors(*browser_), ::testing::IsEmpty());
}

// A finished sweep's page draws U_z against Omega (uPlot) and the daemon's own figure renders.
TEST_F(DashboardTest, SweepPageDrawsItsFigures) {
  const json sweep = daemon_->WaitForSweep(sweep_id_, 120);
  ASSERT_EQ(sweep["counts"]["done"], 4) << sweep.dump();
  Open("/sweeps/" + std::to_string(sweep_id_));
  if (!browser_->WaitUntil("document.querySelectorAll('#runs tbody tr').length === 4", 20)) {
    Shot("sweep-failed");
    for (const auto& e : browser_->BrowserLog()) std::printf("LOG %s %s\n", e.level.c_str(), e.message.c_str());
    FAIL() << browser_->Text("#main") << " | " << browser_->Script("return performance.getEntriesByType('resource').map(e => e.name + ' ' + Math.round(e.duration)).join('\\n')").dump();
  }
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#uz-plot canvas')", 20)) << browser_->Text("#uz-plot");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#zt-plot canvas')", 20)) << browser_->Text("#zt-plot");
  ASSERT_TRUE(browser_->WaitUntil(
      "[...document.querySelectorAll('img.figure')].every(i => i.complete && i.naturalWidth > 100)", 60))
      << "the daemon's SVG figures did not load";
  // Hover over the U_z plot: its legend shows a value with its interval.
  browser_->Script(R"(
    const over = document.querySelector('#uz-plot .u-over'), box = over.getBoundingClientRect();
    over.dispatchEvent(new MouseEvent('mousemove', {clientX: box.left + 2, clientY: box.top + box.height / 2, bubbles: true}));)");
  ASSERT_TRUE(browser_->WaitUntil("/±/.test(document.querySelector('#uz-plot .u-legend').textContent)", 5))
      << browser_->Text("#uz-plot");
  Shot("sweep");
  EXPECT_THAT(UnexpectedErrors(*browser_), ::testing::IsEmpty());
}

// A sweep over a material: its runs table has the material's column, with its unit, and the point
// at Table 1's value shows that value (the row does not carry it).
TEST_F(DashboardTest, AMaterialSweepShowsItsColumnWithTable1sValue) {
  int status = 0;
  json sweep = OmegaSweep("dash-density", {-80}, 1.5);
  sweep["axes"] = json::array({{{"param", "so_density"}, {"values", {2500, 5000}}}});
  const json made = daemon_->Post("/api/v1/sweeps", sweep, &status);
  ASSERT_EQ(status, 201) << made.dump();
  Open("/sweeps/" + std::to_string(made["id"].get<int64_t>()));
  ASSERT_TRUE(browser_->WaitUntil("document.querySelectorAll('#runs tbody tr').length === 2", 20)) << browser_->Text("#main");
  const std::string header = browser_->Text("#runs thead");
  EXPECT_THAT(header, HasSubstr("so_density (kg/m^3)"));
  const json cells = browser_->Script(
      "const i = [...document.querySelectorAll('#runs thead th')].findIndex(th => th.textContent.includes('so_density'));"
      "return [...document.querySelectorAll('#runs tbody tr')].map(tr => tr.children[i].textContent.trim()).sort();");
  EXPECT_EQ(cells, json::array({"2500", "5000"})) << cells.dump();
  Shot("material-sweep");
  EXPECT_THAT(UnexpectedErrors(*browser_), ::testing::IsEmpty());
}

// A bad sweep: the daemon's problem+json names the field, and the editor shows the reason next to
// that field's line. Nothing is stored.
TEST_F(DashboardTest, BadSweepShowsTheFieldErrorNextToTheField) {
  const std::string before = daemon_->Query("SELECT count(*) FROM sweeps");
  Open("/submit");
  EXPECT_EQ(browser_->Property("#token", "value"), kDashToken) << "the link's token is the tab's";
  json bad = OmegaSweep("bad", {-80, 80}, 0.5);
  bad["base"]["A"] = -0.03;
  const std::string text = bad.dump(2);
  browser_->Script("const a = document.querySelector('#sweep-json'); a.value = arguments[0];"
                   "a.dispatchEvent(new Event('input'));",
                   json::array({text}));
  browser_->Click("#submit");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('.field-error')", 10))
      << browser_->Text("#main") << "\nresult: " << browser_->Text("#submit-result") << "\nlog: " << browser_->BrowserLog().size();
  EXPECT_EQ(browser_->Attribute(".field-error", "data-field"), "base.A");
  // The line of "A" inside "base" in the text as sent.
  int line = 1;
  const size_t at = text.find("\"A\"", text.find("\"base\""));
  for (size_t i = 0; i < at; ++i) line += text[i] == '\n';
  EXPECT_EQ(browser_->Attribute(".field-error", "data-line"), std::to_string(line));
  EXPECT_THAT(browser_->Text(".field-error"), HasSubstr("base.A"));
  EXPECT_THAT(browser_->Text("#sweep-editor .gutter .bad"), HasSubstr(std::to_string(line)));
  Shot("submit-error");
  // Text that is not JSON (a '}' closing an array): the daemon's reason, and the page stays alive.
  browser_->Script("const a = document.querySelector('#sweep-json'); a.value = arguments[0];"
                   "a.dispatchEvent(new Event('input'));",
                   json::array({"{\"name\": \"x\", \"axes\": [1}"}));
  browser_->Click("#submit");
  ASSERT_TRUE(browser_->WaitUntil("/malformed JSON/.test(document.querySelector('#sweep-editor .editor-errors').textContent)", 10))
      << browser_->Text("#sweep-editor .editor-errors");
  EXPECT_EQ(browser_->Script("return 6 * 7;").get<int>(), 42) << "the page answers";
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM sweeps"), before) << "nothing stored";
  EXPECT_THAT(UnexpectedErrors(*browser_, {"400"}), ::testing::IsEmpty());
}

// Cancel with a wrong token: refused with the daemon's reason on screen, and nothing changes.
TEST_F(DashboardTest, CancelWithAWrongTokenIsRefusedAndChangesNothing) {
  const std::string path = "/api/v1/sweeps/" + std::to_string(campaign_sweep_id_);
  Open("/sweeps/" + std::to_string(campaign_sweep_id_));
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#cancel')", 20));
  browser_->Script("sessionStorage.setItem('sandswim-token', 'ffffffffffffffffffffffffffffffff');");
  browser_->Click("#cancel");
  ASSERT_TRUE(browser_->WaitUntil("!document.querySelector('#action-message').hidden", 10));
  EXPECT_THAT(browser_->Text("#action-message"), HasSubstr("401"));
  EXPECT_THAT(browser_->Text("#action-message"), HasSubstr("token"));
  Shot("cancel-refused");
  const json after = daemon_->Get(path);
  EXPECT_EQ(after["cancelled"], false) << after.dump();
  EXPECT_EQ(daemon_->Query("SELECT count(*) FROM runs WHERE state = 'cancelled'"), "0");
  EXPECT_THAT(UnexpectedErrors(*browser_, {"401"}), ::testing::IsEmpty());
}

// The overview lists the campaign run and the sweeps with their progress (the README's picture).
TEST_F(DashboardTest, OverviewShowsProgress) {
  ASSERT_EQ(daemon_->WaitForSweep(sweep_id_, 120)["counts"]["done"], 4);
  Open("/");
  ASSERT_TRUE(browser_->WaitUntil("document.querySelectorAll('#campaign-runs tbody tr').length >= 1", 20));
  // Every sweep the daemon holds (paper-58's ten, dash-omega, and those other tests submitted).
  const size_t sweeps = daemon_->Get("/api/v1/sweeps")["sweeps"].size();
  ASSERT_GE(sweeps, 11u);
  ASSERT_TRUE(browser_->WaitUntil(
      "document.querySelectorAll('#sweeps tbody tr').length === " + std::to_string(sweeps), 20))
      << browser_->Text("#sweeps");
  EXPECT_THAT(browser_->Text("#campaign-runs"), HasSubstr("paper-58"));
  EXPECT_THAT(browser_->Text("#sweeps"), HasSubstr("4 done · 0 running · 0 queued")) << "dash-omega has finished";
  Shot("overview");
  EXPECT_THAT(UnexpectedErrors(*browser_), ::testing::IsEmpty());
}

// A campaign of one's own, written in the editor. The daemon's refusal names a field of
// the definition (sweeps[1].axes[0].values), shown beside that line, and nothing is stored; fixed,
// it is saved as version 1, its page shows it, a bad cron is refused beside the schedule, and
// "Run now" starts a campaign run of that version.
TEST_F(DashboardTest, CampaignEditorShowsTheFieldErrorBesideItsLineThenSavesAndRuns) {
  const size_t campaigns_before = daemon_->Get("/api/v1/campaigns")["campaigns"].size();
  Open("/new-campaign");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-json')", 20)) << browser_->Text("#main");
  json mine = {{"name", "dash-mine"},
               {"extends", "paper-58"},
               {"sweeps", json::array({"baseline",
                                       {{"name", "slow-Omega"},
                                        {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", 3}, {"Omega", -40}, {"duration_s", 1.5}}},
                                        {"axes", json::array({{{"param", "Omega"}, {"values", json::array()}}})}}})}};
  std::string text = mine.dump(2);
  SetEditorText("#campaign-json", text);
  browser_->Click("#save");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-editor .field-error')", 10))
      << browser_->Text("#main");
  EXPECT_EQ(browser_->Attribute(".field-error", "data-field"), "sweeps[1].axes[0].values");
  // dump() sorts the keys: sweeps[1]'s "axes" (and its "values") come first after "baseline".
  const int line = LineOf(text, "\"values\"", "\"baseline\"");
  EXPECT_EQ(browser_->Attribute(".field-error", "data-line"), std::to_string(line));
  EXPECT_THAT(browser_->Text("#campaign-editor .gutter .bad"), HasSubstr(std::to_string(line)));
  EXPECT_THAT(browser_->Text(".field-error"), HasSubstr("at least one"));
  Shot("campaign-editor-error");
  int status = 0;
  daemon_->Get("/api/v1/campaigns/dash-mine", &status);
  EXPECT_EQ(status, 404) << "a refused campaign is not stored";
  EXPECT_EQ(daemon_->Get("/api/v1/campaigns")["campaigns"].size(), campaigns_before) << "nothing stored";

  // Fixed: saved, and the page goes to the campaign's own page.
  mine["sweeps"][1]["axes"][0]["values"] = {-40, 40};
  text = mine.dump(2);
  SetEditorText("#campaign-json", text);
  browser_->Click("#save");
  ASSERT_TRUE(browser_->WaitUntil("location.pathname === '/campaigns/dash-mine' && !!document.querySelector('#definition')", 20))
      << browser_->Text("#main") << browser_->Text("#action-message");
  EXPECT_THAT(browser_->Text("#action-message"), HasSubstr("Created campaign dash-mine, version 1"));
  EXPECT_THAT(browser_->Text("h1"), HasSubstr("version 1"));
  EXPECT_THAT(browser_->Text("#definition"), HasSubstr("slow-Omega"));
  EXPECT_TRUE(browser_->Exists("#edit"));
  EXPECT_FALSE(browser_->Exists("#make-copy")) << "one's own campaign is edited, not copied";

  // The schedule: a cron that is not one is refused beside it; a good one is stored and shown.
  SetEditorText("#cron", "61 2 * * *");
  browser_->Click("#schedule-set");
  ASSERT_TRUE(browser_->WaitUntil("document.querySelector('#schedule-error').textContent.length > 0", 10));
  EXPECT_THAT(browser_->Text("#schedule-error"), HasSubstr("422"));
  EXPECT_TRUE(browser_->Exists("#cron.bad-input"));
  EXPECT_EQ(daemon_->Get("/api/v1/campaigns/dash-mine")["schedule"], nullptr) << "a refused schedule is not stored";
  SetEditorText("#cron", "0 3 * * *");
  browser_->Click("#schedule-set");
  ASSERT_TRUE(browser_->WaitUntil("/0 3 \\* \\* \\*/.test(document.querySelector('#schedule-now').textContent)", 10))
      << browser_->Text("#schedule-error");
  EXPECT_EQ(daemon_->Get("/api/v1/campaigns/dash-mine")["schedule"]["cron"], "0 3 * * *");
  Shot("campaign-page");

  // Run now, at smoke: a campaign run of version 1, whose page opens.
  browser_->Script("document.querySelector('#run-scale').value = 'smoke'; return 0;");
  browser_->Click("#run-now");
  ASSERT_TRUE(browser_->WaitUntil("/^\\/campaign-runs\\/\\d+$/.test(location.pathname)", 20)) << browser_->Text("#action-message");
  const std::string path = browser_->Script("return location.pathname;").get<std::string>();
  const json run = daemon_->Get("/api/v1" + path);
  EXPECT_EQ(run["campaign"], "dash-mine") << run.dump();
  EXPECT_EQ(run["campaign_version"], 1) << run.dump();
  EXPECT_EQ(run["scale"], "smoke") << run.dump();
  // The campaign's page lists it, linked to its page.
  Open("/campaigns/dash-mine");
  const std::string id = path.substr(path.rfind('/') + 1);
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-runs-of a[href=\"" + path + "\"]')", 20))
      << browser_->Text("#campaign-runs-of");
  // The list of campaigns shows it beside paper-58, with its version, base and schedule.
  Open("/campaigns");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-list tr[data-id=\"dash-mine\"] a[href^=\"/campaign-runs/\"]')", 20))
      << browser_->Text("#campaign-list");
  const std::string row = browser_->Text("#campaign-list tr[data-id='dash-mine']");
  EXPECT_THAT(row, HasSubstr("paper-58"));
  EXPECT_THAT(row, HasSubstr("0 3 * * *"));
  EXPECT_THAT(row, HasSubstr(id));
  EXPECT_THAT(browser_->Text("#campaign-list tr[data-id='paper-58']"), HasSubstr("built-in"));
  Shot("campaigns");
  EXPECT_THAT(UnexpectedErrors(*browser_, {"404", "422"}), ::testing::IsEmpty());
}

// A built-in campaign is read-only: its page and the overview's text ("edit or remove it in your
// own copy of this campaign") open the editor with a copy, {"name": ..., "extends": "paper-58"},
// which saves as a campaign of one's own.
TEST_F(DashboardTest, BuiltInCampaignOffersMakeMyOwnCopy) {
  Open("/");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaigns a.own-copy')", 20)) << browser_->Text("#campaigns");
  browser_->Click("#campaigns a.own-copy");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-json')", 20)) << browser_->Text("#main");
  EXPECT_EQ(browser_->Script("return location.pathname + location.search;").get<std::string>(), "/new-campaign?from=paper-58");
  Open("/campaigns/paper-58");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#make-copy')", 20)) << browser_->Text("#main");
  EXPECT_FALSE(browser_->Exists("#edit"));
  EXPECT_FALSE(browser_->Exists("#delete"));
  EXPECT_THAT(browser_->Text("h1"), HasSubstr("built-in"));
  Shot("campaign-builtin");
  browser_->Click("#make-copy");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-json')", 20)) << browser_->Text("#main");
  const json prefilled = json::parse(browser_->Property("#campaign-json", "value").get<std::string>());
  EXPECT_EQ(prefilled, (json{{"name", "my-paper-58"}, {"extends", "paper-58"}}));
  EXPECT_THAT(browser_->Text("#base-sweeps"), HasSubstr("Omega-sweep")) << "the base's sweeps, to pick from";
  Shot("campaign-copy");
  // Saved under the built-in's own name: refused (409), the name's line marked, nothing changed.
  SetEditorText("#campaign-json", json({{"name", "paper-58"}, {"extends", "paper-58"}, {"replicates", 3}}).dump(2));
  browser_->Click("#save");
  ASSERT_TRUE(browser_->WaitUntil("!!document.querySelector('#campaign-editor .field-error')", 10)) << browser_->Text("#main");
  EXPECT_EQ(browser_->Attribute(".field-error", "data-field"), "name");
  EXPECT_THAT(browser_->Text("#campaign-editor .editor-errors"), HasSubstr("409"));
  EXPECT_EQ(daemon_->Get("/api/v1/campaigns/paper-58")["builtin"], true);
  SetEditorText("#campaign-json", prefilled.dump(2));
  browser_->Click("#save");
  ASSERT_TRUE(browser_->WaitUntil("location.pathname === '/campaigns/my-paper-58' && !!document.querySelector('#definition')", 20))
      << browser_->Text("#main") << browser_->Text("#action-message");
  const json copy = daemon_->Get("/api/v1/campaigns/my-paper-58");
  EXPECT_EQ(copy["builtin"], false);
  EXPECT_EQ(copy["extends"], "paper-58");
  EXPECT_EQ(copy["version"], 1);
  EXPECT_EQ(copy["resolved"]["sweeps"].size(), daemon_->Get("/api/v1/campaigns/paper-58")["resolved"]["sweeps"].size());
  EXPECT_THAT(UnexpectedErrors(*browser_, {"409"}), ::testing::IsEmpty());
}

}  // namespace
}  // namespace sandswim::testing
