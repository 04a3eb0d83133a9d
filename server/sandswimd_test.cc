// The real sandswimd binary on an ephemeral port with a temp SQLite file: it serves, makes its own
// token on a first start and reuses it, refuses a weak token and --no-token beyond loopback, logs
// and slows wrong tokens, refuses a Host that is not its own, and survives SIGKILL with a run leased — after a
// restart on the same file nothing is lost (the lease, the bed, the Idempotency-Key) and nothing
// is doubled (no second run, no second result); its local worker's runs are handed back, not
// charged an attempt, whether it stops (SIGTERM) or dies (SIGKILL).
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/keys.h"

namespace sandswim {
namespace {

using json = nlohmann::json;
using ::testing::HasSubstr;

#ifndef SANDSWIMD_PATH
#error "SANDSWIMD_PATH must name the sandswimd binary (server/CMakeLists.txt)"
#endif

const char* kDaemonExampleSweep = R"({"name": "omega-sign", "scale": "smoke",
  "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
  "axes": [{"param": "Omega", "values": [-80, 80]}], "combine": "product"})";

// One sandswimd process; stdout is read until its "listening on" line.
class Daemon {
 public:
  ~Daemon() { Kill(SIGKILL); }

  // Returns the exit status when the daemon exits before it is ready.
  std::optional<int> Start(const std::vector<std::string>& flags, const std::string& log_path) {
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0) return -1;
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
    posix_spawn_file_actions_addopen(&actions, 2, log_path.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    std::vector<std::string> args = {SANDSWIMD_PATH};
    args.insert(args.end(), flags.begin(), flags.end());
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    int rc = posix_spawn(&pid_, SANDSWIMD_PATH, &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    if (rc != 0) {
      close(fds[0]);
      return -1;
    }
    std::string out;
    auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    const std::string ready = "sandswimd listening on http://127.0.0.1:";
    auto have_ready_line = [&] {
      size_t at = out.find(ready);
      return at != std::string::npos && out.find('\n', at) != std::string::npos;
    };
    while (!have_ready_line()) {
      pollfd p{fds[0], POLLIN, 0};
      if (std::chrono::steady_clock::now() > deadline || poll(&p, 1, 1000) < 0) break;
      char buffer[512];
      ssize_t n = read(fds[0], buffer, sizeof buffer);
      if (n <= 0) break;
      out.append(buffer, static_cast<size_t>(n));
    }
    close(fds[0]);  // the daemon prints nothing else on stdout
    stdout_ = out;
    size_t at = out.find(ready);
    if (at == std::string::npos) {
      int status = 0;
      waitpid(pid_, &status, 0);
      pid_ = 0;
      return status;
    }
    port_ = std::stoi(out.substr(at + ready.size()));
    return std::nullopt;
  }

  int Kill(int signal) {
    if (pid_ <= 0) return 0;
    kill(pid_, signal);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = 0;
    return status;
  }

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  // What it printed on stdout up to its "listening on" line.
  const std::string& printed() const { return stdout_; }

 private:
  std::string stdout_;
  pid_t pid_ = 0;
  int port_ = 0;
};

class SandswimdTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/sandswimd-test-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // `no_token`: these tests' requests send none (the tests of the token pass false).
  std::vector<std::string> Flags(const std::string& listen = "127.0.0.1:0", bool no_token = true) {
    std::vector<std::string> flags = {"--db",
                                      dir_ + "/var/sandswim.db",
                                      "--data",
                                      dir_ + "/var/data",
                                      "--listen",
                                      listen,
                                      "--engine-version",
                                      "LIGGGHTS (Version test)",
                                      "--lease-ttl",
                                      "600"};
    if (no_token) flags.push_back("--no-token");
    return flags;
  }
  std::string TokenPath() { return dir_ + "/var/data/token"; }
  std::string Log() { return dir_ + "/sandswimd.log"; }

  std::string dir_;
};

json Parse(const httplib::Result& r) { return json::parse(r->body); }

TEST_F(SandswimdTest, RefusesANonLoopbackAddressWithoutAToken) {
  Daemon d;
  auto exited = d.Start(Flags("0.0.0.0:0"), Log());  // with --no-token
  ASSERT_TRUE(exited.has_value()) << "it started";
  EXPECT_TRUE(WIFEXITED(*exited) && WEXITSTATUS(*exited) != 0);
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/var/sandswim.db"));
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// A first start with no token given makes one (256 bits, DATA/token, mode 0600), prints the
// dashboard's link with it, and serves with it: reads and writes need it, /healthz does not. The
// next start reuses it.
TEST_F(SandswimdTest, AFirstStartMakesItsTokenFileAndTheNextReusesIt) {
  std::string token;
  {
    Daemon d;
    ASSERT_FALSE(d.Start(Flags("127.0.0.1:0", /*no_token=*/false), Log()).has_value()) << ReadText(Log());
    ASSERT_TRUE(std::filesystem::exists(TokenPath()));
    EXPECT_EQ(std::filesystem::status(TokenPath()).permissions() & std::filesystem::perms::all,
              std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
    token = ReadText(TokenPath());
    while (!token.empty() && token.back() == '\n') token.pop_back();
    EXPECT_THAT(token, ::testing::MatchesRegex("[0-9a-f]{64}"));
    // Its stdout is a pipe here, as the journal is under systemd: the link names the token's file
    // and never prints the token (a terminal gets the whole link).
    EXPECT_THAT(d.printed(), HasSubstr("dashboard: http://127.0.0.1:" + std::to_string(d.port()) +
                                       "/?token=TOKEN, TOKEN the contents of " + TokenPath()));
    EXPECT_THAT(d.printed(), ::testing::Not(HasSubstr(token)));
    httplib::Client c("127.0.0.1", d.port());
    EXPECT_EQ(c.Get("/healthz")->status, 200);
    EXPECT_EQ(c.Get("/api/v1/sweeps")->status, 401);
    EXPECT_EQ(c.Post("/api/v1/sweeps", kDaemonExampleSweep, "application/json")->status, 401);
    c.set_bearer_token_auth(token);
    EXPECT_EQ(c.Get("/api/v1/sweeps")->status, 200);
    EXPECT_EQ(c.Post("/api/v1/sweeps", kDaemonExampleSweep, "application/json")->status, 201);
    d.Kill(SIGTERM);
  }
  Daemon again;
  ASSERT_FALSE(again.Start(Flags("127.0.0.1:0", /*no_token=*/false), Log()).has_value()) << ReadText(Log());
  EXPECT_THAT(again.printed(), HasSubstr("the contents of " + TokenPath()));
  httplib::Client c("127.0.0.1", again.port());
  c.set_bearer_token_auth(token);
  EXPECT_EQ(c.Get("/api/v1/sweeps")->status, 200);
  EXPECT_THAT(ReadText(Log()), HasSubstr("using the token in " + TokenPath()));
}

// Under umask 022, every file a fresh daemon makes is 0600 and every directory 0700, its database's
// WAL and shared memory too; a data directory an earlier daemon left readable by others is
// tightened at start, with a log line.
TEST_F(SandswimdTest, ItsFilesAreItsUsersAloneWhateverTheUmask) {
  namespace fs = std::filesystem;
  const mode_t old_umask = umask(022);
  fs::create_directories(dir_ + "/var/data/beds");
  std::ofstream(dir_ + "/var/data/beds/old.restart") << "x";  // 0644, 0755: an earlier daemon's
  Daemon d;
  auto exited = d.Start(Flags("127.0.0.1:0", /*no_token=*/false), Log());
  umask(old_umask);
  ASSERT_FALSE(exited.has_value()) << ReadText(Log());
  std::string token = ReadText(TokenPath());
  token.pop_back();
  httplib::Client c("127.0.0.1", d.port());
  c.set_bearer_token_auth(token);
  ASSERT_EQ(c.Post("/api/v1/sweeps", kDaemonExampleSweep, "application/json")->status, 201);
  auto mode = [](const std::string& path) {
    struct stat st {};
    return lstat(path.c_str(), &st) == 0 ? static_cast<int>(st.st_mode & 07777) : -1;
  };
  const std::string db = dir_ + "/var/sandswim.db";
  for (const std::string& file : {db, db + "-wal", db + "-shm", TokenPath(), dir_ + "/var/data/beds/old.restart"}) {
    EXPECT_EQ(mode(file), 0600) << file;
  }
  for (const std::string& sub : {"", "/beds", "/backups", "/uploads"}) {
    const std::string path = dir_ + "/var/data" + sub;
    if (fs::exists(path)) EXPECT_EQ(mode(path), 0700) << path;
  }
  EXPECT_THAT(ReadText(Log()), HasSubstr("private to this user"));
  d.Kill(SIGTERM);
}

// A token the operator gives must hold 128 bits; the refusal says how to make one.
TEST_F(SandswimdTest, AShortOperatorTokenIsRefusedAtStart) {
  const std::string file = dir_ + "/short-token";
  std::ofstream(file) << "s3cret\n";
  std::vector<std::string> flags = Flags("127.0.0.1:0", /*no_token=*/false);
  flags.insert(flags.end(), {"--token-file", file});
  Daemon d;
  auto exited = d.Start(flags, Log());
  ASSERT_TRUE(exited.has_value()) << "it started";
  EXPECT_TRUE(WIFEXITED(*exited) && WEXITSTATUS(*exited) != 0);
  EXPECT_THAT(ReadText(Log()), HasSubstr("openssl rand -hex 32"));
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/var/sandswim.db"));
}

// Wrong tokens: 401, one log line naming the peer and the route, and later ones slowed (counted
// in /metrics); the right token is not slowed by them.
TEST_F(SandswimdTest, WrongTokensAreRefusedLoggedAndSlowed) {
  Daemon d;
  ASSERT_FALSE(d.Start(Flags("127.0.0.1:0", /*no_token=*/false), Log()).has_value()) << ReadText(Log());
  httplib::Client c("127.0.0.1", d.port());
  for (int i = 0; i < 6; ++i) {
    auto r = c.Post("/api/v1/sweeps", {{"Authorization", "Bearer " + std::string(64, 'a' + i)}}, kDaemonExampleSweep,
                    "application/json");
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 401);
  }
  std::string token = ReadText(TokenPath());
  token.pop_back();
  auto metrics = c.Get("/metrics", {{"Authorization", "Bearer " + token}});
  ASSERT_EQ(metrics->status, 200);
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_auth_failures_total 6\n"));
  EXPECT_THAT(metrics->body, HasSubstr("sandswim_auth_delayed_total 3\n"));
  const std::string log = ReadText(Log());
  // Every loopback address is one peer (ClientKey): guesses spread over 127/8 are slowed together.
  EXPECT_THAT(log, HasSubstr("refused 1 request(s) with a wrong token from loopback (last: POST /api/v1/sweeps"));
  EXPECT_EQ(log.find("refused 2 request(s)"), std::string::npos) << "one line per peer per 10 s";
  EXPECT_EQ(log.find(std::string(64, 'a')), std::string::npos) << "the guesses are not logged";
}

// --no-token: only on loopback, and said loudly. A Host that is not the daemon's is refused.
TEST_F(SandswimdTest, NoTokenIsLoudAndAForeignHostIsRefused) {
  Daemon d;
  ASSERT_FALSE(d.Start(Flags(), Log()).has_value()) << ReadText(Log());
  EXPECT_THAT(ReadText(Log()), HasSubstr("serving WITHOUT A TOKEN"));
  EXPECT_FALSE(std::filesystem::exists(TokenPath()));
  httplib::Client c("127.0.0.1", d.port());
  auto r = c.Post("/api/v1/sweeps", {{"Host", "evil.example"}}, kDaemonExampleSweep, "application/json");
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 421);
  EXPECT_EQ(Parse(c.Get("/api/v1/sweeps"))["sweeps"].size(), 0u);
}

TEST_F(SandswimdTest, SigkillWithARunLeasedLosesNothingAndDoublesNothing) {
  Daemon first;
  ASSERT_FALSE(first.Start(Flags(), Log()).has_value());
  httplib::Client a("127.0.0.1", first.port());
  httplib::Headers key = {{"Idempotency-Key", "nightly-1"}};
  auto submitted = a.Post("/api/v1/sweeps", key, kDaemonExampleSweep, "application/json");
  ASSERT_EQ(submitted->status, 201) << submitted->body;
  int64_t sweep = Parse(submitted)["id"].get<int64_t>();

  // Prepare the bed, then lease the first run and heartbeat it.
  auto bed_lease = a.Post("/api/v1/leases", R"({"worker": "w1"})", "application/json");
  ASSERT_EQ(bed_lease->status, 200) << bed_lease->body;
  auto bed = Parse(bed_lease)["lease"].get<api::LeaseGrant>();
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  const std::string restart = "a bed restart";
  auto put = a.Put(("/api/v1/beds/" + std::to_string(bed.id) + "/restart?token=" + bed.token).c_str(),
                   {{"X-Sha256", Sha256Hex(restart)}}, restart, "application/octet-stream");
  ASSERT_EQ(put->status, 200) << put->body;
  api::Completion bed_done;
  bed_done.ok = true;
  bed_done.bed_result = api::BedResult{
      3700, 0, 0.22, true, 1e-4, Sha256Hex(restart), 13, std::nullopt, std::nullopt, std::nullopt, std::nullopt};
  ASSERT_EQ(
      a.Post(("/api/v1/leases/" + bed.token + "/complete").c_str(), json(bed_done).dump(), "application/json")->status,
      200);
  auto run_lease = a.Post("/api/v1/leases", R"({"worker": "w1"})", "application/json");
  ASSERT_EQ(run_lease->status, 200) << run_lease->body;
  auto run = Parse(run_lease)["lease"].get<api::LeaseGrant>();
  ASSERT_EQ(run.kind, api::JobKind::kRun);
  ASSERT_EQ(a.Post(("/api/v1/leases/" + run.token + "/heartbeat").c_str(), R"({"sim_time_s": 0.1})", "application/json")
                ->status,
            200);

  first.Kill(SIGKILL);

  Daemon second;
  ASSERT_FALSE(second.Start(Flags(), Log()).has_value());
  httplib::Client b("127.0.0.1", second.port());
  auto counts = Parse(b.Get(("/api/v1/sweeps/" + std::to_string(sweep)).c_str()))["counts"];
  EXPECT_EQ(counts["running"], 1);
  EXPECT_EQ(counts["queued"], 1);
  EXPECT_EQ(Parse(b.Get("/api/v1/runs"))["runs"].size(), 2u);
  auto download = b.Get(("/api/v1/beds/" + std::to_string(bed.id) + "/restart").c_str());
  ASSERT_EQ(download->status, 200);
  EXPECT_EQ(download->body, restart);

  // The same submission replays; it does not create a second sweep.
  auto replay = b.Post("/api/v1/sweeps", key, kDaemonExampleSweep, "application/json");
  ASSERT_EQ(replay->status, 201) << replay->body;
  EXPECT_EQ(Parse(replay)["id"], sweep);
  EXPECT_EQ(Parse(b.Get("/api/v1/sweeps"))["sweeps"].size(), 1u);

  // The lease from before the crash still holds: its completion counts, once.
  api::Completion done;
  done.ok = true;
  done.result = api::RunResult{};
  done.result->uz = 0.004;
  done.trajectory = api::Trajectory{{0, 0.3}, {0, 0}, {0, 0}, {0, 0.0012}};
  std::string complete = "/api/v1/leases/" + run.token + "/complete";
  auto completed = b.Post(complete.c_str(), json(done).dump(), "application/json");
  ASSERT_EQ(completed->status, 200) << completed->body;
  EXPECT_EQ(Parse(completed)["state"], "done");
  EXPECT_EQ(Parse(b.Post(complete.c_str(), json(done).dump(), "application/json"))["state"], "duplicate");

  // The other run is leased next, not the one that is done.
  auto next = b.Post("/api/v1/leases", R"({"worker": "w2"})", "application/json");
  ASSERT_EQ(next->status, 200) << next->body;
  auto other = Parse(next)["lease"].get<api::LeaseGrant>();
  EXPECT_EQ(other.kind, api::JobKind::kRun);
  EXPECT_NE(other.id, run.id);
  ASSERT_EQ(Parse(b.Post(("/api/v1/leases/" + other.token + "/complete").c_str(), json(done).dump(),
                         "application/json"))["state"],
            "done");
  EXPECT_EQ(b.Post("/api/v1/leases", R"({"worker": "w2"})", "application/json")->status, 204);

  auto results = Parse(b.Get(("/api/v1/sweeps/" + std::to_string(sweep) + "/results").c_str()))["results"];
  ASSERT_EQ(results.size(), 2u);
  for (const auto& row : results) EXPECT_DOUBLE_EQ(row["Uz"].get<double>(), 0.004);
  counts = Parse(b.Get(("/api/v1/sweeps/" + std::to_string(sweep)).c_str()))["counts"];
  EXPECT_EQ(counts["done"], 2);
  EXPECT_EQ(counts["running"], 0);

  // The daemon's figures are drawn by sandswim-render, installed next to it.
  auto figure = b.Get(("/api/v1/runs/" + std::to_string(run.id) + "/trajectory.svg").c_str());
  ASSERT_EQ(figure->status, 200) << figure->body;
  EXPECT_NE(figure->body.find("<svg"), std::string::npos);

  // SIGTERM is a clean exit.
  int status = second.Kill(SIGTERM);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
}

// Stopping the daemon stops its local worker; dying (SIGKILL), the daemon takes it down too. Either
// way the runs that worker held were not at fault: SIGTERM hands them back as the daemon stops, and
// after a SIGKILL the next daemon hands them back once their leases run out without a heartbeat --
// queued again, attempts uncounted. A worker of its own (any other name) that goes silent still
// costs its run an attempt. The leases are taken here over HTTP under the name the daemon gives its
// local worker (server/local_workers.h LocalWorkerName: "<host>:local-<daemon pid>"), so the test
// needs no engine; the daemon process, its signals and its restarts are the real ones.
TEST_F(SandswimdTest, ItsLocalWorkersRunsAreHandedBackWhetherItStopsOrDies) {
  char host_buffer[256] = {0};
  gethostname(host_buffer, sizeof host_buffer - 1);
  const std::string host = host_buffer;
  auto flags_with_ttl = [&](const std::string& ttl) {
    std::vector<std::string> f = Flags();
    for (size_t i = 0; i + 1 < f.size(); ++i)
      if (f[i] == "--lease-ttl") f[i + 1] = ttl;
    return f;
  };
  auto lease = [](httplib::Client& c, const std::string& worker) {
    auto r = c.Post("/api/v1/leases", json{{"worker", worker}, {"host", "h"}}.dump(), "application/json");
    EXPECT_EQ(r->status, 200) << r->body;
    return Parse(r)["lease"].get<api::LeaseGrant>();
  };
  auto run_of = [](httplib::Client& c, int64_t id) { return Parse(c.Get(("/api/v1/runs/" + std::to_string(id)).c_str())); };

  Daemon first;
  ASSERT_FALSE(first.Start(flags_with_ttl("600"), Log()).has_value());
  httplib::Client a("127.0.0.1", first.port());
  ASSERT_EQ(a.Post("/api/v1/sweeps", kDaemonExampleSweep, "application/json")->status, 201);
  auto bed = lease(a, "w1");
  ASSERT_EQ(bed.kind, api::JobKind::kBed);
  const std::string restart = "a bed restart";
  ASSERT_EQ(a.Put(("/api/v1/beds/" + std::to_string(bed.id) + "/restart?token=" + bed.token).c_str(),
                  {{"X-Sha256", Sha256Hex(restart)}}, restart, "application/octet-stream")
                ->status,
            200);
  api::Completion bed_done;
  bed_done.ok = true;
  bed_done.bed_result = api::BedResult{
      3700, 0, 0.22, true, 1e-4, Sha256Hex(restart), 13, std::nullopt, std::nullopt, std::nullopt, std::nullopt};
  ASSERT_EQ(
      a.Post(("/api/v1/leases/" + bed.token + "/complete").c_str(), json(bed_done).dump(), "application/json")->status,
      200);
  auto local = lease(a, host + ":local-" + std::to_string(first.pid()));
  ASSERT_EQ(local.kind, api::JobKind::kRun);

  // SIGTERM: the daemon hands back what its local worker left.
  int status = first.Kill(SIGTERM);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  // (A lease outlives a restart by at least the new TTL, never less than it had: 10 s here, so the
  // leases below hold until the SIGKILL however slow the machine, and run out soon after.)
  Daemon second;
  ASSERT_FALSE(second.Start(flags_with_ttl("10"), Log()).has_value());
  httplib::Client b("127.0.0.1", second.port());
  EXPECT_EQ(run_of(b, local.id)["state"], "queued");
  EXPECT_EQ(run_of(b, local.id)["attempts"], 0);

  // SIGKILL: the next daemon hands them back once their leases run out unheard.
  auto local2 = lease(b, host + ":local-" + std::to_string(second.pid()));
  ASSERT_EQ(local2.id, local.id);
  auto remote = lease(b, "node7:4242");
  ASSERT_EQ(remote.kind, api::JobKind::kRun);
  ASSERT_NE(remote.id, local.id);
  second.Kill(SIGKILL);
  Daemon third;
  ASSERT_FALSE(third.Start(flags_with_ttl("2"), Log()).has_value());
  httplib::Client c("127.0.0.1", third.port());
  auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while ((run_of(c, local.id)["state"] == "running" || run_of(c, remote.id)["state"] == "running") &&
         std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the daemon's own lease expiry, every second
  }
  json handed = run_of(c, local.id), expired = run_of(c, remote.id);
  EXPECT_EQ(handed["state"], "queued");
  EXPECT_EQ(handed["attempts"], 0) << handed.dump();
  EXPECT_EQ(expired["state"], "queued");
  EXPECT_EQ(expired["attempts"], 1) << expired.dump();
  EXPECT_EQ(expired["last_error"]["kind"], "lease_expired");
  std::ifstream log(Log());
  std::stringstream text;
  text << log.rdbuf();
  EXPECT_THAT(text.str(), HasSubstr("handed back 1 job(s) the local worker left running"));
  EXPECT_THAT(text.str(), HasSubstr("1 of the running job(s) were leased by the local workers of the daemon that stopped"));
  status = third.Kill(SIGTERM);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
}

}  // namespace
}  // namespace sandswim
