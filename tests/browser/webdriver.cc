#include "tests/browser/webdriver.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <utility>

#include <httplib.h>

namespace sandswim::testing {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using WdClock = std::chrono::steady_clock;

constexpr double kWdDriverReadyTimeoutS = 20;
constexpr int kWdCommandTimeoutS = 60;
constexpr int kWdDriverStartAttempts = 3;  // another process may take the port between pick and bind
constexpr double kWdGuardGraceS = 3;       // the guard's wait for chromedriver after SIGTERM
constexpr double kWdStopTimeoutS = 10;     // our wait for the guard before SIGKILL of the group
constexpr char kWdElementKey[] = "element-6066-11e4-a52e-4f735466cecf";  // W3C's element reference key

double WdSecondsSince(WdClock::time_point start) {
  return std::chrono::duration<double>(WdClock::now() - start).count();
}

std::string WdErrno(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

// A free loopback TCP port: bind port 0, read the port back, close. chromedriver binds it next.
int WdPickFreePort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw WebDriverError("", WdErrno("socket"));
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof(addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) != 0) {
    const std::string error = WdErrno("binding a loopback port");
    ::close(fd);
    throw WebDriverError("", error);
  }
  ::close(fd);
  return ntohs(addr.sin_port);
}

// --- The guard: runs in the forked child, so only async-signal-safe calls (the parent may have
// other threads, whose locks the child inherits held).

void WdSleepMs(long ms) {
  timespec ts{ms / 1000, (ms % 1000) * 1000000L};
  while (::nanosleep(&ts, &ts) != 0 && errno == EINTR) {
  }
}

void WdGuardSay(const char* text, int number) {  // a line in the log, e.g. "... status 256"
  char buf[160];
  size_t n = 0;
  for (const char* p = text; *p && n < 120; ++p) buf[n++] = *p;
  char digits[16];
  int d = 0;
  unsigned value = number < 0 ? static_cast<unsigned>(-number) : static_cast<unsigned>(number);
  do {
    digits[d++] = static_cast<char>('0' + value % 10);
    value /= 10;
  } while (value != 0);
  if (number < 0) buf[n++] = '-';
  while (d > 0) buf[n++] = digits[--d];
  buf[n++] = '\n';
  [[maybe_unused]] ssize_t ignored = ::write(2, buf, n);
}

// The process-group leader: starts chromedriver as its child, then waits until the control pipe
// reaches end of file (the Browser closed it, or the test process died) or chromedriver exits,
// and then ends the whole group: SIGTERM, up to kWdGuardGraceS for chromedriver, SIGKILL (which
// ends the guard too).
[[noreturn]] void WdRunGuard(int control_fd, int log_fd, int null_fd, char* const* argv) {
  ::setpgid(0, 0);
  if (::getpgrp() != ::getpid()) {  // never signal the test process's own group
    WdGuardSay("[guard] cannot lead a process group, errno ", errno);
    ::_exit(125);
  }
  ::dup2(null_fd, 0);
  ::dup2(log_fd, 1);
  ::dup2(log_fd, 2);
  ::dup2(control_fd, 3);
  ::fcntl(3, F_SETFD, FD_CLOEXEC);
  // Nothing else of the test process's stays open here (sockets, other Browsers' pipes).
  if (::syscall(SYS_close_range, 4U, ~0U, 0U) != 0) {
    for (int fd = 4; fd < 4096; ++fd) ::close(fd);
  }
  sigset_t none;
  sigemptyset(&none);
  ::sigprocmask(SIG_SETMASK, &none, nullptr);
  for (int sig : {SIGPIPE, SIGTERM, SIGINT, SIGHUP, SIGCHLD}) ::signal(sig, SIG_DFL);

  const pid_t driver = ::fork();
  if (driver == 0) {
    ::execv(argv[0], argv);
    WdGuardSay("cannot exec chromedriver, errno ", errno);
    ::_exit(127);
  }
  if (driver < 0) {
    WdGuardSay("cannot fork chromedriver, errno ", errno);
    ::_exit(126);
  }
  ::signal(SIGTERM, SIG_IGN);  // the group's SIGTERM below is for the others

  bool driver_exited = false;
  for (;;) {
    pollfd control{3, POLLIN, 0};
    if (::poll(&control, 1, 100) > 0) {
      char byte;
      if (::read(3, &byte, 1) <= 0) break;  // end of file: stop
    }
    int status = 0;
    if (::waitpid(driver, &status, WNOHANG) == driver) {
      WdGuardSay("[guard] chromedriver exited; wait status ", status);
      driver_exited = true;
      break;
    }
  }
  ::kill(0, SIGTERM);
  for (int i = 0; !driver_exited && i < static_cast<int>(kWdGuardGraceS * 20); ++i) {
    int status = 0;
    if (::waitpid(driver, &status, WNOHANG) == driver) break;
    WdSleepMs(50);
  }
  ::kill(0, SIGKILL);
  ::_exit(0);  // not reached
}

// ---

std::string WdReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream out;
  out << in.rdbuf();
  return out.str();
}

std::string WdBase64Decode(const std::string& text) {
  static const auto kTable = [] {
    std::array<int, 256> table;
    table.fill(-1);
    const char* alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (int i = 0; i < 64; ++i) table[static_cast<unsigned char>(alphabet[i])] = i;
    return table;
  }();
  std::string out;
  out.reserve(text.size() / 4 * 3);
  unsigned bits = 0;
  int count = 0;
  for (char c : text) {
    if (c == '=') break;
    if (c == '\n' || c == '\r') continue;
    const int value = kTable[static_cast<unsigned char>(c)];
    if (value < 0) throw WebDriverError("", "screenshot: not base64 (character " + std::to_string(int(c)) + ")");
    bits = (bits << 6) | static_cast<unsigned>(value);
    if (++count == 4) {
      out.push_back(static_cast<char>((bits >> 16) & 0xff));
      out.push_back(static_cast<char>((bits >> 8) & 0xff));
      out.push_back(static_cast<char>(bits & 0xff));
      bits = 0;
      count = 0;
    }
  }
  if (count == 2) {
    out.push_back(static_cast<char>((bits >> 4) & 0xff));
  } else if (count == 3) {
    out.push_back(static_cast<char>((bits >> 10) & 0xff));
    out.push_back(static_cast<char>((bits >> 2) & 0xff));
  } else if (count == 1) {
    throw WebDriverError("", "screenshot: truncated base64");
  }
  return out;
}

std::string WdQuote(const std::string& s) { return json(s).dump(); }

std::string WdElementId(const json& reference) {
  if (!reference.is_object() || !reference.contains(kWdElementKey) || !reference[kWdElementKey].is_string()) {
    throw WebDriverError("", "not an element reference: " + reference.dump());
  }
  return reference[kWdElementKey].get<std::string>();
}

}  // namespace

bool BrowserAvailable(std::string* why) {
  for (const char* path : {kChromiumPath, kChromedriverPath}) {
    if (::access(path, X_OK) != 0) {
      if (why != nullptr) {
        *why = std::string(path) + " is missing (apt-get install chromium chromium-driver): " + std::strerror(errno);
      }
      return false;
    }
  }
  return true;
}

Browser::Browser(const std::string& log_dir) : log_dir_(log_dir) {
  struct sigaction pipe_action {};
  if (::sigaction(SIGPIPE, nullptr, &pipe_action) == 0 && pipe_action.sa_handler == SIG_DFL) ::signal(SIGPIPE, SIG_IGN);
  try {
    std::error_code ec;
    fs::create_directories(log_dir_, ec);
    if (ec) throw WebDriverError("", "cannot create " + log_dir_ + ": " + ec.message());
    std::string failure;
    bool ready = false;
    for (int attempt = 1; attempt <= kWdDriverStartAttempts && !ready; ++attempt) ready = StartDriver(&failure);
    if (!ready) throw WebDriverError("", failure);

    std::string profile_template = (fs::temp_directory_path() / "sandswim-chromium-XXXXXX").string();
    if (::mkdtemp(profile_template.data()) == nullptr) throw WebDriverError("", WdErrno("mkdtemp"));
    profile_dir_ = profile_template;

    const json capabilities = {{"capabilities",
                                {{"alwaysMatch",
                                  {{"browserName", "chrome"},
                                   {"goog:chromeOptions",
                                    {{"binary", kChromiumPath},
                                     {"args",
                                      {"--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                                       "--window-size=1280,900", "--user-data-dir=" + profile_dir_}}}},
                                   {"goog:loggingPrefs", {{"browser", "ALL"}}}}}}}};
    const json session = Call("POST", "/session", capabilities);
    if (!session.is_object() || !session.contains("sessionId") || !session["sessionId"].is_string()) {
      throw WebDriverError("", "POST /session: no sessionId in " + session.dump());
    }
    session_id_ = session["sessionId"].get<std::string>();
    // Below our HTTP timeout, so that chromedriver answers with an error before we give up on it.
    SessionCall("POST", "/timeouts", {{"pageLoad", 30000}, {"script", 30000}, {"implicit", 0}});
  } catch (...) {
    Shutdown();
    throw;
  }
}

Browser::~Browser() { Shutdown(); }

bool Browser::StartDriver(std::string* failure) {
  port_ = WdPickFreePort();
  log_path_ = (fs::path(log_dir_) / ("chromedriver-" + std::to_string(port_) + ".log")).string();
  // INFO: every command and its reply (long ones cut short) in the log, a few kB a test.
  std::vector<std::string> args = {kChromedriverPath, "--port=" + std::to_string(port_), "--log-level=INFO"};
  std::vector<char*> argv;
  for (auto& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);

  const int log_fd = ::open(log_path_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (log_fd < 0) throw WebDriverError("", WdErrno(("cannot open " + log_path_).c_str()));
  const int null_fd = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  int control[2];
  if (null_fd < 0 || ::pipe2(control, O_CLOEXEC) != 0) {
    const std::string error = WdErrno("cannot open /dev/null or a pipe");
    ::close(log_fd);
    if (null_fd >= 0) ::close(null_fd);
    throw WebDriverError("", error);
  }
  const pid_t pid = ::fork();
  if (pid == 0) WdRunGuard(control[0], log_fd, null_fd, argv.data());
  const int fork_errno = errno;
  ::close(log_fd);
  ::close(null_fd);
  ::close(control[0]);
  if (pid < 0) {
    ::close(control[1]);
    errno = fork_errno;
    throw WebDriverError("", WdErrno("fork"));
  }
  ::setpgid(pid, pid);  // also done by the child; whichever runs first
  guard_pid_ = pid;
  control_fd_ = control[1];

  client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
  client_->set_connection_timeout(1, 0);
  client_->set_read_timeout(2, 0);
  client_->set_write_timeout(2, 0);
  const auto start = WdClock::now();
  std::string last_reply = "no answer";
  for (;;) {
    int status = 0;
    if (::waitpid(guard_pid_, &status, WNOHANG) == guard_pid_) {
      guard_pid_ = 0;
      ::close(control_fd_);
      control_fd_ = -1;
      *failure = "chromedriver exited before it was ready; its log " + log_path_ + ":\n" + LogTail();
      return false;
    }
    if (auto res = client_->Get("/status")) {
      last_reply = "HTTP " + std::to_string(res->status) + " " + res->body;
      const json reply = json::parse(res->body, nullptr, false);
      if (res->status == 200 && reply.is_object() && reply.contains("value") && reply["value"].is_object() &&
          reply["value"].value("ready", false)) {
        break;
      }
    } else {
      last_reply = httplib::to_string(res.error());
    }
    if (WdSecondsSince(start) > kWdDriverReadyTimeoutS) {
      StopDriver();
      throw WebDriverError("", "chromedriver on port " + std::to_string(port_) + " not ready after " +
                                   std::to_string(int(kWdDriverReadyTimeoutS)) + " s (last GET /status: " + last_reply +
                                   "); its log " + log_path_ + ":\n" + LogTail());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  client_->set_connection_timeout(5, 0);
  client_->set_read_timeout(kWdCommandTimeoutS, 0);
  client_->set_write_timeout(kWdCommandTimeoutS, 0);
  client_->set_keep_alive(true);
  return true;
}

void Browser::StopDriver() {
  client_.reset();
  if (guard_pid_ <= 0) return;
  ::close(control_fd_);  // the guard ends the group
  control_fd_ = -1;
  const auto start = WdClock::now();
  int status = 0;
  while (::waitpid(guard_pid_, &status, WNOHANG) == 0) {
    if (WdSecondsSince(start) > kWdStopTimeoutS) {
      ::kill(-guard_pid_, SIGKILL);  // the guard is unreaped, so its group id is still ours
      ::waitpid(guard_pid_, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  guard_pid_ = 0;
}

void Browser::Shutdown() {
  if (!session_id_.empty() && client_) {
    client_->set_read_timeout(10, 0);
    client_->Delete("/session/" + session_id_);  // errors ignored: the group ends anyway
  }
  session_id_.clear();
  StopDriver();
  if (!profile_dir_.empty()) {
    // A dying Chromium process may still add a file: try again briefly.
    for (int i = 0; i < 10; ++i) {
      std::error_code ec;
      fs::remove_all(profile_dir_, ec);
      if (!ec) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    profile_dir_.clear();
  }
}

std::string Browser::LogTail() const {
  std::string text = WdReadFile(log_path_);
  constexpr size_t kTail = 4000;
  if (text.size() > kTail) text = "..." + text.substr(text.size() - kTail);
  return text;
}

json Browser::Call(const std::string& method, const std::string& path, const json& body) {
  if (!client_) throw WebDriverError("", method + " " + path + ": chromedriver is not running");
  auto send = [&] {
    if (method == "GET") return client_->Get(path);
    if (method == "DELETE") return client_->Delete(path);
    return client_->Post(path, body.is_null() ? "{}" : body.dump(), "application/json");
  };
  const httplib::Result res = send();
  const std::string what = "webdriver " + method + " " + path;
  if (!res) {
    throw WebDriverError("", what + ": no answer from chromedriver (" + httplib::to_string(res.error()) +
                                 "); its log " + log_path_ + ":\n" + LogTail());
  }
  json reply = json::parse(res->body, nullptr, false);
  if (reply.is_discarded() || !reply.is_object() || !reply.contains("value")) {
    throw WebDriverError(
        "", what + ": HTTP " + std::to_string(res->status) + ", not a WebDriver reply: " + res->body.substr(0, 2000));
  }
  json value = std::move(reply["value"]);
  if (res->status != 200) {
    std::string error = "unknown error", message;
    if (value.is_object()) {
      error = value.value("error", error);
      message = value.value("message", "");
    }
    if (message.empty()) message = value.dump();
    throw WebDriverError(error, what + ": " + error + " (HTTP " + std::to_string(res->status) + "): " + message);
  }
  return value;
}

json Browser::SessionCall(const std::string& method, const std::string& path, const json& body) {
  return Call(method, "/session/" + session_id_ + path, body);
}

json Browser::ElementCall(const char* what, const std::string& css, const std::string& method,
                          const std::string& path_suffix, const json& body) {
  try {
    for (int attempt = 0;; ++attempt) {
      const std::string id = Find(css);
      try {
        return SessionCall(method, "/element/" + id + path_suffix, body);
      } catch (const WebDriverError& e) {
        if (e.error() != "stale element reference" || attempt > 0) throw;
      }
    }
  } catch (const WebDriverError& e) {
    throw WebDriverError(e.error(), std::string(what) + "(" + WdQuote(css) + "): " + e.what());
  }
}

void Browser::Navigate(const std::string& url) { SessionCall("POST", "/url", {{"url", url}}); }

std::string Browser::Url() { return SessionCall("GET", "/url").get<std::string>(); }

json Browser::Script(const std::string& js, const json& args) {
  json call_args = args;
  if (!call_args.is_array()) call_args = json::array({args});  // one argument given bare
  return SessionCall("POST", "/execute/sync", {{"script", js}, {"args", call_args}});
}

bool Browser::WaitUntil(const std::string& js_expression, double timeout_s) {
  const auto start = WdClock::now();
  // The newline ends a trailing // comment in the expression.
  const std::string js = "return Boolean(" + js_expression + "\n);";
  for (;;) {
    std::string error;
    try {
      if (Script(js).get<bool>()) return true;
    } catch (const WebDriverError& e) {
      if (e.error() != "javascript error") throw;  // the expression's own error counts as false
      error = e.what();
    }
    if (WdSecondsSince(start) >= timeout_s) {
      if (!error.empty()) {
        throw WebDriverError("javascript error", "WaitUntil(" + WdQuote(js_expression) + "): still failing after " +
                                                     std::to_string(timeout_s) + " s: " + error);
      }
      return false;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

std::string Browser::Find(const std::string& css) {
  return WdElementId(SessionCall("POST", "/element", {{"using", "css selector"}, {"value", css}}));
}

std::vector<std::string> Browser::FindAll(const std::string& css) {
  const json found = SessionCall("POST", "/elements", {{"using", "css selector"}, {"value", css}});
  std::vector<std::string> ids;
  for (const auto& reference : found) ids.push_back(WdElementId(reference));
  return ids;
}

bool Browser::Exists(const std::string& css) { return !FindAll(css).empty(); }

std::string Browser::Text(const std::string& css) {
  return ElementCall("Text", css, "GET", "/text").get<std::string>();
}

void Browser::Click(const std::string& css) { ElementCall("Click", css, "POST", "/click", json::object()); }

void Browser::Type(const std::string& css, const std::string& text) {
  ElementCall("Type", css, "POST", "/value", {{"text", text}});
}

void Browser::Clear(const std::string& css) { ElementCall("Clear", css, "POST", "/clear", json::object()); }

std::string Browser::Attribute(const std::string& css, const std::string& name) {
  const json value = ElementCall("Attribute", css, "GET", "/attribute/" + name);
  if (value.is_null()) return "";
  return value.is_string() ? value.get<std::string>() : value.dump();
}

json Browser::Property(const std::string& css, const std::string& name) {
  return ElementCall("Property", css, "GET", "/property/" + name);
}

void Browser::Screenshot(const std::string& png_path) {
  const json encoded = SessionCall("GET", "/screenshot");
  if (!encoded.is_string()) throw WebDriverError("", "screenshot: not a string: " + encoded.dump().substr(0, 200));
  const std::string png = WdBase64Decode(encoded.get<std::string>());
  const fs::path path(png_path);
  std::error_code ec;
  if (path.has_parent_path()) fs::create_directories(path.parent_path(), ec);
  std::ofstream out(png_path, std::ios::binary | std::ios::trunc);
  out.write(png.data(), static_cast<std::streamsize>(png.size()));
  out.close();
  if (!out) throw WebDriverError("", "screenshot: cannot write " + png_path);
}

std::vector<LogEntry> Browser::BrowserLog() {
  // W3C-mode chromedriver serves the log at /se/log; older ones at the legacy /log (POST both).
  const json body = {{"type", "browser"}};
  json entries;
  if (!log_route_.empty()) {
    entries = SessionCall("POST", log_route_, body);
  } else {
    try {
      entries = SessionCall("POST", "/se/log", body);
      log_route_ = "/se/log";
    } catch (const WebDriverError& e) {
      if (e.error() != "unknown command" && e.error() != "unknown method") throw;
      entries = SessionCall("POST", "/log", body);
      log_route_ = "/log";
    }
  }
  for (const auto& entry : entries) {
    if (!entry.is_object()) continue;
    log_.push_back({entry.value("level", ""), entry.value("message", "")});
  }
  return log_;
}

std::vector<std::string> Browser::ConsoleErrors() {
  std::vector<std::string> errors;
  for (const auto& entry : BrowserLog()) {
    if (entry.level == "SEVERE") errors.push_back(entry.message);
  }
  return errors;
}

}  // namespace sandswim::testing
