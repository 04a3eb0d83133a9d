#include "platform/files.h"

#include <openssl/evp.h>
#include <openssl/rand.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

namespace sandswim {

Result<std::string> Sha256OfFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound(path + " does not exist");
  EVP_MD_CTX* ctx = EVP_MD_CTX_new();
  EVP_DigestInit_ex(ctx, EVP_sha256(), nullptr);
  std::vector<char> buf(1 << 20);
  while (in) {
    in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
    if (in.gcount() > 0) EVP_DigestUpdate(ctx, buf.data(), static_cast<size_t>(in.gcount()));
  }
  unsigned char md[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_DigestFinal_ex(ctx, md, &len);
  EVP_MD_CTX_free(ctx);
  static const char* kHex = "0123456789abcdef";
  std::string hex;
  for (unsigned int i = 0; i < len; ++i) {
    hex.push_back(kHex[md[i] >> 4]);
    hex.push_back(kHex[md[i] & 15]);
  }
  return hex;
}

Result<std::string> ReadWholeFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::IOError("cannot read " + path);
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Status::IOError("cannot read " + path);
  return ss.str();
}

Status WriteFileAtomically(const std::string& path, std::string_view bytes) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path target(path);
  if (target.has_parent_path()) {
    fs::create_directories(target.parent_path(), ec);
    if (ec) return Status::IOError("cannot create " + target.parent_path().string() + ": " + ec.message());
  }
  unsigned char salt[4];
  if (RAND_bytes(salt, sizeof salt) != 1) return Status::Internal("no randomness for a temporary name");
  char suffix[16];
  std::snprintf(suffix, sizeof suffix, ".tmp.%02x%02x%02x%02x", salt[0], salt[1], salt[2], salt[3]);
  const std::string tmp = path + suffix;
  FILE* f = std::fopen(tmp.c_str(), "wb");
  if (f == nullptr) return Status::IOError("cannot write " + tmp);
  bool good = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
  good = std::fflush(f) == 0 && good;
  good = ::fsync(fileno(f)) == 0 && good;
  good = std::fclose(f) == 0 && good;
  if (!good) {
    fs::remove(tmp, ec);
    return Status::IOError("cannot write " + tmp + " (disk full?)");
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return Status::IOError("cannot rename into " + path + ": " + ec.message());
  }
  return Status::Ok();
}

Status PlaceFile(const std::string& path, std::string_view bytes, const std::string& from) {
  namespace fs = std::filesystem;
  if (from.empty()) return WriteFileAtomically(path, bytes);
  const int fd = ::open(from.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return Status::IOError("cannot open " + from + ": " + std::strerror(errno));
  const bool synced = ::fsync(fd) == 0;
  ::close(fd);
  if (!synced) return Status::IOError("cannot sync " + from + " (disk full?)");
  std::error_code ec;
  const fs::path target(path);
  if (target.has_parent_path()) {
    fs::create_directories(target.parent_path(), ec);
    if (ec) return Status::IOError("cannot create " + target.parent_path().string() + ": " + ec.message());
  }
  if (::rename(from.c_str(), path.c_str()) == 0) return Status::Ok();
  if (errno != EXDEV) return Status::IOError("cannot rename " + from + " into " + path + ": " + std::strerror(errno));
  SANDSWIM_RETURN_IF_ERROR(WriteFileAtomically(path, bytes));
  fs::remove(from, ec);
  return Status::Ok();
}

namespace {
// One entry's permissions without group's and others' bits; true when they had some.
Result<bool> RestrictEntry(const std::string& path) {
  struct stat st {};
  if (lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return false;
    return Status::IOError("cannot stat " + path + ": " + std::strerror(errno));
  }
  if (S_ISLNK(st.st_mode) || (st.st_mode & 077) == 0) return false;
  if (chmod(path.c_str(), st.st_mode & 07700) != 0) {
    return Status::IOError("cannot make " + path + " private (chmod): " + std::strerror(errno));
  }
  return true;
}
}  // namespace

Result<int> RestrictToOwner(const std::string& path) {
  namespace fs = std::filesystem;
  auto top = RestrictEntry(path);
  if (!top.ok()) return top.status();
  int changed = *top ? 1 : 0;
  std::error_code ec;
  if (!fs::is_directory(fs::symlink_status(path, ec))) return changed;
  for (fs::recursive_directory_iterator it(path, fs::directory_options::none, ec), end; !ec && it != end;
       it.increment(ec)) {
    auto one = RestrictEntry(it->path().string());
    if (!one.ok()) return one.status();
    if (*one) ++changed;
  }
  if (ec) return Status::IOError("cannot list " + path + ": " + ec.message());
  return changed;
}

Result<FileIdentity> IdentifyFile(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return Status::NotFound(path + " does not exist");
  FileIdentity id;
  id.device = static_cast<uint64_t>(st.st_dev);
  id.inode = static_cast<uint64_t>(st.st_ino);
  id.size = static_cast<int64_t>(st.st_size);
  id.mtime_ns = static_cast<int64_t>(st.st_mtim.tv_sec) * 1000000000 + st.st_mtim.tv_nsec;
  return id;
}

}  // namespace sandswim
