// A web page of another origin, in a real headless Chromium, tries every write an attacker's page
// can make without JavaScript's help or with it -- fetch in no-cors mode with a text/plain body, an
// HTML form (urlencoded), a form with enctype="text/plain" (whose body is JSON), a forced rerun of
// the campaign, a cancel, a stolen lease, a CORS request with application/json, and the old
// GET /api/v1/backup as an image -- against a real sandswimd started with --no-token (the worst
// case: nothing but the request policy stands in the way). The page is served by a tiny HTTP
// server of the test's own, once on 127.0.0.2 (another site) and once on another port of
// 127.0.0.1 (the same site, another origin). Afterwards the database is exactly as it was, and the
// daemon counted every attempt that reached it as refused (403).
#include <chrono>
#include <filesystem>
#include <memory>
#include <regex>
#include <string>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "tests/browser/webdriver.h"
#include "tests/service_fixture.h"

namespace sandswim::testing {
namespace {

using nlohmann::json;

// The attacker's page: three forms posting into frames, and a script making the rest of the
// attempts; window.results says how each fetch ended as the page saw it.
std::string AttackPage(const std::string& daemon, int64_t sweep_id) {
  const json sweep = OmegaSweep("planted", {-80, 80}, 0.5);
  std::string fields = sweep.dump();
  fields.pop_back();  // {..."axes":[...], then "x":"<name>=<value>"}: the text/plain form's JSON
  const std::string form_name = fields + ",\"x\":\"";
  auto attr = [](std::string s) {
    std::string out;
    for (char ch : s) out += ch == '\'' ? std::string("&#39;") : ch == '&' ? std::string("&amp;") : std::string(1, ch);
    return out;
  };
  const std::string cancel = daemon + "/api/v1/sweeps/" + std::to_string(sweep_id) + "/cancel";
  return "<!doctype html><html><head><meta charset='utf-8'><title>a page of another site</title></head><body>"
         "<iframe name='sink1'></iframe><iframe name='sink2'></iframe><iframe name='sink3'></iframe>"
         "<form id='urlencoded' method='POST' target='sink1' action='" +
         daemon +
         "/api/v1/sweeps'>"
         "<input name='" +
         attr(form_name) +
         "' value='\"}'></form>"
         "<form id='textplain' method='POST' enctype='text/plain' target='sink2' action='" +
         daemon +
         "/api/v1/sweeps'>"
         "<input name='" +
         attr(form_name) +
         "' value='\"}'></form>"
         "<form id='cancelform' method='POST' target='sink3' action='" +
         cancel +
         "'></form>"
         "<script>\n"
         "window.results = {};\n"
         "const D = " +
         json(daemon).dump() +
         ";\n"
         "async function attempt(name, p) {\n"
         "  try { const r = await p; window.results[name] = r.type + ':' + r.status; }\n"
         "  catch (e) { window.results[name] = 'error'; }\n"
         "}\n"
         "const plain = body => ({ method: 'POST', mode: 'no-cors', headers: { 'Content-Type': 'text/plain' }, body "
         "});\n"
         "attempt('sweep', fetch(D + '/api/v1/sweeps', plain(" +
         json(sweep.dump()).dump() +
         ")));\n"
         "attempt('rerun', fetch(D + '/api/v1/sweeps', plain(JSON.stringify({campaign: 'paper-58', scale: 'mini', "
         "force: true}))));\n"
         "attempt('cancel', fetch(" +
         json(cancel).dump() +
         ", plain('{}')));\n"
         "attempt('lease', fetch(D + '/api/v1/leases', plain(JSON.stringify({worker: 'thief', host: 'thief', slots: "
         "1}))));\n"
         "attempt('cors-json', fetch(D + '/api/v1/sweeps', { method: 'POST', headers: { 'Content-Type': "
         "'application/json' },"
         " body: " +
         json(sweep.dump()).dump() +
         " }));\n"
         "const img = new Image(); img.src = D + '/api/v1/backup';\n"
         "document.getElementById('urlencoded').submit();\n"
         "document.getElementById('textplain').submit();\n"
         "document.getElementById('cancelform').submit();\n"
         "</script></body></html>";
}

// A tiny HTTP server of the test's own on `host`, serving `page` at /.
class AttackerServer {
 public:
  AttackerServer(const std::string& host, std::string page) : page_(std::move(page)) {
    server_.Get("/", [this](const httplib::Request&, httplib::Response& res) { res.set_content(page_, "text/html"); });
    server_.Get("/favicon.ico", [](const httplib::Request&, httplib::Response& res) { res.status = 204; });
    port_ = server_.bind_to_any_port(host);
    if (port_ <= 0) throw std::runtime_error("cannot bind " + host);
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    url_ = "http://" + host + ":" + std::to_string(port_) + "/";
  }
  ~AttackerServer() {
    for (int i = 0; i < 5000 && !server_.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    server_.stop();
    thread_.join();
  }
  const std::string& url() const { return url_; }

 private:
  std::string page_;
  httplib::Server server_;
  int port_ = 0;
  std::string url_;
  std::thread thread_;
};

// The count of answers with `code` in the daemon's /metrics.
int64_t Answered(Daemon& daemon, int code) {
  const std::string metrics = daemon.GetText("/metrics");
  std::smatch m;
  const std::regex re("sandswim_http_requests_total\\{code=\"" + std::to_string(code) + "\"\\} ([0-9]+)");
  return std::regex_search(metrics, m, re) ? std::stoll(m[1]) : 0;
}

TEST(CrossSiteTest, APageOfAnotherOriginChangesNothing) {
  std::string why;
  if (!BrowserAvailable(&why)) GTEST_SKIP() << why;
  const std::string out = SANDSWIM_BROWSER_TEST_DIR;
  const std::string dir = out + "/cross-site";
  std::filesystem::remove_all(dir);
  Daemon daemon(dir + "/daemon");  // --no-token: see service_fixture.h
  int status = 0;
  const json sweep = daemon.Post("/api/v1/sweeps", OmegaSweep("victim", {-80, 80}, 0.5), &status);
  ASSERT_EQ(status, 201) << sweep.dump();
  const int64_t sweep_id = sweep["id"].get<int64_t>();
  const char* kState =
      "SELECT (SELECT count(*) FROM sweeps) || '/' || (SELECT count(*) FROM runs) || '/' || "
      "(SELECT count(*) FROM campaign_runs) || '/' || (SELECT count(*) FROM submissions) || '/' || "
      "(SELECT count(*) FROM runs WHERE state <> 'queued') || '/' || (SELECT count(*) FROM beds WHERE state <> "
      "'queued')";
  const std::string before = daemon.Query(kState);
  const int64_t refused_before = Answered(daemon, 403);

  Browser browser(out);
  AttackerServer other_site("127.0.0.2", AttackPage(daemon.url(), sweep_id));
  AttackerServer other_port("127.0.0.1", AttackPage(daemon.url(), sweep_id));
  int64_t expected = refused_before;
  for (const AttackerServer* page : {&other_site, &other_port}) {
    browser.Navigate(page->url());
    ASSERT_TRUE(browser.WaitUntil("Object.keys(window.results || {}).length === 5", 30))
        << browser.Script("return JSON.stringify(window.results);").dump();
    const json results = browser.Script("return window.results;");
    // The no-cors attempts reached the daemon (their answers are opaque to the page); the CORS
    // one never did: the preflight was not approved.
    for (const char* name : {"sweep", "rerun", "cancel", "lease"}) EXPECT_EQ(results[name], "opaque:0") << name;
    EXPECT_EQ(results["cors-json"], "error");
    // Four fetches and three forms, each refused as coming from another site.
    expected += 7;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (Answered(daemon, 403) < expected && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_EQ(Answered(daemon, 403), expected) << "from " << page->url();
  }
  EXPECT_EQ(daemon.Query(kState), before) << "sweeps/runs/campaign runs/submissions/runs not queued/beds not queued";
  EXPECT_EQ(daemon.Query("SELECT cancelled_at IS NULL FROM sweeps WHERE id = " + std::to_string(sweep_id)), "1");
  EXPECT_EQ(daemon.Query("SELECT count(*) FROM sweeps WHERE name = 'planted'"), "0");
  // The old backup route is no route: nothing was copied.
  const std::string backups = dir + "/daemon/data/backups";
  EXPECT_TRUE(!std::filesystem::exists(backups) || std::filesystem::is_empty(backups));
  EXPECT_THAT(daemon.process().Output(), ::testing::HasSubstr("the request comes from a web page of another origin"));
}

}  // namespace
}  // namespace sandswim::testing
