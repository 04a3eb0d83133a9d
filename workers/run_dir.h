// Run directories and the per-host bed cache.
//
// Each job runs in its own directory under the worker's workdir, named by kind, id and attempt
// ("run-42-a1", "bed-7-a2"), so two attempts of one job never share files. A fresh directory is
// made for every lease (left-overs of an earlier attempt under the same name are removed).
//
// BedCache keeps bed restart files once per host under <workdir>/beds/<sha256>.restart: a bed is
// downloaded once, and its SHA-256 is verified before every use. A run directory gets the bed as
// bed.restart (a hard link, or a copy across file systems). A checksum that does not match is
// Status Corruption whose reason starts with "bed_mismatch:". Hashing a paper-scale bed takes a
// while, so a file this cache has verified is not hashed again while its inode, size and
// modification time stay the same (any rewrite changes them).
//
// Several workers on one host may share a workdir, each with its own BedCache on the same beds/
// directory (hosts or containers may share it too): each downloads to a name of its own
// (<sha256>.restart.part.<host>.<pid>.<random 64 bits>), and a worker whose copy could not be put
// in place uses the one another worker stored if it verifies. A cache's first Provide removes the
// parts untouched for a day (downloads a crash cut short).
//
// Thread safety: RunDir is a value. BedCache is thread-safe (one download at a time per cache).
#ifndef SANDSWIM_WORKERS_RUN_DIR_H_
#define SANDSWIM_WORKERS_RUN_DIR_H_

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "core/api.h"
#include "core/status.h"
#include "platform/files.h"

namespace sandswim::worker {

class RunDir {
 public:
  // Creates <workdir>/<kind>-<id>-a<attempt>, empty.
  static Result<RunDir> Create(const std::string& workdir, api::JobKind kind, int64_t id, int attempt);

  const std::string& path() const { return path_; }
  std::string File(const std::string& name) const { return path_ + "/" + name; }
  // Writes text to a file in the directory (write to a temporary, then rename).
  Status Write(const std::string& name, const std::string& text) const;
  // Reads a file of the directory; NotFound when it is not there.
  Result<std::string> Read(const std::string& name) const;
  // Removes the directory and everything in it.
  Status Remove() const;

 private:
  explicit RunDir(std::string path) : path_(std::move(path)) {}
  std::string path_;
};

// A full-bed frame a drive deck wrote for a run's snapshots (core/deck.h): the periodic ones
// (kSnapshotFramePattern, '*' the step) and the last (kSnapshotLastFile).
struct SnapshotFrame {
  double t = 0;  // s: step * dt
  std::string path;
};
// The frames in `dir`, ascending t (the last frame's step read from its header; a periodic frame
// at the same step is the same bed and is left out). Frames still being written are listed too:
// read them once the engine has ended.
std::vector<SnapshotFrame> ListSnapshotFrames(const RunDir& dir, double dt);
// Deletes the periodic frames no snapshot can pick any more at time `t_now` of the run
// (core/snapshot.h SnapshotFramesStillNeeded), so a long run at a large scale does not keep
// every frame on disk. The newest frame is always kept (the engine may be writing it).
void DropUnneededSnapshotFrames(const RunDir& dir, double dt, const std::vector<double>& fractions, double t_now);

class BedCache {
 public:
  // Downloads the bed's restart to `dest` (the cache verifies it afterwards).
  using Download = std::function<Status(const api::BedRef& bed, const std::string& dest)>;

  BedCache(std::string dir, Download download) : dir_(std::move(dir)), download_(std::move(download)) {}

  // Puts the bed into `run_dir` as bed.restart, downloading it first if this host lacks it.
  Status Provide(const api::BedRef& bed, const RunDir& run_dir);

 private:
  struct FileStamp {
    unsigned long long ino = 0, size = 0;
    long long mtime_ns = 0;
    bool operator==(const FileStamp& o) const { return ino == o.ino && size == o.size && mtime_ns == o.mtime_ns; }
  };
  static bool Stamp(const std::string& path, FileStamp* stamp);
  // A name no other download on this host uses, where this one downloads `cached` to before it is verified and renamed.
  static std::string PartName(const std::string& cached);
  void RemoveStaleParts();  // REQUIRES: mu_ held

  std::string dir_;
  Download download_;
  std::mutex mu_;
  bool swept_ = false;  // the stale parts were removed (first Provide)
  std::map<std::string, FileStamp> verified_;  // sha256 -> stamp of the cached file when verified
};

}  // namespace sandswim::worker

#endif  // SANDSWIM_WORKERS_RUN_DIR_H_
