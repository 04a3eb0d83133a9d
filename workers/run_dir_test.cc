#include "workers/run_dir.h"

#include <signal.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/deck.h"
#include "core/keys.h"
#include "tests/fixture_file.h"

namespace sandswim::worker {
namespace {

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(RunDirTest, FreshDirectoryPerAttempt) {
  const std::string work = testing::TempDir("rundir");
  auto a = RunDir::Create(work, api::JobKind::kRun, 42, 1);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->path(), work + "/run-42-a1");
  ASSERT_TRUE(a->Write("drive.in", "deck text").ok());
  EXPECT_EQ(*a->Read("drive.in"), "deck text");
  EXPECT_EQ(a->Read("nope").status().code(), StatusCode::kNotFound);
  // The same name again starts empty.
  auto again = RunDir::Create(work, api::JobKind::kRun, 42, 1);
  ASSERT_TRUE(again.ok());
  EXPECT_FALSE(std::filesystem::exists(work + "/run-42-a1/drive.in"));
  auto bed = RunDir::Create(work, api::JobKind::kBed, 3, 2);
  EXPECT_EQ(bed->path(), work + "/bed-3-a2");
  ASSERT_TRUE(bed->Remove().ok());
  EXPECT_FALSE(std::filesystem::exists(work + "/bed-3-a2"));
}

TEST(RunDirTest, Sha256OfFileMatchesCore) {
  const std::string work = testing::TempDir("rundir");
  std::ofstream(work + "/f", std::ios::binary) << std::string(3 << 20, 'x');
  auto sha = Sha256OfFile(work + "/f");
  ASSERT_TRUE(sha.ok());
  EXPECT_EQ(*sha, Sha256Hex(std::string(3 << 20, 'x')));
}

TEST(BedCacheTest, DownloadsOnceVerifiesEveryUseAndRefusesMismatch) {
  const std::string work = testing::TempDir("rundir");
  std::string served = "bed bytes";
  int downloads = 0;
  BedCache cache(work + "/beds", [&](const api::BedRef&, const std::string& dest) {
    ++downloads;
    std::ofstream(dest, std::ios::binary) << served;
    return Status::Ok();
  });
  api::BedRef bed{1, Sha256Hex("bed bytes"), "", ""};
  auto r1 = RunDir::Create(work, api::JobKind::kRun, 1, 1);
  auto r2 = RunDir::Create(work, api::JobKind::kRun, 2, 1);
  ASSERT_TRUE(cache.Provide(bed, *r1).ok());
  ASSERT_TRUE(cache.Provide(bed, *r2).ok());
  EXPECT_EQ(downloads, 1);
  EXPECT_EQ(ReadAll(r2->File("bed.restart")), "bed bytes");

  // A cached copy damaged on disk is noticed and fetched again.
  std::ofstream(work + "/beds/" + bed.sha256 + ".restart", std::ios::binary) << "damaged";
  auto r3 = RunDir::Create(work, api::JobKind::kRun, 3, 1);
  ASSERT_TRUE(cache.Provide(bed, *r3).ok());
  EXPECT_EQ(downloads, 2);
  EXPECT_EQ(ReadAll(r3->File("bed.restart")), "bed bytes");

  // The daemon serves bytes that do not match the lease: refused, nothing cached.
  served = "other bytes";
  api::BedRef other{2, Sha256Hex("expected bytes"), ""};
  auto r4 = RunDir::Create(work, api::JobKind::kRun, 4, 1);
  Status s = cache.Provide(other, *r4);
  EXPECT_EQ(s.code(), StatusCode::kCorruption);
  EXPECT_EQ(s.reason().rfind("bed_mismatch:", 0), 0u) << s.reason();
  EXPECT_FALSE(std::filesystem::exists(r4->File("bed.restart")));
  EXPECT_FALSE(std::filesystem::exists(work + "/beds/" + other.sha256 + ".restart"));
}

TEST(BedCacheTest, DownloadFailureIsPassedOn) {
  const std::string work = testing::TempDir("rundir");
  BedCache cache(work + "/beds",
                 [](const api::BedRef&, const std::string&) { return Status::NotFound("GET bed: HTTP 404"); });
  auto r = RunDir::Create(work, api::JobKind::kRun, 1, 1);
  EXPECT_EQ(cache.Provide(api::BedRef{1, std::string(64, 'a'), ""}, *r).code(), StatusCode::kNotFound);
}

// Two workers sharing one workdir, each with its own cache on the same beds/ directory, fetch the
// same bed at once: the second one's download runs while the first one's is half written. Before,
// both wrote <sha>.restart.part, the second removed and rewrote the first's file, and one of them
// failed the run "cannot store the bed ... No such file or directory" (seen on a real run).
TEST(BedCacheTest, TwoCachesOnOneDirectoryFetchingTheSameBedBothSucceed) {
  const std::string work = testing::TempDir("rundir-shared");
  const std::string bytes(1 << 20, 'b');
  api::BedRef bed{1, Sha256Hex(bytes), "", ""};
  int downloads = 0;
  BedCache second(work + "/beds", [&](const api::BedRef&, const std::string& dest) {
    ++downloads;
    std::ofstream(dest, std::ios::binary) << bytes;
    return Status::Ok();
  });
  auto r2 = RunDir::Create(work, api::JobKind::kRun, 2, 1);
  Status inner = Status::Internal("not called");
  BedCache first(work + "/beds", [&](const api::BedRef& b, const std::string& dest) {
    ++downloads;
    std::ofstream out(dest, std::ios::binary);
    out << bytes.substr(0, bytes.size() / 2) << std::flush;
    inner = second.Provide(b, *r2);  // the other worker fetches and stores it meanwhile
    out << bytes.substr(bytes.size() / 2);
    return Status::Ok();
  });
  auto r1 = RunDir::Create(work, api::JobKind::kRun, 1, 1);
  Status outer = first.Provide(bed, *r1);
  EXPECT_TRUE(inner.ok()) << inner.ToString();
  EXPECT_TRUE(outer.ok()) << outer.ToString();
  EXPECT_EQ(downloads, 2);
  EXPECT_EQ(ReadAll(r1->File("bed.restart")), bytes);
  EXPECT_EQ(ReadAll(r2->File("bed.restart")), bytes);
  // Nothing half-downloaded is left behind.
  for (const auto& entry : std::filesystem::directory_iterator(work + "/beds")) {
    EXPECT_EQ(entry.path().filename().string(), bed.sha256 + ".restart");
  }
}

// When this worker's copy vanished before it could be stored (another worker cleaned it away) but
// the bed is in the cache and verifies, that copy is used; when it is not there, the error says so.
TEST(BedCacheTest, AVanishedDownloadIsReplacedByAStoredCopyThatVerifies) {
  const std::string work = testing::TempDir("rundir-vanished");
  api::BedRef bed{1, Sha256Hex("bed bytes"), "", ""};
  const std::string cached = work + "/beds/" + bed.sha256 + ".restart";
  bool store_meanwhile = true;
  BedCache cache(work + "/beds", [&](const api::BedRef&, const std::string& dest) {
    if (store_meanwhile) std::ofstream(cached, std::ios::binary) << "bed bytes";
    std::filesystem::remove(dest);
    return Status::Ok();
  });
  auto r1 = RunDir::Create(work, api::JobKind::kRun, 1, 1);
  EXPECT_TRUE(cache.Provide(bed, *r1).ok());
  EXPECT_EQ(ReadAll(r1->File("bed.restart")), "bed bytes");

  std::filesystem::remove(cached);
  store_meanwhile = false;
  auto r2 = RunDir::Create(work, api::JobKind::kRun, 2, 1);
  Status s = cache.Provide(bed, *r2);
  EXPECT_EQ(s.code(), StatusCode::kIOError);
  EXPECT_NE(s.reason().find("cannot store the bed in " + cached), std::string::npos) << s.reason();
}

// A download's part is named for its host, process and a random 64-bit value (pids repeat
// across containers and hosts sharing a workdir); parts untouched for a day (a crash cut them
// short) are removed when the cache first provides a bed, younger ones (maybe live) are kept.
TEST(BedCacheTest, APartNamesItsHostAndStalePartsAreRemoved) {
  const std::string work = testing::TempDir("rundir-parts");
  const std::string beds = work + "/beds";
  std::filesystem::create_directories(beds);
  const std::string stale = beds + "/" + std::string(64, 'c') + ".restart.part.otherhost.77.0123456789abcdef";
  const std::string young = beds + "/" + std::string(64, 'd') + ".restart.part.otherhost.78.fedcba9876543210";
  const std::string other = beds + "/notes.txt";
  for (const std::string& f : {stale, young, other}) std::ofstream(f) << "x";
  std::filesystem::last_write_time(stale, std::filesystem::file_time_type::clock::now() - std::chrono::hours(25));
  std::filesystem::last_write_time(other, std::filesystem::file_time_type::clock::now() - std::chrono::hours(25));
  std::vector<std::string> parts;
  BedCache cache(beds, [&](const api::BedRef&, const std::string& dest) {
    parts.push_back(dest);
    std::ofstream(dest, std::ios::binary) << "bed bytes";
    return Status::Ok();
  });
  const api::BedRef bed{1, Sha256Hex("bed bytes"), "", ""};
  auto r1 = RunDir::Create(work, api::JobKind::kRun, 1, 1);
  ASSERT_TRUE(cache.Provide(bed, *r1).ok());
  EXPECT_FALSE(std::filesystem::exists(stale));
  EXPECT_TRUE(std::filesystem::exists(young));
  EXPECT_TRUE(std::filesystem::exists(other));
  char host[256] = {};
  ASSERT_EQ(gethostname(host, sizeof(host) - 1), 0);
  std::filesystem::remove(beds + "/" + bed.sha256 + ".restart");
  auto r2 = RunDir::Create(work, api::JobKind::kRun, 2, 1);
  ASSERT_TRUE(cache.Provide(bed, *r2).ok());
  ASSERT_EQ(parts.size(), 2u);
  const std::string prefix = beds + "/" + bed.sha256 + ".restart.part." + host + "." + std::to_string(getpid()) + ".";
  for (const std::string& p : parts) {
    ASSERT_EQ(p.rfind(prefix, 0), 0u) << p;
    EXPECT_EQ(p.size() - prefix.size(), 16u) << p;  // 64 bits in hex
  }
  EXPECT_NE(parts[0], parts[1]);
}

// Two processes fetching one bed into one directory, each held half-written inside its download
// until the other has started its own (a pipe each way); `second_dies` makes the second exit
// before it starts. Each process closes the pipe ends it does not use, and so does the test, so a
// process whose twin died reads end-of-file instead of waiting for ever. Their exit statuses
// (waitpid's), or -1 for one still running after 30 s (then killed).
std::vector<int> TwoProcessesFetch(const std::string& work, const std::string& bytes, bool second_dies) {
  const api::BedRef bed{1, Sha256Hex(bytes), "", ""};
  int to_a[2], to_b[2];
  if (pipe(to_a) != 0 || pipe(to_b) != 0) return {};
  auto child = [&](int id, int signal_fd, int wait_fd, bool dies) -> pid_t {
    const pid_t pid = fork();
    if (pid != 0) return pid;
    signal(SIGPIPE, SIG_IGN);  // a write to a dead twin fails instead of killing this process
    for (int fd : {to_a[0], to_a[1], to_b[0], to_b[1]})
      if (fd != signal_fd && fd != wait_fd) close(fd);
    if (dies) _exit(3);
    BedCache cache(work + "/beds", [&](const api::BedRef&, const std::string& dest) {
      std::ofstream out(dest, std::ios::binary);
      out << bytes.substr(0, bytes.size() / 2) << std::flush;
      char c = 'x';
      if (write(signal_fd, &c, 1) != 1 || read(wait_fd, &c, 1) != 1) return Status::IOError("pipe");
      out << bytes.substr(bytes.size() / 2);
      return Status::Ok();
    });
    auto dir = RunDir::Create(work, api::JobKind::kRun, id, 1);
    const bool ok = dir.ok() && cache.Provide(bed, *dir).ok() && ReadAll(dir->File("bed.restart")) == bytes;
    _exit(ok ? 0 : 1);
  };
  const pid_t a = child(1, to_b[1], to_a[0], false);
  const pid_t b = child(2, to_a[1], to_b[0], second_dies);
  for (int fd : {to_a[0], to_a[1], to_b[0], to_b[1]}) close(fd);
  std::vector<int> statuses;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  for (pid_t pid : {a, b}) {
    int status = -1;
    if (pid <= 0) {
      statuses.push_back(-1);
      continue;
    }
    while (waitpid(pid, &status, WNOHANG) == 0) {
      if (std::chrono::steady_clock::now() > deadline) {
        kill(pid, SIGKILL);
        waitpid(pid, nullptr, 0);
        status = -1;
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    statuses.push_back(status);
  }
  return statuses;
}

bool ExitedWith(int status, int code) { return status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == code; }

// The same race between two processes: both are inside their download at once, then both finish.
TEST(BedCacheTest, TwoProcessesFetchingTheSameBedBothSucceed) {
  const std::vector<int> s = TwoProcessesFetch(testing::TempDir("rundir-procs"), std::string(4 << 20, 'p'), false);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_TRUE(ExitedWith(s[0], 0)) << "first worker process: status " << s[0];
  EXPECT_TRUE(ExitedWith(s[1], 0)) << "second worker process: status " << s[1];
}

// A process whose twin dies before it signals fails its download at once (it waited for ever
// while the test and its twin held the pipe's write end open).
TEST(BedCacheTest, AProcessWhoseTwinDiesFailsItsDownloadInsteadOfHanging) {
  const std::vector<int> s = TwoProcessesFetch(testing::TempDir("rundir-procs-dies"), std::string(1 << 10, 'p'), true);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_TRUE(ExitedWith(s[0], 1)) << "first worker process: status " << s[0] << " (-1: hung, killed)";
  EXPECT_TRUE(ExitedWith(s[1], 3)) << "second worker process: status " << s[1];
}

}  // namespace

// The frames a drive deck wrote for a run's snapshots, in time order, the last one at its own step
// (and a periodic frame at that step left out); frames no fraction can pick any more are dropped
// as the run goes, the newest never.
TEST(RunDirTest, SnapshotFramesAreListedAndTheUnneededDropped) {
  const std::string work = testing::TempDir("rundir-frames");
  auto dir = RunDir::Create(work, api::JobKind::kRun, 7, 1);
  ASSERT_TRUE(dir.ok());
  for (int step : {0, 1000, 2000, 3000, 4000}) {
    ASSERT_TRUE(dir->Write("frame." + std::to_string(step) + ".dump", "ITEM: TIMESTEP\n" + std::to_string(step) + "\n").ok());
  }
  ASSERT_TRUE(dir->Write("frame.x.dump", "not a frame of ours").ok());
  const double dt = 1e-5;
  std::vector<SnapshotFrame> frames = ListSnapshotFrames(*dir, dt);
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_DOUBLE_EQ(frames[2].t, 0.02);
  // At t = 0.04 s, the middle (0.5) can only be the frame at 0.02 s or later; the start stays.
  DropUnneededSnapshotFrames(*dir, dt, {0, 0.5}, 0.04);
  frames = ListSnapshotFrames(*dir, dt);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_DOUBLE_EQ(frames[0].t, 0.0);
  EXPECT_DOUBLE_EQ(frames[1].t, 0.02);
  // The last frame, written where the run ended (at a step a periodic frame also has).
  ASSERT_TRUE(dir->Write(kSnapshotLastFile, "ITEM: TIMESTEP\n4000\n").ok());
  frames = ListSnapshotFrames(*dir, dt);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames.back().path, dir->File(kSnapshotLastFile));
  EXPECT_DOUBLE_EQ(frames.back().t, 0.04);
}

}  // namespace sandswim::worker
