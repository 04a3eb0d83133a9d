#include "workers/run_dir.h"

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <sstream>
#include <system_error>
#include <vector>

#include <spdlog/spdlog.h>

#include "core/deck.h"
#include "core/snapshot.h"

namespace sandswim::worker {
namespace fs = std::filesystem;

Result<RunDir> RunDir::Create(const std::string& workdir, api::JobKind kind, int64_t id, int attempt) {
  const std::string name =
      std::string(kind == api::JobKind::kBed ? "bed-" : "run-") + std::to_string(id) + "-a" + std::to_string(attempt);
  const std::string path = workdir + "/" + name;
  std::error_code ec;
  fs::remove_all(path, ec);
  if (ec) return Status::IOError("cannot clear " + path + ": " + ec.message());
  fs::create_directories(path, ec);
  if (ec) return Status::IOError("cannot create " + path + ": " + ec.message());
  return RunDir(path);
}

Status RunDir::Write(const std::string& name, const std::string& text) const {
  const std::string tmp = File(name + ".tmp");
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) return Status::IOError("cannot write " + tmp);
  }
  std::error_code ec;
  fs::rename(tmp, File(name), ec);
  if (ec) return Status::IOError("cannot rename " + tmp + ": " + ec.message());
  return Status::Ok();
}

Result<std::string> RunDir::Read(const std::string& name) const {
  std::ifstream in(File(name), std::ios::binary);
  if (!in) return Status::NotFound(File(name) + " does not exist");
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

std::vector<SnapshotFrame> ListSnapshotFrames(const RunDir& dir, double dt) {
  const std::string pattern = kSnapshotFramePattern;
  const size_t star = pattern.find('*');
  const std::string prefix = pattern.substr(0, star), suffix = pattern.substr(star + 1);
  std::vector<std::pair<long long, std::string>> by_step;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(dir.path(), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.size() <= prefix.size() + suffix.size() || name.rfind(prefix, 0) != 0 ||
        name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0)
      continue;
    const std::string digits = name.substr(prefix.size(), name.size() - prefix.size() - suffix.size());
    if (digits.size() > 18 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    by_step.emplace_back(std::stoll(digits), entry.path().string());
  }
  // The last frame: its step is the line after "ITEM: TIMESTEP".
  std::ifstream last(dir.File(kSnapshotLastFile));
  std::string item, step_line;
  if (last && std::getline(last, item) && std::getline(last, step_line) && item.rfind("ITEM: TIMESTEP", 0) == 0) {
    const long long step = std::strtoll(step_line.c_str(), nullptr, 10);
    by_step.erase(std::remove_if(by_step.begin(), by_step.end(), [&](const auto& f) { return f.first == step; }),
                  by_step.end());
    by_step.emplace_back(step, dir.File(kSnapshotLastFile));
  }
  std::sort(by_step.begin(), by_step.end());
  std::vector<SnapshotFrame> frames;
  for (const auto& [step, path] : by_step) frames.push_back({static_cast<double>(step) * dt, path});
  return frames;
}

void DropUnneededSnapshotFrames(const RunDir& dir, double dt, const std::vector<double>& fractions, double t_now) {
  const std::vector<SnapshotFrame> frames = ListSnapshotFrames(dir, dt);
  if (frames.size() < 2) return;
  std::vector<double> frame_t;
  for (const SnapshotFrame& f : frames) frame_t.push_back(f.t);
  const std::vector<bool> keep = SnapshotFramesStillNeeded(frame_t, fractions, t_now);
  std::error_code ec;
  for (size_t i = 0; i + 1 < frames.size(); ++i)
    if (!keep[i]) fs::remove(frames[i].path, ec);
}

Status RunDir::Remove() const {
  std::error_code ec;
  fs::remove_all(path_, ec);
  if (ec) return Status::IOError("cannot remove " + path_ + ": " + ec.message());
  return Status::Ok();
}

std::string BedCache::PartName(const std::string& cached) {
  // The host and pid tell processes apart where hosts or containers share the workdir (pids
  // repeat across them); a random 64-bit value makes the name unique even where both repeat.
  char host[256] = {};
  if (gethostname(host, sizeof(host) - 1) != 0 || host[0] == '\0') std::snprintf(host, sizeof(host), "host");
  static std::mutex mu;
  static std::mt19937_64 random{(static_cast<uint64_t>(std::random_device{}()) << 32) ^ std::random_device{}()};
  uint64_t r;
  {
    std::lock_guard<std::mutex> lock(mu);
    r = random();
  }
  char hex[17];
  std::snprintf(hex, sizeof(hex), "%016llx", static_cast<unsigned long long>(r));
  return cached + ".part." + host + "." + std::to_string(getpid()) + "." + hex;
}

void BedCache::RemoveStaleParts() {
  // A download cut short by a crash leaves its part behind under a name nobody will use again.
  // One untouched for a day is no live download's (a bed downloads in minutes).
  std::error_code ec;
  const auto now = fs::file_time_type::clock::now();
  for (const fs::directory_entry& e : fs::directory_iterator(dir_, ec)) {
    const std::string name = e.path().filename().string();
    if (name.find(".restart.part.") == std::string::npos) continue;
    std::error_code time_ec;
    const auto written = fs::last_write_time(e.path(), time_ec);
    if (time_ec || now - written < std::chrono::hours(24)) continue;
    std::error_code rm_ec;
    if (fs::remove(e.path(), rm_ec)) spdlog::info("removed {}, a bed download left unfinished over a day ago", name);
  }
}

bool BedCache::Stamp(const std::string& path, FileStamp* stamp) {
  struct stat st;
  if (stat(path.c_str(), &st) != 0) return false;
  stamp->ino = st.st_ino;
  stamp->size = static_cast<unsigned long long>(st.st_size);
  stamp->mtime_ns = static_cast<long long>(st.st_mtim.tv_sec) * 1000000000LL + st.st_mtim.tv_nsec;
  return true;
}

Status BedCache::Provide(const api::BedRef& bed, const RunDir& run_dir) {
  if (bed.sha256.size() != 64) {
    return Status::Corruption("bed_mismatch: bed " + std::to_string(bed.id) + " has no valid sha256 in its lease");
  }
  std::lock_guard<std::mutex> lock(mu_);
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) return Status::IOError("cannot create the bed cache " + dir_ + ": " + ec.message());
  if (!swept_) {
    swept_ = true;
    RemoveStaleParts();
  }
  const std::string cached = dir_ + "/" + bed.sha256 + ".restart";
  FileStamp stamp;
  auto known = verified_.find(bed.sha256);
  bool ok = known != verified_.end() && Stamp(cached, &stamp) && stamp == known->second;
  if (!ok) {
    auto have = Sha256OfFile(cached);
    ok = have.ok() && *have == bed.sha256;
  }
  if (!ok) {
    // Missing, or damaged since it was stored: fetch it (again). Other workers on this host may
    // share the directory and fetch the same bed at the same time, so each download has a name of
    // its own (process and call) and only a finished, verified file is renamed into place; the
    // rename replaces the cached file atomically, and every finisher puts the same bytes there.
    const std::string tmp = PartName(cached);
    fs::remove(tmp, ec);
    if (Status s = download_(bed, tmp); !s.ok()) {
      fs::remove(tmp, ec);
      return s;
    }
    auto got = Sha256OfFile(tmp);
    if (got.ok() && *got != bed.sha256) {
      fs::remove(tmp, ec);
      return Status::Corruption("bed_mismatch: bed " + std::to_string(bed.id) + " downloaded with sha256 " + *got +
                                ", the lease says " + bed.sha256);
    }
    if (got.ok()) fs::rename(tmp, cached, ec);
    if (!got.ok() || ec) {
      // Our copy is gone or could not be put in place. When another worker has stored the bed
      // meanwhile, that one serves as well as ours.
      const std::string why = got.ok() ? ec.message() : got.status().reason();
      fs::remove(tmp, ec);
      auto have = Sha256OfFile(cached);
      if (!have.ok() || *have != bed.sha256) {
        return Status::IOError("cannot store the bed in " + cached + ": " + why);
      }
    }
  }
  if (Stamp(cached, &stamp)) verified_[bed.sha256] = stamp;
  const std::string dest = run_dir.File(kBedRestartFile);
  fs::remove(dest, ec);
  fs::create_hard_link(cached, dest, ec);
  if (ec) {
    ec.clear();
    fs::copy_file(cached, dest, fs::copy_options::overwrite_existing, ec);
    if (ec) return Status::IOError("cannot put the bed into " + dest + ": " + ec.message());
    // A copy is a new file: check it as well.
    auto copied = Sha256OfFile(dest);
    if (!copied.ok() || *copied != bed.sha256) {
      return Status::Corruption("bed_mismatch: the copy of bed " + std::to_string(bed.id) + " differs");
    }
  }
  return Status::Ok();
}

}  // namespace sandswim::worker
