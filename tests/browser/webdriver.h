// Test support: a small W3C WebDriver client that drives headless Chromium through chromedriver.
//
// A Browser starts /usr/bin/chromedriver on a free loopback port, in a process group of its own
// under a small guard process, and opens one session in a headless /usr/bin/chromium with a fresh
// profile. The guard ends the whole group (chromedriver and every Chromium process; SIGTERM, then
// SIGKILL) when the Browser is destroyed, and also when the test process dies without destroying
// it (a crash, or ctest's timeout), so no browser outlives its test. chromedriver's output, each
// command and reply included, goes to `<log_dir>/chromedriver-<port>.log`.
//
// Elements are named by CSS selector and looked up afresh on every call; a selector matching several
// elements means the first. Every failure throws WebDriverError (a std::runtime_error) whose message
// names the call and carries chromedriver's reply, so a test needs no try/catch: GoogleTest reports it.
//
// Tests skip themselves when the browser is missing:
//   std::string why;
//   if (!sandswim::testing::BrowserAvailable(&why)) GTEST_SKIP() << why;
//
// The Browser sets SIGPIPE to ignored if it was at its default (a write to a closed socket must
// not kill the test). Thread safety: none; one thread drives a Browser.
#ifndef SANDSWIM_TESTS_BROWSER_WEBDRIVER_H_
#define SANDSWIM_TESTS_BROWSER_WEBDRIVER_H_

#include <sys/types.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

namespace httplib {
class Client;
}  // namespace httplib

namespace sandswim::testing {

inline constexpr char kChromedriverPath[] = "/usr/bin/chromedriver";
inline constexpr char kChromiumPath[] = "/usr/bin/chromium";

// True when both binaries above are present and executable; otherwise false, and `why` (if not
// null) says which one is missing.
bool BrowserAvailable(std::string* why = nullptr);

// What every Browser call throws. error() is WebDriver's error code ("no such element",
// "javascript error", ...), or "" when chromedriver gave no WebDriver answer (not running, timed
// out, not JSON) or the failure is the client's own (a file it cannot write).
class WebDriverError : public std::runtime_error {
 public:
  WebDriverError(std::string error, const std::string& message)
      : std::runtime_error(message), error_(std::move(error)) {}
  const std::string& error() const { return error_; }

 private:
  std::string error_;
};

// One entry of the browser's console log.
struct LogEntry {
  std::string level;    // "SEVERE" (console.error, failed loads, uncaught errors), "WARNING", "INFO", "DEBUG"
  std::string message;  // as Chromium words it: source, line:column, then the JSON of the text,
                        // e.g. `http://127.0.0.1:8080/ 12:14 "boom"`
};

class Browser {
 public:
  // Starts chromedriver (its log in `log_dir`, created if missing), waits up to 20 s until
  // GET /status says ready, and opens a session (page loads and scripts time out after 30 s on
  // chromedriver's side; every HTTP call after 60 s on ours). Throws with chromedriver's reply or
  // the tail of its log when any step fails, leaving nothing running.
  explicit Browser(const std::string& log_dir);
  // Deletes the session, ends chromedriver's process group and removes the profile. Never throws.
  ~Browser();
  Browser(const Browser&) = delete;
  Browser& operator=(const Browser&) = delete;

  // Loads `url` and returns once the page has loaded (document.readyState "complete"). A page
  // that cannot be fetched (connection refused) does not throw: Chromium shows its error page.
  void Navigate(const std::string& url);
  // The current page's URL.
  std::string Url();

  // Runs `js` as the body of a function in the page (so use `return` to hand a value back) and
  // returns what it returned, as JSON (undefined: null). `args` are `arguments[0]`, ... (an array;
  // anything else is passed as the one argument).
  // A thrown exception throws WebDriverError "javascript error" with its message.
  nlohmann::json Script(const std::string& js, const nlohmann::json& args = nlohmann::json::array());
  // Evaluates the JavaScript expression every 100 ms until it is truthy (returns true) or
  // `timeout_s` has passed (returns false); it is always evaluated at least once. An evaluation
  // that throws counts as falsy (e.g. while the element it reads is not there yet), but if the
  // last one before the timeout threw, WaitUntil throws that error instead of returning false.
  // Other errors (the session gone, an alert open) throw at once.
  bool WaitUntil(const std::string& js_expression, double timeout_s);

  // The WebDriver id of the first element matching `css`; throws "no such element" when none does.
  std::string Find(const std::string& css);
  // Whether any element matches `css`.
  bool Exists(const std::string& css);
  // The ids of all matching elements, in document order; empty when none.
  std::vector<std::string> FindAll(const std::string& css);
  // The element's rendered text (innerText-like: hidden parts left out, whitespace collapsed).
  std::string Text(const std::string& css);
  // Scrolls the element into view and clicks its centre. Throws "element not interactable" when
  // it is not rendered, "element click intercepted" when another element covers it; a disabled
  // control is clicked to no effect.
  void Click(const std::string& css);
  // Focuses the element and types `text` at the end of what it holds, as key presses.
  void Type(const std::string& css, const std::string& text);
  // Empties an input, textarea or contenteditable element.
  void Clear(const std::string& css);
  // The element's attribute `name` as in the markup (getAttribute), "" when it has none. What
  // was typed into an input is its "value" property, not its attribute: see Property().
  std::string Attribute(const std::string& css, const std::string& name);
  // The element's DOM property `name` (e.g. "value", "checked"), as JSON; null when undefined.
  nlohmann::json Property(const std::string& css, const std::string& name);

  // Writes a PNG of the viewport to `png_path` (parent directories created).
  void Screenshot(const std::string& png_path);

  // Every console entry the pages of this session have logged so far, oldest first (chromedriver
  // hands each entry out once; the Browser keeps them). Entries of what happens after the load
  // (timers, fetches, the favicon request) may come some time after Navigate() returns.
  std::vector<LogEntry> BrowserLog();
  // The messages of BrowserLog()'s SEVERE entries: console.error, uncaught exceptions, and failed
  // loads, such as the /favicon.ico Chromium asks for when the page names no icon (a 404 from most
  // test servers; `<link rel="icon" href="data:,">` in the page prevents it).
  std::vector<std::string> ConsoleErrors();

  const std::string& session_id() const { return session_id_; }
  const std::string& log_path() const { return log_path_; }        // chromedriver's output
  int port() const { return port_; }                               // chromedriver's, on 127.0.0.1
  const std::string& profile_dir() const { return profile_dir_; }  // Chromium's --user-data-dir

 private:
  // One HTTP call to chromedriver; returns the reply's "value" or throws. A POST's null body is {}.
  nlohmann::json Call(const std::string& method, const std::string& path, const nlohmann::json& body = nullptr);
  // Call() on /session/{id}{path}.
  nlohmann::json SessionCall(const std::string& method, const std::string& path, const nlohmann::json& body = nullptr);
  // Runs `path_suffix` (e.g. "/click") on the element `css` names: finds it, retries once if it
  // went stale, and prefixes errors with `what("css")`.
  nlohmann::json ElementCall(const char* what, const std::string& css, const std::string& method,
                             const std::string& path_suffix, const nlohmann::json& body = nullptr);
  // Starts chromedriver under the guard on a fresh port; true once ready, false if it exited first.
  bool StartDriver(std::string* failure);
  void StopDriver();
  void Shutdown();  // the destructor's work; also undoes a constructor that throws
  std::string LogTail() const;

  std::string log_dir_, log_path_, profile_dir_, session_id_;
  int port_ = 0;
  pid_t guard_pid_ = 0;  // the guard: leader of the process group; 0 when none
  int control_fd_ = -1;  // closing it tells the guard to end the group
  std::unique_ptr<httplib::Client> client_;
  std::string log_route_;  // the route that served the browser log, once known
  std::vector<LogEntry> log_;
};

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_BROWSER_WEBDRIVER_H_
