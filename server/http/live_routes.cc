// Routes of the dashboard's live feed (server/dashboard/live_feed.h): the board, its server-sent
// events and a run's trail.
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

// ---- Handlers: the dashboard's live feed (server/dashboard/live_feed.h) -------------------------------

// A stream says it is alive at least this often: proxies close silent connections, and a write is
// how the server learns that the page went away, so a closed stream frees its slot within ~2 s.
constexpr double kLiveKeepAliveS = 2;

LiveFeed* NeedLiveFeed(Call& c) {
  if (c.deps.live == nullptr) Fail(c, Status::Unavailable("this daemon serves no live feed"));
  return c.deps.live;
}

void GetLive(Call& c) {
  LiveFeed* feed = NeedLiveFeed(c);
  if (feed == nullptr) return;
  auto snap = feed->Current();
  const std::string etag = "\"live-" + std::to_string(snap->version) + "\"";
  c.res.set_header("ETag", etag);
  c.res.set_header("Cache-Control", "no-cache");
  if (c.req.get_header_value("If-None-Match") == etag) {
    c.res.status = 304;
    return;
  }
  c.res.status = 200;
  c.res.set_content(snap->json, "application/json");
}

// Server-sent events: "event: board" with the snapshot as data, at each new version; a comment
// line every kLiveKeepAliveS otherwise. At most LiveFeed's max_streams at once, and its
// max_streams_per_client from one peer address (503 past them).
void GetLiveEvents(Call& c) {
  LiveFeed* feed = NeedLiveFeed(c);
  if (feed == nullptr) return;
  const std::string client = c.req.remote_addr;
  if (!feed->OpenStream(client)) {  // expected under many pages: answered without the error log of a 5xx
    c.res.set_header("Retry-After", "10");
    c.res.status = 503;
    c.res.set_content(api::ToJsonText(ProblemFor(
                          Status::Unavailable("every live stream this daemon allows (in all, or to this client) is "
                                              "open: poll GET /api/v1/live"),
                          503)),
                      kProblemType);
    return;
  }
  auto last = std::make_shared<uint64_t>(0);
  c.res.set_header("Cache-Control", "no-store");
  c.res.set_chunked_content_provider(
      "text/event-stream",
      [feed, last](size_t, httplib::DataSink& sink) {
        auto snap = feed->WaitNewer(*last, kLiveKeepAliveS);
        if (feed->stopped()) {
          sink.done();
          return true;
        }
        std::string message;
        if (snap->version > *last) {
          *last = snap->version;
          message = "id: " + std::to_string(snap->version) + "\nevent: board\ndata: " + snap->json + "\n\n";
        } else {
          message = ": alive\n\n";
        }
        return sink.write(message.data(), message.size());  // false: the page went away
      },
      [feed, client](bool) { feed->CloseStream(client); });
}

// The run's z(t) so far, from its heartbeats while it runs (empty once it is not running: its
// stored trajectory is GET /api/v1/runs/{id}'s).
void GetRunTrail(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  LiveFeed* feed = NeedLiveFeed(c);
  if (feed == nullptr) return;
  LiveFeed::Trail trail = feed->TrailOf(*id);
  SendJson(c, 200, {{"run_id", *id}, {"t", trail.t}, {"z", trail.z}});
}

}  // namespace

const std::vector<Route>& LiveRoutes() {
  // clang-format off: one route a line, in columns, as the table in routes.cc reads.
  static const std::vector<Route> kTable = {
    // method  path                                   access            body                handler
    {"GET",  "/api/v1/live",                          Access::kRead,   BodyKind::kNone,    GetLive},
    {"GET",  "/api/v1/live/events",                   Access::kRead,   BodyKind::kNone,    GetLiveEvents},
    {"GET",  "/api/v1/runs/{id}/trail",               Access::kRead,   BodyKind::kNone,    GetRunTrail},
  };
  // clang-format on
  return kTable;
}

}  // namespace routes

}  // namespace sandswim
