#include "platform/data_dir.h"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "platform/tls.h"
#include "platform/token.h"

namespace sandswim {
namespace {

// The layout as the daemon has always spelled it (`DATA + "/token"`, `path(DATA) / "beds"`, ...):
// a data directory an earlier version made keeps working.
TEST(DataDirTest, SpellsEveryPathAsTheDaemonAlwaysHas) {
  const DataDir data("/srv/sandswim");
  EXPECT_EQ(data.Token(), "/srv/sandswim/token");
  EXPECT_EQ(data.Tls(), "/srv/sandswim/tls");
  EXPECT_EQ(SelfSignedCertificate(data.Tls()), "/srv/sandswim/tls/cert.pem");
  EXPECT_EQ(data.Beds(), "/srv/sandswim/beds");
  EXPECT_EQ(data.BedRestart("ab12"), "/srv/sandswim/beds/ab12.restart");
  EXPECT_EQ(data.Snapshots(), "/srv/sandswim/snapshots");
  EXPECT_EQ(data.RunSnapshots(7), "/srv/sandswim/snapshots/run-7");
  EXPECT_EQ(data.Snapshot(7, 2), "/srv/sandswim/snapshots/run-7/2.dump");
  EXPECT_EQ(data.Figures(), "/srv/sandswim/figures");
  EXPECT_EQ(data.Backups(), "/srv/sandswim/backups");
  EXPECT_EQ(data.Uploads(), "/srv/sandswim/uploads");
  EXPECT_EQ(data.Worker(), "/srv/sandswim/worker");
  // The default --data, relative, as the CLI looks for its token.
  EXPECT_EQ(DataDir(kDefaultDataDir).Token(), "./var/data/token");
  // A root written with a trailing slash names the same files.
  EXPECT_EQ(DataDir("/srv/sandswim/").Snapshot(7, 2), data.Snapshot(7, 2));
}

// Files laid out by hand where an earlier daemon put them are the ones the paths name.
TEST(DataDirTest, FindsTheFilesOfAnExistingDataDirectory) {
  namespace fs = std::filesystem;
  const fs::path root = fs::temp_directory_path() / ("sandswim-data-dir-" + std::to_string(::getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "snapshots" / "run-3");
  fs::create_directories(root / "beds");
  std::ofstream(root / "token") << "an-old-token";
  std::ofstream(root / "beds" / "k.restart") << "restart";
  std::ofstream(root / "snapshots" / "run-3" / "0.dump") << "dump";
  const DataDir data(root.string());
  std::string token;
  std::ifstream(data.Token()) >> token;
  EXPECT_EQ(token, "an-old-token");
  EXPECT_TRUE(fs::equivalent(data.BedRestart("k"), root / "beds" / "k.restart"));
  EXPECT_TRUE(fs::equivalent(data.Snapshot(3, 0), root / "snapshots" / "run-3" / "0.dump"));
  fs::remove_all(root);
}

}  // namespace
}  // namespace sandswim
