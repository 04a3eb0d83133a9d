// Routes of the worker protocol (core/api.h), in the order a worker uses them: leases, heartbeats,
// completions, bed restart and snapshot uploads (streamed to DATA/uploads/, then handed to the
// lease queue) and downloads.
#include "server/http/call.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <utility>
#include <httplib.h>
#include <openssl/crypto.h>
#include <spdlog/spdlog.h>
#include "core/aggregate.h"
#include "core/result_table.h"
#include "core/snapshot.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "platform/data_dir.h"
#include "platform/http_status.h"
#include "server/store/campaigns.h"
#include "server/store/cost_model.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/drift_report.h"
#include "server/dashboard/dashboard_files.h"
#include "server/analysis/figures.h"
#include "server/http/guarded_http_server.h"
#include "server/http/routes.h"
#include "server/dashboard/live_feed.h"
#include "server/analysis/report.h"
#include "server/store/schema_files.h"
#include "server/jobs/submission.h"
#include "server/http/result_rows.h"

namespace sandswim {
namespace routes {
namespace {

void LeaseJob(Call& c) {
  auto request = ParseMessage<api::LeaseRequest>(c.body, "LeaseRequest", /*allow_empty=*/true, Keys::kClosed);
  if (!request.ok()) return Fail(c, request.status());
  if (request->ranks < 1) {
    return Fail(c, Status::InvalidArgument("ranks", "must be at least 1, got " + std::to_string(request->ranks)));
  }
  if (Status s = api::LimitLengths(*request); !s.ok()) return Fail(c, s);
  auto grant = c.deps.leases->Lease(*request);
  if (!grant.ok()) return Fail(c, grant.status());
  if (!*grant) {
    c.res.status = 204;
    return;
  }
  SendJson(c, 200, {{"lease", **grant}});
}

void HeartbeatLease(Call& c) {
  auto beat = ParseMessage<api::Heartbeat>(c.body, "Heartbeat", /*allow_empty=*/true, Keys::kClosed);
  if (!beat.ok()) return Fail(c, beat.status());
  auto reply = c.deps.leases->Heartbeat(PathToken(c), *beat);
  if (!reply.ok()) return Fail(c, reply.status());
  SendJson(c, 200, *reply);
}

void CompleteLease(Call& c) {
  auto completion = ParseMessage<api::Completion>(c.body, "Completion", /*allow_empty=*/false);
  if (!completion.ok()) return Fail(c, completion.status());
  if (Status s = api::LimitLengths(*completion); !s.ok()) return Fail(c, s);
  auto reply = c.deps.leases->Complete(PathToken(c), *completion);
  if (!reply.ok()) return Fail(c, reply.status());
  SendJson(c, 200, *reply);
}

void ReleaseLease(Call& c) {
  auto request = ParseMessage<api::ReleaseRequest>(c.body, "ReleaseRequest", /*allow_empty=*/true);
  if (!request.ok()) return Fail(c, request.status());
  if (Status s = api::LimitLengths(*request); !s.ok()) return Fail(c, s);
  auto reply = c.deps.leases->Release(PathToken(c), request->reason);
  if (!reply.ok()) return Fail(c, reply.status());
  SendJson(c, 200, *reply);
}

// A file mapped read-only, so a restart of any size reaches PutBedRestart without a copy in memory.
class MappedFile {
 public:
  ~MappedFile() {
    if (data_ != nullptr) munmap(data_, size_);
    if (fd_ >= 0) close(fd_);
  }
  Status Open(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) return Status::IOError("cannot open " + path);
    struct stat st {};
    if (fstat(fd_, &st) != 0) return Status::IOError("cannot stat " + path);
    size_ = static_cast<size_t>(st.st_size);
    if (size_ == 0) return Status::Ok();
    void* p = mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (p == MAP_FAILED) return Status::IOError("cannot map " + path);
    data_ = p;
    return Status::Ok();
  }
  std::string_view view() const {
    return data_ == nullptr ? std::string_view() : std::string_view(static_cast<const char*>(data_), size_);
  }

 private:
  int fd_ = -1;
  void* data_ = nullptr;
  size_t size_ = 0;
};

// A request body received into a temporary file under DATA/uploads, mapped read-only, and
// removed when this goes unless the lease queue renamed it into place: an upload of any size
// reaches its store without a copy in memory or a second one on disk.
struct Upload {
  std::filesystem::path temp;
  MappedFile mapped;
  ~Upload() {
    std::error_code ignored;
    if (!temp.empty()) std::filesystem::remove(temp, ignored);
  }
};

// Receives the body into `upload` (at most max_restart_body bytes: 413 past it). False when it
// answered the request with a problem instead. Called once the lease is checked: a body is read
// only for a lease that may upload it (a refusal before it ends the connection; the server then
// drains what the client still sends for a moment, so that the answer reaches it, not a reset).
bool ReceiveUpload(Call& c, const std::string& name, const std::string& what, Upload& upload) {
  static std::atomic<uint64_t> upload_counter{0};
  std::filesystem::path dir = DataDir(c.deps.data_dir).Uploads();
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) {
    Fail(c, Status::IOError("cannot create " + dir.string() + ": " + ec.message()));
    return false;
  }
  upload.temp = dir / (name + "-" + std::to_string(getpid()) + "-" + std::to_string(upload_counter.fetch_add(1)) +
                       ".part");
  std::ofstream out(upload.temp, std::ios::binary | std::ios::trunc);
  if (!out) {
    Fail(c, Status::IOError("cannot write " + upload.temp.string()));
    return false;
  }
  size_t received = 0;
  bool too_big = false;
  (*c.reader)([&](const char* data, size_t n) {
    received += n;
    if (received > c.deps.max_restart_body) {
      too_big = true;
      return false;
    }
    out.write(data, static_cast<std::streamsize>(n));
    return static_cast<bool>(out);
  });
  out.close();
  if (too_big) {
    c.res.set_header("Connection", "close");
    Fail(c,
         Status::ResourceExhausted("body", what + " may be at most " + std::to_string(c.deps.max_restart_body) + " bytes"),
         413);
    return false;
  }
  if (!out) {
    const int err = errno;
    Fail(c, err == ENOSPC ? Status::Unavailable("cannot write " + upload.temp.string() +
                                                ": the disk that holds --data is full; free space on it and send "
                                                "it again (nothing was kept)")
                          : Status::IOError("cannot write " + upload.temp.string() + ": " + std::strerror(err)));
    return false;
  }
  Status s = upload.mapped.Open(upload.temp.string());
  if (!s.ok()) {
    Fail(c, s);
    return false;
  }
  return true;
}

// An upload refused before its body is read: the rest of the body is not read either, so the
// connection ends with the answer.
void RefuseUpload(Call& c, const Status& why) {
  c.res.set_header("Connection", "close");
  Fail(c, why);
}

void UploadBedRestart(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return RefuseUpload(c, id.status());
  std::string token = c.req.get_param_value("token");
  std::string sha256 = c.req.get_header_value("X-Sha256");
  if (token.empty()) return RefuseUpload(c, Status::InvalidArgument("token", "the query parameter token= is required"));
  if (sha256.empty()) return RefuseUpload(c, Status::InvalidArgument("X-Sha256", "the header X-Sha256 is required"));
  // The lease, and that it is this bed's, before a byte of the body reaches the disk.
  if (Status held = c.deps.leases->CheckUploadLease(token, api::JobKind::kBed, *id); !held.ok()) {
    return RefuseUpload(c, held);
  }
  Upload upload;
  if (!ReceiveUpload(c, "bed-" + std::to_string(*id), "a bed restart", upload)) return;
  Status s = c.deps.leases->PutBedRestart(token, upload.mapped.view(), sha256, c.deps.data_dir, upload.temp.string());
  if (!s.ok()) return Fail(c, s);
  SendJson(c, 200, {{"bed_id", *id}, {"sha256", sha256}, {"bytes", upload.mapped.view().size()}});
}

// A full-bed snapshot of a running run, handed in before the completion that lists it.
void UploadRunSnapshot(Call& c) {
  auto n = ParseInt(c.req.matches[2].str(), "n", 0, 1000);
  if (!n.ok()) return RefuseUpload(c, n.status());
  std::string sha256 = c.req.get_header_value("X-Sha256");
  if (sha256.empty()) return RefuseUpload(c, Status::InvalidArgument("X-Sha256", "the header X-Sha256 is required"));
  if (Status held = c.deps.leases->CheckUploadLease(PathToken(c), api::JobKind::kRun); !held.ok()) {
    return RefuseUpload(c, held);
  }
  Upload upload;
  if (!ReceiveUpload(c, "snapshot", "a snapshot", upload)) return;
  Status s = c.deps.leases->PutRunSnapshot(PathToken(c), static_cast<int>(*n), upload.mapped.view(), sha256,
                                          upload.temp.string());
  if (!s.ok()) return Fail(c, s);
  SendJson(c, 200, {{"n", *n}, {"sha256", sha256}, {"bytes", upload.mapped.view().size()}});
}

// Streams `size` bytes of an open file as the reply's body, a megabyte at a time.
void DownloadBedRestart(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto bed = c.deps.leases->GetBedRestart(*id);
  if (!bed.ok()) return Fail(c, bed.status());
  auto file = std::make_shared<std::ifstream>(bed->path, std::ios::binary);
  std::error_code ec;
  auto size = std::filesystem::file_size(bed->path, ec);
  if (!*file || ec) {
    return Fail(c, Status::IOError("bed " + std::to_string(*id) + "'s restart file " + bed->path +
                                   " is missing; the bed must be prepared again"));
  }
  c.res.status = 200;
  c.res.set_header("X-Sha256", bed->sha256);
  SendFile(c, file, static_cast<size_t>(size), "application/octet-stream");
}

}  // namespace

const std::vector<Route>& WorkerRoutes() {
  // clang-format off: one route a line, in columns, as the table in routes.cc reads.
  static const std::vector<Route> kTable = {
    // method  path                                   access            body                handler
    {"POST", "/api/v1/leases",                        Access::kWorker, BodyKind::kJson,    LeaseJob},
    {"GET",  "/api/v1/beds/{id}/restart",             Access::kWorker, BodyKind::kNone,    DownloadBedRestart},
    {"POST", "/api/v1/leases/{token}/heartbeat",      Access::kWorker, BodyKind::kJson,    HeartbeatLease},
    {"PUT",  "/api/v1/beds/{id}/restart",             Access::kWorker, BodyKind::kRestart, UploadBedRestart},
    {"PUT",  "/api/v1/leases/{token}/snapshots/{n}",  Access::kWorker, BodyKind::kRestart, UploadRunSnapshot},
    {"POST", "/api/v1/leases/{token}/complete",       Access::kWorker, BodyKind::kJson,    CompleteLease},
    {"POST", "/api/v1/leases/{token}/release",        Access::kWorker, BodyKind::kJson,    ReleaseLease},
  };
  // clang-format on
  return kTable;
}

}  // namespace routes

}  // namespace sandswim
