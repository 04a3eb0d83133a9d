// End to end over HTTPS: the real sandswimd serving with a self-signed certificate it
// makes itself (--tls self-signed), a real sandswim-worker that pins the certificate's fingerprint
// and runs a smoke run with LIGGGHTS on the shared smoke bed (ctest's smoke_bed fixture, handed in
// through the worker protocol, over HTTPS too), and a worker with a wrong fingerprint that is
// refused before it leases anything.
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/deck.h"
#include "tests/engine_fixture.h"
#include "tests/service_fixture.h"

namespace sandswim {
namespace {

using nlohmann::json;
using testing::Daemon;
using ::testing::HasSubstr;

constexpr double kTimeoutS = 900;

TEST(EndToEndTlsTest, AWorkerPinningTheSelfSignedCertificateRunsASmokeRunAndAWrongPinIsRefused) {
  const std::string dir = testing::CacheDir() + "/e2e-tls";
  std::filesystem::remove_all(dir);
  Daemon daemon(dir + "/daemon", {"--tls", "self-signed"});
  ASSERT_EQ(daemon.url().rfind("https://", 0), 0u) << daemon.url();
  ASSERT_THAT(daemon.tls_fingerprint(), ::testing::MatchesRegex("SHA256(:[0-9A-F][0-9A-F]){32}"))
      << daemon.process().Output();
  struct stat key {};
  ASSERT_EQ(stat((dir + "/daemon/data/tls/key.pem").c_str(), &key), 0);
  EXPECT_EQ(key.st_mode & 0777, 0600u);

  int status = 0;
  json r = daemon.Post("/api/v1/sweeps", testing::OmegaSweep("over-tls", {-40}, 0.1), &status);
  ASSERT_EQ(status, 201) << r.dump();
  const int64_t id = r.value("id", int64_t{0});
  testing::HandInBeds(daemon, testing::PrepareBed(*FindScale("smoke")));

  // A wrong pin: the worker names both fingerprints, leases nothing and gives up when idle.
  std::string wrong = daemon.tls_fingerprint();
  wrong.back() = wrong.back() == '0' ? '1' : '0';
  auto refused = testing::StartWorker(daemon, dir + "/worker-wrong-pin", 1,
                                      {"--tls-fingerprint", wrong, "--exit-when-idle", "2"});
  for (int i = 0; i < 600 && refused->running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const std::string said = refused->Output();
  EXPECT_FALSE(refused->running()) << said;
  EXPECT_THAT(said, HasSubstr("not the pinned " + wrong)) << said;
  EXPECT_THAT(said, HasSubstr("presented a certificate with fingerprint " + daemon.tls_fingerprint())) << said;
  json runs = daemon.Get("/api/v1/runs?sweep=" + std::to_string(id))["runs"];
  ASSERT_EQ(runs.size(), 1u);
  EXPECT_EQ(runs[0]["state"], "queued") << runs.dump();
  EXPECT_EQ(runs[0].value("attempts", 0), 0) << runs.dump();

  auto worker = testing::StartWorker(daemon, dir + "/worker", 1);
  json sweep = daemon.WaitForSweep(id, kTimeoutS);
  EXPECT_EQ(sweep["counts"]["done"], 1) << sweep.dump() << "\nworker:\n" << worker->Output();
  json run = daemon.Get("/api/v1/runs/" + std::to_string(runs[0]["id"].get<int64_t>()));
  EXPECT_EQ(run["state"], "done") << run.dump();
  EXPECT_TRUE(run["result"].is_object()) << run.dump();
  worker->Stop();
}

}  // namespace
}  // namespace sandswim
