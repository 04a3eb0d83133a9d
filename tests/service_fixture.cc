#include "tests/service_fixture.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <regex>
#include <stdexcept>
#include <thread>

#include <httplib.h>
#include <sqlite3.h>

#include "core/deck.h"
#include "core/engine_log.h"
#include "platform/tls.h"
#include "tests/engine_fixture.h"
#include "workers/client.h"
#include "workers/job_outcome.h"
#include "workers/run_dir.h"

namespace sandswim::testing {
namespace fs = std::filesystem;

ChildProcess::ChildProcess(std::vector<std::string> argv, const std::string& dir, const std::string& output_file)
    : output_path_(dir + "/" + output_file) {
  fs::create_directories(dir);
  worker::LaunchSpec spec;
  spec.argv = std::move(argv);
  spec.cwd = dir;
  spec.output_file = output_file;
  worker::GuardedLauncher launcher;
  auto started = launcher.Start(spec);
  if (!started.ok()) throw std::runtime_error("cannot start " + spec.argv[0] + ": " + started.status().ToString());
  process_ = std::move(started.value());
  pid_ = process_->pid();
}

ChildProcess::~ChildProcess() { Stop(); }

bool ChildProcess::running() { return !process_->WaitFor(0); }

void ChildProcess::Kill(int signal) {
  if (running()) ::kill(pid_, signal);
}

void ChildProcess::SignalProgram(int signal) {
  // The guard's one child is the program (/proc's list of a task's children).
  std::ifstream in("/proc/" + std::to_string(pid_) + "/task/" + std::to_string(pid_) + "/children");
  pid_t program = 0;
  if (!(in >> program) || program <= 0) throw std::runtime_error("the guard " + std::to_string(pid_) + " has no child");
  ::kill(program, signal);
}

void ChildProcess::Stop(double grace_s) { process_->Stop(grace_s); }

std::string ChildProcess::Output() const { return ReadFile(output_path_); }

Daemon::Daemon(const std::string& dir, std::vector<std::string> extra, const std::string& listen)
    : dir_(dir), db_(dir + "/sandswim.db") {
  // SANDSWIMD_UNDER_TEST: another build's daemon, for a benchmark's before-and-after figures.
  const char* other = std::getenv("SANDSWIMD_UNDER_TEST");
  const std::string program = other != nullptr && *other != '\0' ? other : SANDSWIMD_PATH;
  std::vector<std::string> argv = {program, "--db", db_, "--data", dir + "/data", "--listen", listen,
                                   "--local-workers", "0"};
  argv.insert(argv.end(), extra.begin(), extra.end());
  // These tests are about runs, not access: without a token, unless the test set one.
  const char* token = std::getenv("SANDSWIM_TOKEN");
  if ((token == nullptr || *token == '\0') && std::find(extra.begin(), extra.end(), "--token-file") == extra.end()) {
    argv.push_back("--no-token");
  }
  process_ = std::make_unique<ChildProcess>(argv, dir, "sandswimd.out");
  static const std::regex re(R"(listening on (https?://127\.0\.0\.1:\d+))");
  static const std::regex fingerprint(R"(tls: certificate .*, fingerprint (SHA256:[0-9A-F:]+))");
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  std::smatch m;
  std::string out;
  while (std::chrono::steady_clock::now() < deadline) {
    out = process_->Output();
    if (std::regex_search(out, m, re)) {
      url_ = m[1];
      if (std::regex_search(out, m, fingerprint)) tls_fingerprint_ = m[1];
      return;
    }
    if (!process_->running()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  throw std::runtime_error("sandswimd did not start; it printed:\n" + out);
}

namespace {
nlohmann::json Parse(const httplib::Result& r, const std::string& what, int* status) {
  if (!r) throw std::runtime_error(what + ": " + httplib::to_string(r.error()));
  if (status) *status = r->status;
  if (r->body.empty()) return nullptr;
  return nlohmann::json::parse(r->body, nullptr, /*allow_exceptions=*/false);
}
}  // namespace

namespace {
// The bearer token of SANDSWIM_TOKEN, when the test set one (the daemon and workers read it too).
httplib::Headers TokenHeaders() {
  const char* token = std::getenv("SANDSWIM_TOKEN");
  if (token == nullptr || *token == '\0') return {};
  return {{"Authorization", std::string("Bearer ") + token}};
}
}  // namespace

nlohmann::json Daemon::Get(const std::string& path, int* status) {
  httplib::Client c(url_);
  ConfigureTls(c, TlsTrust{"", tls_fingerprint_});
  return Parse(c.Get(path, TokenHeaders()), "GET " + path, status);
}

std::string Daemon::GetText(const std::string& path, int* status) {
  httplib::Client c(url_);
  ConfigureTls(c, TlsTrust{"", tls_fingerprint_});
  c.set_read_timeout(120, 0);
  auto r = c.Get(path, TokenHeaders());
  if (!r) throw std::runtime_error("GET " + path + ": " + httplib::to_string(r.error()));
  if (status != nullptr) *status = r->status;
  return r->body;
}

nlohmann::json Daemon::Post(const std::string& path, const nlohmann::json& body, int* status) {
  httplib::Client c(url_);
  ConfigureTls(c, TlsTrust{"", tls_fingerprint_});
  return Parse(c.Post(path, TokenHeaders(), body.dump(), "application/json"), "POST " + path, status);
}

nlohmann::json Daemon::Put(const std::string& path, const nlohmann::json& body, int* status) {
  httplib::Client c(url_);
  ConfigureTls(c, TlsTrust{"", tls_fingerprint_});
  return Parse(c.Put(path, TokenHeaders(), body.dump(), "application/json"), "PUT " + path, status);
}

nlohmann::json Daemon::WaitForSweep(int64_t sweep_id, double timeout_s) {
  auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  nlohmann::json s;
  while (std::chrono::steady_clock::now() < deadline) {
    s = Get("/api/v1/sweeps/" + std::to_string(sweep_id));
    if (s.is_object() && s["counts"]["queued"] == 0 && s["counts"]["running"] == 0) return s;
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
  return s;
}

namespace {
// The daemon's file opened beside it: read-only, or read-write for StoreDeckForRun.
struct Connection {
  Connection(const std::string& path, bool write) {
    const int flags = write ? SQLITE_OPEN_READWRITE : SQLITE_OPEN_READONLY;
    if (sqlite3_open_v2(path.c_str(), &db, flags, nullptr) != SQLITE_OK) {
      throw std::runtime_error("cannot open " + path + ": " + sqlite3_errmsg(db));
    }
    sqlite3_busy_timeout(db, 10000);
  }
  ~Connection() { sqlite3_close(db); }
  sqlite3* db = nullptr;
};

void Check(int rc, sqlite3* db, const std::string& sql) {
  if (rc != SQLITE_OK && rc != SQLITE_ROW && rc != SQLITE_DONE) {
    throw std::runtime_error(sql + ": " + sqlite3_errmsg(db));
  }
}
}  // namespace

int ConnectTo(const std::string& listen, const std::string& from) {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (!from.empty()) {
    sockaddr_in source{};
    source.sin_family = AF_INET;
    inet_pton(AF_INET, from.c_str(), &source.sin_addr);
    if (bind(fd, reinterpret_cast<sockaddr*>(&source), sizeof source) != 0) {
      close(fd);
      return -1;
    }
  }
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_port = htons(static_cast<uint16_t>(std::stoi(listen.substr(listen.rfind(':') + 1))));
  inet_pton(AF_INET, "127.0.0.1", &addr.sin_addr);
  if (connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

std::vector<ProcessInfo> ProcessesUnder(const std::string& dir) {
  std::vector<ProcessInfo> found;
  for (const auto& entry : fs::directory_iterator("/proc")) {
    std::error_code ec;
    const std::string cwd = fs::read_symlink(entry.path() / "cwd", ec).string();
    if (ec || cwd.compare(0, dir.size(), dir) != 0) continue;
    std::ifstream stat(entry.path() / "stat");
    std::string line;
    std::getline(stat, line);
    const size_t open = line.find('('), close = line.rfind(')');
    if (open == std::string::npos || close == std::string::npos || close + 2 >= line.size()) continue;
    if (line[close + 2] == 'Z') continue;
    found.push_back({static_cast<pid_t>(std::stol(line)), line.substr(open + 1, close - open - 1)});
  }
  return found;
}

std::string Daemon::Query(const std::string& sql) const {
  Connection c(db_, /*write=*/false);
  sqlite3_stmt* st = nullptr;
  Check(sqlite3_prepare_v2(c.db, sql.c_str(), -1, &st, nullptr), c.db, sql);
  const int rc = sqlite3_step(st);
  std::string out;
  if (rc == SQLITE_ROW && sqlite3_column_type(st, 0) != SQLITE_NULL) {
    out = reinterpret_cast<const char*>(sqlite3_column_text(st, 0));
  }
  sqlite3_finalize(st);
  Check(rc, c.db, sql);
  return out;
}

void Daemon::StoreDeckForRun(int64_t run_id, const std::string& deck) {
  Connection c(db_, /*write=*/true);
  const std::string sql = "INSERT INTO run_decks (run_id, deck) VALUES (?, ?)";
  sqlite3_stmt* st = nullptr;
  Check(sqlite3_prepare_v2(c.db, sql.c_str(), -1, &st, nullptr), c.db, sql);
  sqlite3_bind_int64(st, 1, run_id);
  sqlite3_bind_text(st, 2, deck.data(), static_cast<int>(deck.size()), SQLITE_TRANSIENT);
  const int rc = sqlite3_step(st);
  sqlite3_finalize(st);
  Check(rc, c.db, sql);
}

namespace {

std::unique_ptr<worker::HttpServerClient> BedClient(const Daemon& daemon) {
  ClientOptions options;
  options.server = daemon.url();
  options.tls.fingerprint = daemon.tls_fingerprint();
  options.retry_for_s = 30;
  return std::make_unique<worker::HttpServerClient>(options);
}

// Uploads the restart at `restart` for the bed leased under `g` and completes it with the figures
// a worker reports for it (workers/job_outcome.h).
void UploadAndComplete(worker::HttpServerClient& client, const api::LeaseGrant& g, const std::string& restart) {
  const std::string dir = fs::path(restart).parent_path().string();
  const EngineLog log = ParseEngineLog(ReadFile(dir + "/" + kLogFile));
  if (!log.bed_grains) throw std::runtime_error("no bed figures in " + dir + "/" + kLogFile);
  if (g.deck != ReadFile(dir + "/deck.in")) {  // another scale or replicate: this restart is not that bed
    (void)client.Release(g.token, "not the prepared bed");
    throw std::runtime_error("the leased bed " + std::to_string(g.id) + " is not the one prepared in " + dir +
                             " (another scale or replicate)");
  }
  std::optional<std::string> bed_dump;
  if (fs::exists(dir + "/" + kBedDumpFile)) bed_dump = ReadFile(dir + "/" + kBedDumpFile);
  auto sha = Sha256OfFile(restart);
  if (!sha.ok()) throw std::runtime_error(sha.status().ToString());
  if (Status s = client.UploadBed(g.id, g.token, restart, *sha); !s.ok()) {
    throw std::runtime_error("bed upload: " + s.ToString());
  }
  worker::JobOutcome judged =
      worker::JudgeJob(api::JobKind::kBed, 0, ExitFacts{}, log, DriveInfo{g.dt_s, 0, 0, std::nullopt},
                       std::vector<SoSample>(), std::nullopt, bed_dump);
  if (!judged.bed) throw std::runtime_error("the bed's log does not make a bed: " + judged.failure->message);
  api::Completion done;
  done.ok = true;
  api::BedResult bed = *judged.bed;
  bed.sha256 = *sha;
  bed.bytes = static_cast<int64_t>(fs::file_size(restart));
  done.bed_result = bed;
  auto reply = client.Complete(g.token, done);
  if (!reply.ok() || reply->state != "done") {
    throw std::runtime_error("bed completion: " + (reply.ok() ? reply->state : reply.status().ToString()));
  }
}

// Leases the next job, which must be a queued bed (a lease would otherwise hand out a run).
api::LeaseGrant LeaseBed(worker::HttpServerClient& client, const std::string& who) {
  auto grant = client.Lease(api::LeaseRequest(who, "localhost", 1));
  if (!grant.ok()) throw std::runtime_error("lease: " + grant.status().ToString());
  if (!grant->has_value()) throw std::runtime_error("a bed is queued, yet there was nothing to lease");
  const api::LeaseGrant& g = **grant;
  if (g.kind != api::JobKind::kBed) {
    (void)client.Release(g.token, "only beds are handed in");
    throw std::runtime_error("a bed is queued, yet the lease handed out a run");
  }
  return g;
}

}  // namespace

void HandInBeds(const Daemon& daemon, const std::string& restart) {
  std::unique_ptr<worker::HttpServerClient> client = BedClient(daemon);
  while (daemon.Query("SELECT count(*) FROM beds WHERE state = 'queued'") != "0") {
    UploadAndComplete(*client, LeaseBed(*client, "test-bed-hand-in"), restart);
  }
}

BedHandIn::BedHandIn(const Daemon& daemon) : client_(BedClient(daemon)), grant_(LeaseBed(*client_, "test-bed-hold")) {
  // The heartbeat holds the lock for its request: the one client is never used by two threads,
  // and no heartbeat crosses the completion.
  heartbeat_ = std::thread([this] {
    std::unique_lock<std::mutex> lock(mu_);
    while (!done_) {
      auto beat = client_->Heartbeat(grant_.token, api::Heartbeat{});
      if (!beat.ok()) heartbeat_error_ = beat.status().ToString();
      cv_.wait_for(lock, std::chrono::duration<double>(grant_.ttl_s / 4));
    }
  });
}

BedHandIn::~BedHandIn() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    done_ = true;
  }
  cv_.notify_all();
  heartbeat_.join();
}

void BedHandIn::Complete(const std::string& restart) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    done_ = true;  // a completed lease takes no more heartbeats
    try {
      UploadAndComplete(*client_, grant_, restart);
    } catch (const std::exception& e) {
      throw std::runtime_error(std::string(e.what()) +
                               (heartbeat_error_.empty() ? "" : " (last heartbeat failed: " + heartbeat_error_ + ")"));
    }
  }
  cv_.notify_all();
}

std::unique_ptr<ChildProcess> StartWorker(const Daemon& daemon, const std::string& dir, int slots,
                                          const std::vector<std::string>& extra) {
  std::vector<std::string> argv = {
      SANDSWIM_WORKER_PATH, "--server", daemon.url(),  "--slots", std::to_string(slots), "--ranks", "1",
      "--workdir",          dir,        "--heartbeat", "1"};
  if (std::find(extra.begin(), extra.end(), "--heartbeat") != extra.end()) argv.resize(argv.size() - 2);  // theirs
  if (!daemon.tls_fingerprint().empty() &&
      std::find(extra.begin(), extra.end(), "--tls-fingerprint") == extra.end()) {
    argv.insert(argv.end(), {"--tls-fingerprint", daemon.tls_fingerprint()});
  }
  argv.insert(argv.end(), extra.begin(), extra.end());
  return std::make_unique<ChildProcess>(argv, dir, "worker.out");
}

nlohmann::json OmegaSweep(const std::string& name, const std::vector<double>& omegas, double duration, double f) {
  using nlohmann::json;
  return {{"name", name},
          {"scale", "smoke"},
          {"base", {{"mode", "oscillatory"}, {"A", 0.03}, {"f", f}, {"Omega", omegas.at(0)}, {"duration_s", duration}}},
          {"axes", json::array({{{"param", "Omega"}, {"values", omegas}}})},
          {"combine", "product"}};
}

}  // namespace sandswim::testing
