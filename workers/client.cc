#include "workers/client.h"

#include <httplib.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>

#include "platform/tls.h"

namespace sandswim::worker {
namespace {

// One HTTP exchange's outcome: a response, or Unavailable when there was none.
struct Exchange {
  Status status;  // OK when a response arrived
  int code = 0;
  std::string body;
};

bool Retryable(const Status& s) { return DaemonTrouble(s); }

}  // namespace

HttpServerClient::HttpServerClient(ClientOptions options, const std::atomic<bool>* stopping, Clock* clock)
    : options_(std::move(options)), stopping_(stopping), clock_(clock != nullptr ? clock : &system_clock_) {}

namespace {

// Runs `call` until it succeeds, fails for good, `retry_for_s` passes or `stopping` is set. The
// wait between tries doubles from 0.2 s up to `max_backoff_s`.
template <typename F>
auto WithRetries(Clock& clock, double retry_for_s, double max_backoff_s, const std::atomic<bool>* stopping, F call)
    -> decltype(call()) {
  const double deadline = clock.Monotonic() + retry_for_s;
  double backoff = 0.2;
  while (true) {
    auto r = call();
    if (r.ok() || !Retryable(r.status()) || clock.Monotonic() >= deadline) return r;
    // Sleep in small steps so a shutdown is not held up by a long backoff.
    const double wake = clock.Monotonic() + backoff;
    for (double left = backoff; left > 0; left = wake - clock.Monotonic()) {
      if (stopping != nullptr && stopping->load()) return r;
      clock.SleepFor(std::min(left, 0.05));
    }
    backoff = std::min(backoff * 2, max_backoff_s);
  }
}

std::unique_ptr<httplib::Client> MakeClient(const ClientOptions& o) { return NewHttpClient(o); }

Exchange FromResult(const httplib::Client& cli, const std::string& server, const httplib::Result& res, const std::string& what) {
  Exchange ex;
  if (!res) {
    // A certificate that is not the daemon's is refused for good, not retried as the daemon's trouble.
    if (auto tls = TlsFailure(cli, static_cast<int>(res.error()), server); tls) {
      ex.status = Status(tls->code(), what + ": " + tls->reason(), tls->field());
      return ex;
    }
    ex.status = Status::Unavailable(what + ": daemon not reachable (" + httplib::to_string(res.error()) + ")");
    return ex;
  }
  ex.code = res->status;
  ex.body = res->body;
  if (ex.code < 200 || ex.code >= 300) ex.status = StatusFromHttp(ex.code, ex.body, what);
  return ex;
}

template <typename T>
Result<T> ParseJson(const std::string& body, const std::string& what) {
  try {
    return nlohmann::json::parse(body).get<T>();
  } catch (const std::exception& e) {
    return Status::Corruption(what + ": unreadable reply: " + e.what());
  }
}

}  // namespace

Result<std::optional<api::LeaseGrant>> HttpServerClient::Lease(const api::LeaseRequest& request) {
  auto cli = MakeClient(options_);
  Exchange ex = FromResult(*cli, options_.server, cli->Post("/api/v1/leases", api::ToJsonText(nlohmann::json(request)), "application/json"),
                           "POST /api/v1/leases");
  if (!ex.status.ok()) return ex.status;
  if (ex.code == 204 || ex.body.empty()) return std::optional<api::LeaseGrant>();
  try {
    nlohmann::json j = nlohmann::json::parse(ex.body);
    if (!j.contains("lease") || j["lease"].is_null()) return std::optional<api::LeaseGrant>();
    api::LeaseGrant grant = j["lease"].get<api::LeaseGrant>();
    NoteLeaseTtl(grant.ttl_s);
    return std::optional<api::LeaseGrant>(std::move(grant));
  } catch (const std::exception& e) {
    return Status::Corruption("POST /api/v1/leases: unreadable lease: " + std::string(e.what()));
  }
}

void HttpServerClient::NoteLeaseTtl(double ttl_s) {
  if (ttl_s > 0) max_backoff_s_.store(std::clamp(ttl_s / 3, 0.2, kMaxRetryBackoffS));
}

Result<api::HeartbeatReply> HttpServerClient::Heartbeat(const std::string& token, const api::Heartbeat& beat) {
  const std::string path = "/api/v1/leases/" + token + "/heartbeat";
  auto cli = MakeClient(options_);
  Exchange ex =
      FromResult(*cli, options_.server, cli->Post(path, api::ToJsonText(nlohmann::json(beat)), "application/json"), "POST heartbeat");
  if (!ex.status.ok()) return ex.status;
  return ParseJson<api::HeartbeatReply>(ex.body, "heartbeat");
}

Result<api::CompletionReply> HttpServerClient::Release(const std::string& token, const std::string& reason) {
  const std::string path = "/api/v1/leases/" + token + "/release";
  auto cli = MakeClient(options_);
  api::ReleaseRequest request{reason};
  Exchange ex =
      FromResult(*cli, options_.server, cli->Post(path, api::ToJsonText(nlohmann::json(request)), "application/json"), "POST release");
  if (!ex.status.ok()) return ex.status;
  return ParseJson<api::CompletionReply>(ex.body, "release");
}

Status HttpServerClient::DownloadBed(const api::BedRef& bed, const std::string& dest_path) {
  const std::string path = bed.url.empty() ? "/api/v1/beds/" + std::to_string(bed.id) + "/restart" : bed.url;
  auto r = WithRetries(*clock_, options_.retry_for_s, max_backoff_s_.load(), stopping_, [&]() -> Result<bool> {
    std::ofstream out(dest_path, std::ios::binary | std::ios::trunc);
    if (!out) return Status::IOError("cannot write " + dest_path);
    auto cli = MakeClient(options_);
    int code = 0;
    std::string error_body;
    auto res = cli->Get(
        path, httplib::Headers{},
        [&](const httplib::Response& response) {
          code = response.status;
          return true;
        },
        [&](const char* data, size_t n) {
          if (code == 200) {
            out.write(data, static_cast<std::streamsize>(n));
          } else if (error_body.size() < 1000) {
            error_body.append(data, n);
          }
          return true;
        });
    Exchange ex = FromResult(*cli, options_.server, res, "GET " + path);
    if (!ex.status.ok()) return ex.status;
    if (code != 200) return StatusFromHttp(code, error_body, "GET " + path);
    out.flush();
    if (!out) return Status::IOError("cannot write " + dest_path);
    return true;
  });
  return r.status();
}

Status HttpServerClient::UploadBed(int64_t bed_id, const std::string& token, const std::string& path,
                                   const std::string& sha256) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::NotFound("bed restart " + path + " does not exist");
  std::stringstream ss;
  ss << in.rdbuf();
  const std::string bytes = ss.str();
  return PutWithChecksum("/api/v1/beds/" + std::to_string(bed_id) + "/restart?token=" + token, bytes, sha256,
                         "application/octet-stream", "PUT bed restart");
}

Status HttpServerClient::PutWithChecksum(const std::string& url, const std::string& bytes, const std::string& sha256,
                                         const char* content_type, const std::string& what) {
  auto r = WithRetries(*clock_, options_.retry_for_s, max_backoff_s_.load(), stopping_, [&]() -> Result<bool> {
    auto cli = MakeClient(options_);
    Exchange ex = FromResult(*cli, options_.server, cli->Put(url, httplib::Headers{{"X-Sha256", sha256}}, bytes, content_type), what);
    if (!ex.status.ok()) return ex.status;
    return true;
  });
  return r.status();
}

Status ServerClient::UploadSnapshot(const std::string&, int, const std::string&, const std::string&) {
  return Status::FailedPrecondition("snapshots", "this client cannot hand in snapshots");
}

Status HttpServerClient::UploadSnapshot(const std::string& token, int idx, const std::string& bytes,
                                        const std::string& sha256) {
  return PutWithChecksum("/api/v1/leases/" + token + "/snapshots/" + std::to_string(idx), bytes, sha256, "text/plain",
                         "PUT snapshot");
}

Result<api::CompletionReply> HttpServerClient::Complete(const std::string& token, const api::Completion& completion) {
  const std::string path = "/api/v1/leases/" + token + "/complete";
  const std::string body = api::ToJsonText(nlohmann::json(completion));
  return WithRetries(*clock_, options_.retry_for_s, max_backoff_s_.load(), stopping_, [&]() -> Result<api::CompletionReply> {
    auto cli = MakeClient(options_);
    Exchange ex = FromResult(*cli, options_.server, cli->Post(path, body, "application/json"), "POST complete");
    if (!ex.status.ok()) return ex.status;
    auto reply = ParseJson<api::CompletionReply>(ex.body, "complete");
    if (reply.ok() && reply->next) NoteLeaseTtl(reply->next->ttl_s);
    return reply;
  });
}

}  // namespace sandswim::worker
