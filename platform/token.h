// The bearer token the daemon, its workers and the CLI share: one rule for where it comes from.
//
// LoadToken: the file's contents when `token_file` is set (surrounding whitespace trimmed; an
// unreadable or empty file is an error naming "--token-file"), else $SANDSWIM_TOKEN (trimmed),
// else "" (no token: the daemon serves loopback only).
//
// Thread safety: reads the file and the environment; no shared state.
#ifndef SANDSWIM_PLATFORM_TOKEN_H_
#define SANDSWIM_PLATFORM_TOKEN_H_

#include <cstdlib>
#include <functional>
#include <string>

#include "core/status.h"

namespace sandswim {

// `getenv` is injectable for tests.
Result<std::string> LoadToken(const std::string& token_file,
                              const std::function<const char*(const char*)>& getenv = std::getenv);

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_TOKEN_H_
