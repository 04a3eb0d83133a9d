// The bearer token the daemon, its workers and the CLI share: where it comes from, how strong it
// must be, and where the daemon keeps the one it makes for itself.
//
// The daemon (sandswimd) takes its token from, in this order:
//   1. --token-file FILE (LoadToken: the file's contents, surrounding whitespace trimmed);
//   2. $SANDSWIM_TOKEN (trimmed);
//   3. else DATA/token (DataDir::Token): read when it exists, else made on this first start
//      (GenerateToken: 32 random bytes from OpenSSL's RAND_bytes, 64 hex digits) and written with
//      mode 0600 (LoadOrCreateTokenFile); later starts reuse it.
// --no-token (loopback only) serves without one. A token the operator gives (1 or 2) must hold at
// least 128 bits (CheckTokenStrength): 32 hexadecimal digits, or 22 characters of any other kind
// (base64 of 16 random bytes). `openssl rand -hex 32` makes one.
//
// A client (the CLI, a worker) finds the token with LoadClientToken, in this order: --token-file,
// $SANDSWIM_TOKEN, else -- only when the daemon's URL names a loopback host, so the token never goes
// to another machine -- the default data directory's token file, ./var/data/token (the file a
// daemon started with its default --data made), when it exists. The daemon hands its own local
// workers --token-file with the file it read.
//
// Thread safety: reads and writes files and reads the environment; no shared state.
#ifndef SANDSWIM_PLATFORM_TOKEN_H_
#define SANDSWIM_PLATFORM_TOKEN_H_

#include <cstdlib>
#include <functional>
#include <string>

#include "core/status.h"
#include "platform/data_dir.h"

namespace sandswim {

// sandswimd's default --data; its token file is the one clients look for when told nothing.
inline constexpr const char* kDefaultDataDir = "./var/data";
// Random bytes in a token the daemon makes (256 bits).
inline constexpr int kGeneratedTokenBytes = 32;

// `token_file`'s contents when it is set (an unreadable or empty file is an error naming
// "--token-file"), else $SANDSWIM_TOKEN, else "". `getenv` is injectable for tests.
Result<std::string> LoadToken(const std::string& token_file,
                              const std::function<const char*(const char*)>& getenv = std::getenv);

// At least 128 bits: 32 or more characters when every one is a hexadecimal digit, else 22 or
// more. An error (naming `field`) says how to make a good one.
Status CheckTokenStrength(const std::string& token, const std::string& field);

// 64 hexadecimal digits of kGeneratedTokenBytes random bytes (OpenSSL's RAND_bytes).
Result<std::string> GenerateToken();

struct TokenFile {
  std::string token;
  std::string path;
  bool created = false;  // made now (else read from an earlier start)
};
// OK when the open file `fd` (`path`) is a regular file of this process's user that no one else
// may read or write (mode 0600 or 0400); else an error naming `field` that says the chmod or
// chown to run.
Status CheckPrivateFd(int fd, const std::string& path, const std::string& field);

// Reads `path` when it exists (opened without following a symbolic link; it must pass
// CheckPrivateFd), else creates it (and its directory) with mode 0600
// holding a new GenerateToken(). A file that exists but holds a weak token is an error.
Result<TokenFile> LoadOrCreateTokenFile(const std::string& path);

// The client's rule (see the top of this file). `server_host` is the host part of the daemon's
// URL; `default_file` is DataDir(kDefaultDataDir).Token() unless a test says otherwise. Returns "" when
// no token is found.
Result<std::string> LoadClientToken(const std::string& token_file, const std::string& server_host,
                                    const std::function<const char*(const char*)>& getenv = std::getenv,
                                    const std::string& default_file = DataDir(kDefaultDataDir).Token());

// True for "localhost", 127.0.0.0/8 and ::1 (brackets allowed: "[::1]").
bool IsLoopbackHost(const std::string& host);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_TOKEN_H_
