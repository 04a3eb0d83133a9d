// Files on the local disk that must be whole or absent: checksums and atomic writes, for the
// daemon (bed restarts, run snapshots) and the worker (its bed cache) alike.
//
// Thread safety: functions; two writers of one path leave one of their files, whole.
#ifndef SANDSWIM_PLATFORM_FILES_H_
#define SANDSWIM_PLATFORM_FILES_H_

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

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_FILES_H_
