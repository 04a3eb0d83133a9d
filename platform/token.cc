#include "platform/token.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <openssl/rand.h>

#include "core/text.h"

namespace sandswim {

std::string TokenFileIn(const std::string& data_dir) { return data_dir + "/token"; }

Result<std::string> LoadToken(const std::string& token_file, const std::function<const char*(const char*)>& getenv) {
  if (!token_file.empty()) {
    std::ifstream in(token_file);
    if (!in) return Status::InvalidArgument("--token-file", "cannot read " + token_file);
    std::stringstream text;
    text << in.rdbuf();
    std::string token(Trim(text.str()));
    if (token.empty()) return Status::InvalidArgument("--token-file", token_file + " is empty");
    return token;
  }
  const char* env = getenv("SANDSWIM_TOKEN");
  return std::string(Trim(env ? env : ""));
}

Status CheckTokenStrength(const std::string& token, const std::string& field) {
  bool hex = !token.empty();
  for (char ch : token) hex = hex && std::isxdigit(static_cast<unsigned char>(ch));
  const size_t needed = hex ? 32 : 22;
  if (token.size() >= needed) return Status::Ok();
  return Status::InvalidArgument(
      field, "the token has " + std::to_string(token.size()) + " characters; a token needs at least 128 bits: " +
                 std::to_string(needed) + " or more " + (hex ? "hexadecimal digits" : "characters") +
                 ". Make one with: openssl rand -hex 32 > FILE; chmod 600 FILE (or start without a token of "
                 "your own, and the daemon makes one in DATA/token)");
}

Result<std::string> GenerateToken() {
  unsigned char bytes[kGeneratedTokenBytes];
  if (RAND_bytes(bytes, sizeof(bytes)) != 1) return Status::Internal("OpenSSL's RAND_bytes could not make a token");
  static const char kHex[] = "0123456789abcdef";
  std::string token;
  for (unsigned char b : bytes) {
    token += kHex[b >> 4];
    token += kHex[b & 15];
  }
  return token;
}

Result<TokenFile> LoadOrCreateTokenFile(const std::string& path) {
  TokenFile out;
  out.path = path;
  struct stat st {};
  if (stat(path.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode)) return Status::InvalidArgument("token file", path + " is not a regular file");
    if ((st.st_mode & 077) != 0) {
      return Status::FailedPrecondition(
          "token file", path + " may be read by other users (mode " +
                            [&] {
                              char mode[8];
                              std::snprintf(mode, sizeof(mode), "%04o", static_cast<unsigned>(st.st_mode & 07777));
                              return std::string(mode);
                            }() +
                            "): chmod 600 " + path + ", or remove it and a new token is made");
    }
    auto token = LoadToken(path, [](const char*) { return nullptr; });
    if (!token.ok()) return Status::InvalidArgument("token file", token.status().reason());
    if (Status strong = CheckTokenStrength(*token, "token file " + path); !strong.ok()) return strong;
    out.token = *token;
    return out;
  }
  if (errno != ENOENT) return Status::IOError("cannot look at " + path + ": " + std::strerror(errno));
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (!dir.empty()) std::filesystem::create_directories(dir, ec);
  if (ec) return Status::IOError("cannot create " + dir.string() + ": " + ec.message());
  auto token = GenerateToken();
  if (!token.ok()) return token.status();
  // O_EXCL: two daemons starting at once on one data directory do not overwrite each other's.
  int fd = open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
  if (fd < 0) {
    if (errno == EEXIST) return LoadOrCreateTokenFile(path);
    return Status::IOError("cannot create " + path + ": " + std::strerror(errno));
  }
  const std::string text = *token + "\n";
  bool written = write(fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) && fsync(fd) == 0;
  close(fd);
  if (!written) {
    unlink(path.c_str());
    return Status::IOError("cannot write " + path + " (disk full?)");
  }
  out.token = *token;
  out.created = true;
  return out;
}

Result<std::string> LoadClientToken(const std::string& token_file, const std::string& server_host,
                                    const std::function<const char*(const char*)>& getenv,
                                    const std::string& default_file) {
  auto given = LoadToken(token_file, getenv);
  if (!given.ok() || !given->empty()) return given;
  if (!IsLoopbackHost(server_host) || access(default_file.c_str(), F_OK) != 0) return std::string();
  auto found = LoadToken(default_file, getenv);
  if (!found.ok())
    return Status::InvalidArgument("--token-file", found.status().reason() + " (the daemon's token file)");
  return found;
}

bool IsLoopbackHost(const std::string& host_in) {
  std::string host = host_in;
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host == "localhost") return true;
  in_addr v4{};
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) return IN6_IS_ADDR_LOOPBACK(&v6);
  return false;
}

}  // namespace sandswim
