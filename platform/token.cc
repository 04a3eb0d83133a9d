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

Status CheckPrivateFd(int fd, const std::string& path, const std::string& field) {
  struct stat st {};
  if (fstat(fd, &st) != 0) return Status::IOError("cannot look at " + path + ": " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return Status::InvalidArgument(field, path + " is not a regular file");
  if (st.st_uid != geteuid()) {
    return Status::FailedPrecondition(
        field, path + " belongs to user " + std::to_string(st.st_uid) + ", not to this process's user " +
                   std::to_string(geteuid()) + ": chown " + std::to_string(geteuid()) + " " + path +
                   " (as root), or remove it and start again");
  }
  if ((st.st_mode & 077) != 0) {
    char mode[8];
    std::snprintf(mode, sizeof(mode), "%04o", static_cast<unsigned>(st.st_mode & 07777));
    return Status::FailedPrecondition(field, path + " may be read by other users (mode " + std::string(mode) +
                                                 "): chmod 600 " + path);
  }
  return Status::Ok();
}

Result<TokenFile> LoadOrCreateTokenFile(const std::string& path) {
  TokenFile out;
  out.path = path;
  // O_NOFOLLOW, and the checks on the opened file itself: a link planted at DATA/token (or a file
  // swapped in between a check and the read) is not followed to someone else's file.
  const int fd = open(path.c_str(), O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
  if (fd >= 0) {
    Status private_file = CheckPrivateFd(fd, path, "token file");
    std::string text;
    char chunk[4096];
    ssize_t n;
    while (private_file.ok() && (n = read(fd, chunk, sizeof chunk)) > 0) text.append(chunk, static_cast<size_t>(n));
    close(fd);
    if (!private_file.ok()) {
      return Status(private_file.code(), private_file.reason() +
                                             (private_file.code() == StatusCode::kFailedPrecondition
                                                  ? ", or remove it and a new token is made"
                                                  : ""),
                    private_file.field());
    }
    std::string token(Trim(text));
    if (token.empty()) return Status::InvalidArgument("token file", path + " is empty");
    if (Status strong = CheckTokenStrength(token, "token file " + path); !strong.ok()) return strong;
    out.token = token;
    return out;
  }
  if (errno == ELOOP) {
    return Status::FailedPrecondition("token file", path + " is a symbolic link: the daemon reads its token only "
                                                           "from a file of its own (remove the link)");
  }
  if (errno != ENOENT) return Status::IOError("cannot look at " + path + ": " + std::strerror(errno));
  std::error_code ec;
  const std::filesystem::path dir = std::filesystem::path(path).parent_path();
  if (!dir.empty()) std::filesystem::create_directories(dir, ec);
  if (ec) return Status::IOError("cannot create " + dir.string() + ": " + ec.message());
  auto token = GenerateToken();
  if (!token.ok()) return token.status();
  // O_EXCL: two daemons starting at once on one data directory do not overwrite each other's.
  const int out_fd = open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  if (out_fd < 0) {
    if (errno == EEXIST) return LoadOrCreateTokenFile(path);
    return Status::IOError("cannot create " + path + ": " + std::strerror(errno));
  }
  const std::string text = *token + "\n";
  bool written = write(out_fd, text.data(), text.size()) == static_cast<ssize_t>(text.size()) && fsync(out_fd) == 0;
  close(out_fd);
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
