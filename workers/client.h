// ServerClient: the worker's side of the worker protocol (core/api.h lists the routes).
//
// Abstract so the worker loop can be tested against a fake. HttpServerClient is the real one
// and the only worker file that includes httplib.h. It sends "Authorization: Bearer <token>"
// when a token is set, and retries with exponential backoff (0.2 s doubling to 10 s) while the
// daemon is down or answers 5xx: a daemon restart then costs a delay, never a running job.
// Which calls retry and for how long:
//   Lease, Heartbeat,
//   Release                  one attempt (the loop calls again on its own schedule);
//   DownloadBed, UploadBed,
//   UploadSnapshot, Complete                 until `retry_for_s` has passed (a completion is recorded once per
//                            token; a retried one with `next` gets a fresh next job).
// Status codes: platform/http_client.h's one table (Conflict for 409: the lease was lost).
// Retried calls retry while the daemon cannot be reached or answers 5xx (DaemonTrouble()).
//
// Thread safety: HttpServerClient is thread-safe (one httplib::Client per call).
#ifndef SANDSWIM_WORKERS_CLIENT_H_
#define SANDSWIM_WORKERS_CLIENT_H_

#include <atomic>
#include <optional>
#include <string>

#include "core/api.h"
#include "core/status.h"
#include "platform/clock.h"
#include "platform/http_client.h"

namespace sandswim::worker {

class ServerClient {
 public:
  virtual ~ServerClient() = default;
  // nullopt when there is no work (204).
  virtual Result<std::optional<api::LeaseGrant>> Lease(const api::LeaseRequest& request) = 0;
  virtual Result<api::HeartbeatReply> Heartbeat(const std::string& token, const api::Heartbeat& beat) = 0;
  virtual Status DownloadBed(const api::BedRef& bed, const std::string& dest_path) = 0;
  virtual Status UploadBed(int64_t bed_id, const std::string& token, const std::string& path,
                           const std::string& sha256) = 0;
  // A run's full-bed snapshot `idx`, before the completion that lists it. The base refuses
  // (kFailedPrecondition): test doubles that never see snapshots need not implement it.
  virtual Status UploadSnapshot(const std::string& token, int idx, const std::string& bytes,
                                const std::string& sha256);
  virtual Result<api::CompletionReply> Complete(const std::string& token, const api::Completion& completion) = 0;
  // Hands an unfinished job back (the worker is stopping); the daemon queues it again without
  // counting the attempt. One attempt, no retries: when it fails the lease simply expires.
  // The default (for fakes that predate it) answers Unavailable, which is how a failure looks.
  virtual Result<api::CompletionReply> Release(const std::string& token, const std::string& reason) {
    (void)token;
    (void)reason;
    return Status::Unavailable("release is not supported by this client");
  }
};

// The longest wait between two retries of a call (less when the daemon's leases are shorter).
inline constexpr double kMaxRetryBackoffS = 10.0;

class HttpServerClient : public ServerClient {
 public:
  // `stopping`, when set and true, ends retries early (the worker is shutting down). `clock` times
  // the retries (nullptr: the system's). REQUIRES: `stopping` and `clock` outlive the client.
  explicit HttpServerClient(ClientOptions options, const std::atomic<bool>* stopping = nullptr, Clock* clock = nullptr);

  Result<std::optional<api::LeaseGrant>> Lease(const api::LeaseRequest& request) override;
  Result<api::HeartbeatReply> Heartbeat(const std::string& token, const api::Heartbeat& beat) override;
  Status DownloadBed(const api::BedRef& bed, const std::string& dest_path) override;
  Status UploadBed(int64_t bed_id, const std::string& token, const std::string& path,
                   const std::string& sha256) override;
  Status UploadSnapshot(const std::string& token, int idx, const std::string& bytes,
                        const std::string& sha256) override;
  Result<api::CompletionReply> Complete(const std::string& token, const api::Completion& completion) override;
  Result<api::CompletionReply> Release(const std::string& token, const std::string& reason) override;

 private:
  // A grant's TTL bounds the wait between retries: after a daemon restart a job's lease runs one
  // TTL (LeaseQueue::ExtendLeasesAfterRestart), so a completion retried at most TTL/3 apart lands
  // before it expires, and the run is not leased to another worker and run twice.
  void NoteLeaseTtl(double ttl_s);
  // PUT `bytes` with header X-Sha256, retried as every upload is.
  Status PutWithChecksum(const std::string& url, const std::string& bytes, const std::string& sha256,
                         const char* content_type, const std::string& what);

  ClientOptions options_;
  const std::atomic<bool>* stopping_;
  SystemClock system_clock_;
  Clock* clock_;  // the one given, or system_clock_
  std::atomic<double> max_backoff_s_{kMaxRetryBackoffS};
};

}  // namespace sandswim::worker

#endif  // SANDSWIM_WORKERS_CLIENT_H_
