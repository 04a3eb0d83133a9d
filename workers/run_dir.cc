#include "workers/run_dir.h"

#include <openssl/evp.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>
#include <vector>

#include "core/deck.h"

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

Status RunDir::Remove() const {
  std::error_code ec;
  fs::remove_all(path_, ec);
  if (ec) return Status::IOError("cannot remove " + path_ + ": " + ec.message());
  return Status::Ok();
}

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
  const std::string cached = dir_ + "/" + bed.sha256 + ".restart";
  FileStamp stamp;
  auto known = verified_.find(bed.sha256);
  bool ok = known != verified_.end() && Stamp(cached, &stamp) && stamp == known->second;
  if (!ok) {
    auto have = Sha256OfFile(cached);
    ok = have.ok() && *have == bed.sha256;
  }
  if (!ok) {
    // Missing, or damaged since it was stored: fetch it (again).
    const std::string tmp = cached + ".part";
    fs::remove(tmp, ec);
    SANDSWIM_RETURN_IF_ERROR(download_(bed, tmp));
    auto got = Sha256OfFile(tmp);
    if (!got.ok()) return got.status();
    if (*got != bed.sha256) {
      fs::remove(tmp, ec);
      return Status::Corruption("bed_mismatch: bed " + std::to_string(bed.id) + " downloaded with sha256 " + *got +
                                ", the lease says " + bed.sha256);
    }
    fs::rename(tmp, cached, ec);
    if (ec) return Status::IOError("cannot store the bed in " + cached + ": " + ec.message());
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
