#include "tests/engine_fixture.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <gtest/gtest.h>

#include "core/deck.h"
#include "core/dump_reader.h"
#include "core/keys.h"

namespace sandswim::testing {
namespace fs = std::filesystem;

std::string ReadFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::string CacheDir() {
  if (const char* c = std::getenv("SANDSWIM_TEST_CACHE")) return c;
  return std::string(SANDSWIM_BINARY_DIR) + "/test-cache";
}

EngineRun RunDeck(const std::string& dir, const std::string& deck, const std::string& bed_restart, int ranks) {
  fs::create_directories(dir);
  std::ofstream(dir + "/deck.in", std::ios::binary) << deck;
  if (!bed_restart.empty()) {
    fs::remove(dir + "/" + kBedRestartFile);
    fs::create_symlink(fs::absolute(bed_restart), dir + "/" + kBedRestartFile);
  }
  // Real mpirun, as the worker uses it; root needs the two OMPI_ALLOW variables.
  std::string cmd =
      "cd '" + dir + "' && OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 mpirun --bind-to none -np " +
      std::to_string(ranks) + " liggghts -in deck.in -log " + kLogFile + " -screen /dev/null > engine.out 2>&1";
  EngineRun r;
  r.dir = dir;
  int st = std::system(cmd.c_str());
  r.exit_code = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  r.log = ReadFile(dir + "/" + kLogFile);
  return r;
}

std::string EngineVersion() {
  static const std::string version = [] {
    std::string dir = CacheDir() + "/version";
    fs::create_directories(dir);
    std::system(("cd '" + dir + "' && echo '' | liggghts -log none > version.txt 2>&1").c_str());
    std::string out = ReadFile(dir + "/version.txt");
    return out.substr(0, out.find('\n'));
  }();
  return version;
}

std::string PrepareBed(const Scale& scale, int replicate, int ranks) {
  const std::string deck = RenderBedDeck(scale, replicate);
  const std::string dir = CacheDir() + "/beds/" + BedKey(deck, EngineVersion()).substr(0, 16);
  const std::string restart = dir + "/" + kBedRestartFile;
  const std::string done = dir + "/done";
  fs::create_directories(dir);
  int fd = ::open((dir + "/lock").c_str(), O_CREAT | O_RDWR, 0644);
  if (fd < 0) throw std::runtime_error("cannot open bed lock in " + dir);
  ::flock(fd, LOCK_EX);
  if (!fs::exists(done)) {
    EngineRun r = RunDeck(dir, deck, "", ranks);
    if (r.exit_code != 0 || r.log.find("SANDSWIM bed done") == std::string::npos) {
      ::flock(fd, LOCK_UN);
      ::close(fd);
      throw std::runtime_error("bed preparation failed in " + dir + " (see log.liggghts there)");
    }
    std::ofstream(done) << "ok\n";
  }
  ::flock(fd, LOCK_UN);
  ::close(fd);
  return restart;
}

std::vector<SoFrame> ReadTrajectory(const std::string& run_dir) {
  DumpReader reader;
  DumpFrameCollector frames;
  EXPECT_TRUE(reader.Feed(ReadFile(run_dir + "/" + kTrajectoryDumpFile), frames).ok());
  EXPECT_TRUE(reader.Finish().ok());
  EXPECT_FALSE(reader.torn());
  std::vector<SoFrame> out;
  for (const DumpFrame& f : frames.Take()) {
    EXPECT_EQ(f.atoms, 1);
    auto c = [&](const char* name) { return f.At(0, f.Column(name)); };
    out.push_back({f.step * kMaterials.dt, c("x"), c("y"), c("z"), c("vy"), c("omegax"), c("omegay"), c("omegaz")});
  }
  return out;
}

EngineRun Drive(const std::string& name, const Point& p, const Scale& scale) {
  EXPECT_TRUE(Validate(p).ok());
  EXPECT_TRUE(FitsScale(p, scale).ok());
  const std::string dir = CacheDir() + "/physics/" + name;
  fs::remove_all(dir);
  EngineRun r = RunDeck(dir, RenderDriveDeck(p, scale, std::nullopt), PrepareBed(scale));
  EXPECT_EQ(r.exit_code, 0) << r.log.substr(r.log.size() > 2000 ? r.log.size() - 2000 : 0);
  return r;
}

}  // namespace sandswim::testing
