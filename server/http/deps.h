// Deps: what the routes reach the daemon through (its store, lease queue, clock, data directory,
// token, limits, renderer and live feed), who may call a route (Access), what body it takes
// (BodyKind) and the problem document (RFC 9457) an error becomes. Shared by the route table
// (routes.h) and the handlers (call.h).
//
// Ownership: Deps points at objects the caller owns; they must outlive the server.
#ifndef SANDSWIM_SERVER_HTTP_DEPS_H_
#define SANDSWIM_SERVER_HTTP_DEPS_H_

#include <cstddef>
#include <cstdint>
#include <string>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "platform/clock.h"
#include "server/http/request_policy.h"
#include "server/jobs/lease_queue.h"
#include "server/jobs/submission.h"
#include "server/store/store.h"

namespace sandswim {

inline constexpr size_t kMaxJsonBodyBytes = size_t{1} << 20;     // 1 MiB
inline constexpr size_t kMaxRestartBodyBytes = size_t{2} << 30;  // 2 GiB
inline constexpr int kDefaultPort = 8640;

class ClaimsCache;
class EtaCache;
class LiveFeed;
class PlotRenderer;

struct Deps {
  Store* store = nullptr;
  LeaseQueue* leases = nullptr;
  Clock* clock = nullptr;
  std::string data_dir;        // beds' restart files and upload temp files live under it
  std::string engine_version;  // enters every content key (Submit)
  std::string token;           // bearer token; empty: no auth
  bool public_reads = false;   // reads need no token (--public-reads)
  // Which client a peer is, for the wrong-token throttle: ClientKey(address, loopback_clients_apart),
  // the rule the connection limits count by. ApiServer copies it from its ConnectionLimits
  // (--http-loopback-clients-apart), so the two never disagree.
  bool loopback_clients_apart = false;
  // Which Host headers name this daemon; ApiServer::Bind fills in the address and port it got.
  HostPolicy host_policy;
  size_t max_json_body = kMaxJsonBodyBytes;
  size_t max_restart_body = kMaxRestartBodyBytes;
  int64_t max_queued_runs = kMaxQueuedRuns;  // submissions past it: 503 (server/jobs/submission.h)
  // Draws figures not drawn before (server/analysis/plot_renderer.h): sandswimd's runs sandswim-render, a
  // process of its own, so that a plotting error cannot end the daemon. nullptr: in this process.
  PlotRenderer* renderer = nullptr;
  // The dashboard's live snapshots and trails (server/dashboard/live_feed.h); nullptr: /api/v1/live* answer 503.
  LiveFeed* live = nullptr;
  // Engines this daemon knows will work (its local workers): the ETA spreads work over at least
  // this many (server/store/cost_model.h ReadEta), more when more are in flight.
  int engine_slots = 0;
  // The ETAs a status answer carries, kept between writes (server/store/eta_cache.h); nullptr:
  // read for every answer.
  EtaCache* etas = nullptr;
  // Campaign runs' verdicts, kept between writes (server/analysis/claims_cache.h); nullptr:
  // evaluated for every answer.
  ClaimsCache* claims = nullptr;
};

// Who may call a route when a token is configured.
enum class Access {
  kPublic,  // always open (/healthz, /api/v1/openapi.json)
  kRead,    // needs the token, unless Deps::public_reads
  kWrite,   // needs the token
  kWorker,  // needs the token (the worker protocol)
};

// What a route reads from the request body.
enum class BodyKind { kNone, kJson, kRestart };

// The RFC 9457 body for a Status: {"type","title","status","detail","field"}.
nlohmann::json ProblemFor(const Status& status, int http_status);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_DEPS_H_
