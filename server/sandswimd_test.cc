// The real sandswimd binary on an ephemeral port with a temp SQLite file: it serves, refuses to
// listen beyond loopback without a token, and survives SIGKILL with a run leased — after a
// restart on the same file nothing is lost (the lease, the bed, the Idempotency-Key) and nothing
// is doubled (no second run, no second result).
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <string>
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

 private:
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

  std::vector<std::string> Flags(const std::string& listen = "127.0.0.1:0") {
    return {"--db",
            dir_ + "/var/sandswim.db",
            "--data",
            dir_ + "/var/data",
            "--listen",
            listen,
            "--engine-version",
            "LIGGGHTS (Version test)",
            "--lease-ttl",
            "600"};
  }
  std::string Log() { return dir_ + "/sandswimd.log"; }

  std::string dir_;
};

json Parse(const httplib::Result& r) { return json::parse(r->body); }

TEST_F(SandswimdTest, RefusesANonLoopbackAddressWithoutAToken) {
  Daemon d;
  auto exited = d.Start(Flags("0.0.0.0:0"), Log());
  ASSERT_TRUE(exited.has_value()) << "it started";
  EXPECT_TRUE(WIFEXITED(*exited) && WEXITSTATUS(*exited) != 0);
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/var/sandswim.db"));
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

}  // namespace
}  // namespace sandswim
