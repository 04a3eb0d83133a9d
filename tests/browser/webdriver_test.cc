// The WebDriver client (webdriver.h) against a real headless Chromium, on pages served here.
#include "tests/browser/webdriver.h"

#include <dirent.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

namespace sandswim::testing {
namespace {

namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::Contains;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;
using ::testing::SizeIs;

const char kWdTestPage[] = R"(<!doctype html>
<html><head><title>webdriver test</title><link rel="icon" href="data:,"></head>
<body>
<h1 id="title">Hello,
   sandswim</h1>
<p id="hidden" style="display: none">secret</p>
<button id="button">Press</button>
<p id="status">idle</p>
<input id="name" value="">
<p id="echo"></p>
<ul><li class="item">a</li><li class="item">b</li><li class="item">c</li></ul>
<p id="later">before</p>
<script>
  let clicks = 0;
  document.getElementById('button').addEventListener('click', () => {
    document.getElementById('status').textContent = 'clicked ' + (++clicks);
  });
  document.getElementById('name').addEventListener('input', (e) => {
    document.getElementById('echo').textContent = e.target.value;
  });
</script>
</body></html>
)";

const char kWdConsolePage[] = R"(<!doctype html>
<html><head><link rel="icon" href="data:,"></head>
<body><p>console</p>
<script>console.error("boom"); console.log("quiet");</script>
</body></html>
)";

std::string WdTestOutputDir() { return SANDSWIM_BROWSER_TEST_DIR; }

double WdTestSecondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Processes (other than this one) whose command line contains `needle`.
std::vector<int> WdProcessesWith(const std::string& needle) {
  std::vector<int> pids;
  for (const auto& entry : fs::directory_iterator("/proc")) {
    const std::string name = entry.path().filename().string();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    const int pid = std::stoi(name);
    if (pid == ::getpid()) continue;
    std::ifstream in(entry.path() / "cmdline", std::ios::binary);
    std::ostringstream text;
    text << in.rdbuf();
    std::string cmdline = text.str();
    for (char& c : cmdline) {
      if (c == '\0') c = ' ';
    }
    if (cmdline.find(needle) != std::string::npos) pids.push_back(pid);
  }
  return pids;
}

// Polls until no process's command line contains `needle`; false after `timeout_s`.
bool WdProcessesGone(const std::string& needle, double timeout_s) {
  const auto start = std::chrono::steady_clock::now();
  while (!WdProcessesWith(needle).empty()) {
    if (WdTestSecondsSince(start) > timeout_s) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return true;
}

class WebDriverTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string why;
    if (!BrowserAvailable(&why)) GTEST_SKIP() << why;
    server_.Get("/",
                [](const httplib::Request&, httplib::Response& res) { res.set_content(kWdTestPage, "text/html"); });
    server_.Get("/console",
                [](const httplib::Request&, httplib::Response& res) { res.set_content(kWdConsolePage, "text/html"); });
    const int port = server_.bind_to_any_port("127.0.0.1");
    ASSERT_GT(port, 0);
    server_thread_ = std::thread([this] { server_.listen_after_bind(); });
    base_ = "http://127.0.0.1:" + std::to_string(port);
    browser_ = std::make_unique<Browser>(WdTestOutputDir());
  }

  void TearDown() override {
    if (browser_) {
      const std::string log = browser_->log_path();
      browser_.reset();
      if (!HasFailure()) fs::remove(log);  // kept for failed tests only
    }
    server_.stop();
    if (server_thread_.joinable()) server_thread_.join();
  }

  httplib::Server server_;
  std::thread server_thread_;
  std::string base_;
  std::unique_ptr<Browser> browser_;
};

TEST_F(WebDriverTest, NavigatesAndReadsText) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  EXPECT_EQ(b.Url(), base_ + "/");
  EXPECT_EQ(b.Text("#title"), "Hello, sandswim");  // rendered: whitespace collapsed
  EXPECT_EQ(b.Text("#hidden"), "");                // not rendered
  EXPECT_TRUE(b.Exists("#title"));
  EXPECT_FALSE(b.Exists("#nope"));
  EXPECT_THAT(b.FindAll("li.item"), SizeIs(3));
  EXPECT_THAT(b.FindAll(".nope"), IsEmpty());
  EXPECT_EQ(b.Find("li.item"), b.FindAll("li.item")[0]);
  EXPECT_EQ(b.Attribute("#name", "id"), "name");
  EXPECT_EQ(b.Attribute("#title", "data-none"), "");
  try {
    b.Find("#nope");
    ADD_FAILURE() << "Find(\"#nope\") did not throw";
  } catch (const WebDriverError& e) {
    EXPECT_EQ(e.error(), "no such element");
    EXPECT_THAT(e.what(), HasSubstr("#nope"));
  }
  try {
    b.Click("#nope");
    ADD_FAILURE() << "Click(\"#nope\") did not throw";
  } catch (const WebDriverError& e) {
    EXPECT_EQ(e.error(), "no such element");
    EXPECT_THAT(e.what(), HasSubstr("Click(\"#nope\")"));
  }
}

TEST_F(WebDriverTest, ClickRunsTheButtonsHandler) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  EXPECT_EQ(b.Text("#status"), "idle");
  b.Click("#button");
  EXPECT_EQ(b.Text("#status"), "clicked 1");
  b.Click("#button");
  EXPECT_EQ(b.Text("#status"), "clicked 2");
}

TEST_F(WebDriverTest, TypeSendsKeysToAnInput) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  b.Type("#name", "sand");
  b.Type("#name", "swim 2");  // appended
  EXPECT_EQ(b.Script("return document.getElementById('name').value;"), "sandswim 2");
  EXPECT_EQ(b.Property("#name", "value"), "sandswim 2");
  EXPECT_EQ(b.Attribute("#name", "value"), "");  // the markup's
  EXPECT_EQ(b.Property("#name", "disabled"), false);
  EXPECT_TRUE(b.Property("#name", "noSuchProperty").is_null());
  EXPECT_EQ(b.Text("#echo"), "sandswim 2");  // each key fired an input event
  b.Clear("#name");
  EXPECT_EQ(b.Script("return document.getElementById('name').value;"), "");
  b.Type("#name", "again");
  EXPECT_EQ(b.Text("#echo"), "again");
}

TEST_F(WebDriverTest, ScriptReturnsValues) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  EXPECT_EQ(b.Script("return 1 + 2;"), 3);
  EXPECT_EQ(b.Script("return arguments[0] * arguments[1];", {6, 7}), 42);
  EXPECT_EQ(b.Script("return arguments[0].length;", "four"), 4);  // one argument given bare
  EXPECT_EQ(b.Script("return document.title;"), "webdriver test");
  EXPECT_EQ(b.Script("return {a: [1, 'x', null], b: true};"), nlohmann::json::parse(R"({"a":[1,"x",null],"b":true})"));
  EXPECT_TRUE(b.Script("document.title = 'changed';").is_null());  // no return: null
  EXPECT_EQ(b.Script("return document.title;"), "changed");
  try {
    b.Script("throw new Error('kaput');");
    ADD_FAILURE() << "a throwing script did not throw";
  } catch (const WebDriverError& e) {
    EXPECT_EQ(e.error(), "javascript error");
    EXPECT_THAT(e.what(), HasSubstr("kaput"));
  }
}

TEST_F(WebDriverTest, WaitUntilSeesALaterChange) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  const auto start = std::chrono::steady_clock::now();
  b.Script("setTimeout(() => { document.getElementById('later').textContent = 'after'; }, 300);");
  EXPECT_EQ(b.Text("#later"), "before");
  EXPECT_TRUE(b.WaitUntil("document.getElementById('later').textContent === 'after'", 10));
  const double waited = WdTestSecondsSince(start);
  EXPECT_GE(waited, 0.3);
  EXPECT_LT(waited, 5);
  EXPECT_EQ(b.Text("#later"), "after");

  // An expression that throws until the element it reads exists (300 ms later) counts as falsy.
  b.Script(
      "setTimeout(() => { const p = document.createElement('p'); p.id = 'late'; p.textContent = 'here';"
      " document.body.appendChild(p); }, 300);");
  EXPECT_TRUE(b.WaitUntil("document.querySelector('#late').textContent === 'here'", 10));
}

TEST_F(WebDriverTest, WaitUntilReturnsFalseOnTimeout) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  auto start = std::chrono::steady_clock::now();
  EXPECT_FALSE(b.WaitUntil("document.title === 'never'", 0.5));
  double waited = WdTestSecondsSince(start);
  EXPECT_GE(waited, 0.5);
  EXPECT_LT(waited, 5);
  EXPECT_FALSE(b.WaitUntil("false", 0));  // evaluated once

  // Still throwing at the timeout: the error, not false.
  start = std::chrono::steady_clock::now();
  try {
    b.WaitUntil("document.querySelector('#never').textContent === 'x'", 0.3);
    ADD_FAILURE() << "WaitUntil on an expression that always throws did not throw";
  } catch (const WebDriverError& e) {
    EXPECT_EQ(e.error(), "javascript error");
    EXPECT_THAT(e.what(), AllOf(HasSubstr("WaitUntil"), HasSubstr("#never")));
  }
  waited = WdTestSecondsSince(start);
  EXPECT_GE(waited, 0.3);
}

TEST_F(WebDriverTest, ConsoleErrorsHoldConsoleErrorButNotConsoleLog) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  EXPECT_THAT(b.ConsoleErrors(), IsEmpty());

  b.Navigate(base_ + "/console");
  const auto errors = b.ConsoleErrors();
  ASSERT_THAT(errors, SizeIs(1));
  EXPECT_THAT(errors[0], HasSubstr("\"boom\""));
  EXPECT_THAT(errors[0], HasSubstr(base_ + "/console"));  // where it was logged
  EXPECT_THAT(errors, Not(Contains(HasSubstr("quiet"))));

  // console.log is in the log, as INFO; the log keeps what was read before.
  const auto log = b.BrowserLog();
  bool quiet_seen = false;
  for (const auto& entry : log) {
    if (entry.message.find("quiet") != std::string::npos) {
      quiet_seen = true;
      EXPECT_EQ(entry.level, "INFO");
    }
  }
  EXPECT_TRUE(quiet_seen);
  EXPECT_THAT(b.ConsoleErrors(), SizeIs(1));

  b.Script("console.error('later ' + 6 * 7);");
  EXPECT_THAT(b.ConsoleErrors(), AllOf(SizeIs(2), Contains(HasSubstr("later 42"))));
}

TEST_F(WebDriverTest, ScreenshotWritesAPng) {
  Browser& b = *browser_;
  b.Navigate(base_ + "/");
  const std::string path = WdTestOutputDir() + "/screenshots/webdriver_test.png";
  fs::remove(path);
  b.Screenshot(path);
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  const std::string png = text.str();
  ASSERT_GT(png.size(), 1000u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  // IHDR: width and height, big-endian, at bytes 16 and 20. The viewport is the window's width.
  auto be32 = [&](size_t at) {
    return (static_cast<unsigned char>(png[at]) << 24) | (static_cast<unsigned char>(png[at + 1]) << 16) |
           (static_cast<unsigned char>(png[at + 2]) << 8) | static_cast<unsigned char>(png[at + 3]);
  };
  EXPECT_EQ(png.substr(12, 4), "IHDR");
  EXPECT_EQ(be32(16), 1280);
  EXPECT_GT(be32(20), 500);
}

// The Browser's processes, by their command lines: chromedriver's names its port, Chromium's its
// profile. Two at once: the second one's guard must not hold the first one's control pipe open.
TEST(BrowserProcessTest, DestructorEndsChromedriverAndChromium) {
  std::string why;
  if (!BrowserAvailable(&why)) GTEST_SKIP() << why;
  Browser other(WdTestOutputDir());
  std::string driver_arg, profile;
  auto b = std::make_unique<Browser>(WdTestOutputDir());
  driver_arg = "--port=" + std::to_string(b->port());
  profile = b->profile_dir();
  EXPECT_THAT(WdProcessesWith(driver_arg), SizeIs(1));
  EXPECT_THAT(WdProcessesWith(profile), Not(IsEmpty()));
  EXPECT_TRUE(fs::is_directory(profile));
  const auto start = std::chrono::steady_clock::now();
  b.reset();
  // Promptly (about 0.3 s): the guard ended the group, not our fallback SIGKILL after 10 s.
  EXPECT_LT(WdTestSecondsSince(start), 5);
  // Ended by the time the destructor returns (SIGKILL waits for nothing, /proc may lag a moment).
  EXPECT_TRUE(WdProcessesGone(driver_arg, 2));
  EXPECT_TRUE(WdProcessesGone(profile, 2)) << WdProcessesWith(profile).size() << " Chromium processes left";
  EXPECT_FALSE(fs::exists(profile));
  // The other one still works.
  EXPECT_THAT(WdProcessesWith(other.profile_dir()), Not(IsEmpty()));
  other.Navigate("data:text/html,<p id=p>still here</p>");
  EXPECT_EQ(other.Text("#p"), "still here");
}

TEST(BrowserProcessTest, ProcessesEndWhenTheTestProcessDies) {
  std::string why;
  if (!BrowserAvailable(&why)) GTEST_SKIP() << why;
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const std::string note = WdTestOutputDir() + "/killed_browser_profile.txt";
  fs::remove(note);
  // The child opens a browser, writes down its profile and dies by SIGKILL: no destructor runs.
  EXPECT_EXIT(
      {
        Browser b(WdTestOutputDir());
        b.Navigate("about:blank");
        std::ofstream(note) << b.profile_dir();
        ::raise(SIGKILL);
      },
      ::testing::KilledBySignal(SIGKILL), "");
  std::ifstream in(note);
  std::string profile;
  ASSERT_TRUE(std::getline(in, profile)) << "the child wrote no profile to " << note;
  ASSERT_FALSE(profile.empty());
  EXPECT_TRUE(WdProcessesGone(profile, 10)) << WdProcessesWith(profile).size() << " Chromium processes left";
  fs::remove_all(profile);  // nobody else removes it
}

}  // namespace
}  // namespace sandswim::testing
