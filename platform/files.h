// Files on the local disk that must be whole or absent: checksums and atomic writes, for the
// daemon (bed restarts, run snapshots) and the worker (its bed cache) alike.
//
// Thread safety: functions; two writers of one path leave one of their files, whole.
#ifndef SANDSWIM_PLATFORM_FILES_H_
#define SANDSWIM_PLATFORM_FILES_H_

#include <cstdint>
#include <string>
#include <string_view>

#include "core/status.h"

namespace sandswim {

// SHA-256 (lower-case hex) of a file's bytes, read a megabyte at a time; NotFound when the file
// is not there.
Result<std::string> Sha256OfFile(const std::string& path);

// The bytes of a file; IOError "cannot read PATH" when it cannot be opened or read.
Result<std::string> ReadWholeFile(const std::string& path);

// Writes `bytes` to `path` through a temporary file beside it (fsync, then rename), so a reader
// never sees half a file; makes the directory if needed. IOError saying what failed.
Status WriteFileAtomically(const std::string& path, std::string_view bytes);

// Puts `bytes` at `path` as WriteFileAtomically does, but when `from` names a file that holds
// exactly those bytes (an upload received into a scratch file on the same disk), that file is
// synced and renamed into place: written once, never copied. `from` is gone afterwards. A rename
// the file system refuses (another disk) falls back to writing `bytes`.
Status PlaceFile(const std::string& path, std::string_view bytes, const std::string& from);

// Takes group's and others' permissions away from `path` and, when it is a directory, from every
// entry under it: a directory ends at most 0700, a file at most 0600 (symbolic links are neither
// followed nor changed). For a data directory made by an earlier version, or under a loose umask,
// before the daemon opens it. Returns how many entries it changed (0 when nothing is at `path`);
// IOError naming an entry it could not change.
Result<int> RestrictToOwner(const std::string& path);

// What tells one file from another at a path without reading it: a file renamed over it, or
// rewritten, has another identity.
struct FileIdentity {
  uint64_t device = 0;
  uint64_t inode = 0;
  int64_t size = 0;
  int64_t mtime_ns = 0;
  bool operator==(const FileIdentity& o) const {
    return device == o.device && inode == o.inode && size == o.size && mtime_ns == o.mtime_ns;
  }
  bool operator!=(const FileIdentity& o) const { return !(*this == o); }
};
// kNotFound when nothing is at `path`.
Result<FileIdentity> IdentifyFile(const std::string& path);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_FILES_H_
