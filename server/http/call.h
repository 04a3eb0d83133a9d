// Call: one request in flight as a route's handler sees it (the request, the response, the
// daemon's Deps, the body), the parsing every handler shares (JSON bodies, worker messages, ids,
// pages, cursors) and the problem documents (RFC 9457) it answers errors with; and Route, a row of
// the route table, which every resource's file (*_routes.cc) lists its routes in. Only the files
// of server/http/ include it.
//
// Thread safety: a Call belongs to the request's thread; HttpCounters is locked.
#ifndef SANDSWIM_SERVER_HTTP_CALL_H_
#define SANDSWIM_SERVER_HTTP_CALL_H_

#include <algorithm>
#include <charconv>
#include <fstream>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <httplib.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/api.h"
#include "core/status.h"
#include "platform/http_status.h"
#include "server/http/deps.h"
#include "server/http/request_policy.h"
#include "server/store/eta_cache.h"

namespace sandswim {
namespace routes {

using json = nlohmann::json;

// A body bigger than its route's limit is still read (and thrown away) up to this many bytes, so
// the client gets its 413 instead of a connection reset; past it the connection is closed.
inline constexpr size_t kDrainCapBytes = size_t{64} << 20;
inline constexpr const char* kProblemType = "application/problem+json";

inline std::string HttpTitle(int http_status) {
  static const std::map<int, const char*> kTitles = {{200, "OK"},
                                                     {201, "Created"},
                                                     {204, "No Content"},
                                                     {400, "Bad Request"},
                                                     {401, "Unauthorized"},
                                                     {403, "Forbidden"},
                                                     {404, "Not Found"},
                                                     {405, "Method Not Allowed"},
                                                     {409, "Conflict"},
                                                     {411, "Length Required"},
                                                     {413, "Content Too Large"},
                                                     {415, "Unsupported Media Type"},
                                                     {416, "Range Not Satisfiable"},
                                                     {421, "Misdirected Request"},
                                                     {422, "Unprocessable Content"},
                                                     {429, "Too Many Requests"},
                                                     {500, "Internal Server Error"},
                                                     {503, "Service Unavailable"}};
  auto it = kTitles.find(http_status);
  return it != kTitles.end() ? it->second : "HTTP " + std::to_string(http_status);
}

// Counts every answered request by status code, for /metrics; and the failed token attempts
// (server/http/request_policy.h), which it also shows.
struct HttpCounters {
  std::mutex mu;
  std::map<int, uint64_t> by_status;
  std::unique_ptr<FailedAuthThrottle> auth_failures;
  std::unique_ptr<RefusalLog> refusals;  // a foreign Host, a cross-site write: a line per peer and interval
  void Count(int status) {
    std::lock_guard<std::mutex> lock(mu);
    ++by_status[status == -1 ? 200 : status];
  }
};

// ---- One request in flight ---------------------------------------------------------------------

struct Call {
  const httplib::Request& req;
  httplib::Response& res;
  Deps& deps;
  std::string body;                                // BodyKind::kJson, at most max_json_body
  const httplib::ContentReader* reader = nullptr;  // BodyKind::kRestart, not yet read
  HttpCounters* counters = nullptr;
};

inline void SendJson(Call& c, int http_status, const json& body) {
  c.res.status = http_status;
  c.res.set_content(api::ToJsonText(body), "application/json");
}

// A 5xx says what failed but not where: file paths stay in the log.
inline void SendProblem(httplib::Response& res, const Status& status, int http_status = 0) {
  if (http_status == 0) http_status = HttpStatusFor(status.code());
  res.status = http_status;
  const Status told = http_status >= 500 ? Status(status.code(), RedactPaths(status.reason()), status.field()) : status;
  res.set_content(api::ToJsonText(ProblemFor(told, http_status)), kProblemType);
  if (http_status == 503 && !res.has_header("Retry-After")) res.set_header("Retry-After", "10");
  if (http_status >= 500) {
    spdlog::error(
        "HTTP {}: {} (check the daemon's --db and --data paths and disk space; "
        "the request can be retried)",
        http_status, status.ToString());
  }
}

inline void Fail(Call& c, const Status& status, int http_status = 0) { SendProblem(c.res, status, http_status); }

// Parses a JSON body; a syntax error names the byte where parsing stopped. A key twice in one
// object is refused, naming it: which of the two a reader takes is the parser's whim, and another
// reader (a proxy, a log) may take the other.
inline Result<json> ParseJsonBody(const std::string& body, bool allow_empty) {
  if (body.empty()) {
    if (allow_empty) return json::object();
    return Status::InvalidArgument("body", "a JSON body is required");
  }
  struct DuplicateKey {
    std::string key;
  };
  std::vector<std::vector<std::string>> keys;  // of each object open, innermost last
  const json::parser_callback_t refuse_duplicates = [&keys](int, json::parse_event_t event, json& parsed) {
    if (event == json::parse_event_t::object_start) keys.emplace_back();
    if (event == json::parse_event_t::object_end && !keys.empty()) keys.pop_back();
    if (event == json::parse_event_t::key && !keys.empty()) {
      const std::string key = parsed.get<std::string>();
      if (std::find(keys.back().begin(), keys.back().end(), key) != keys.back().end()) throw DuplicateKey{key};
      keys.back().push_back(key);
    }
    return true;
  };
  try {
    return json::parse(body, refuse_duplicates);
  } catch (const DuplicateKey& d) {
    return Status::InvalidArgument(d.key, "appears twice in one object: give each key once");
  } catch (const json::parse_error& e) {
    return Status::InvalidArgument("body", "malformed JSON at byte " + std::to_string(e.byte) + ": " + e.what());
  } catch (const json::exception& e) {  // e.g. a number too large for a double (1e999)
    return Status::InvalidArgument("body", std::string("unreadable JSON: ") + e.what());
  }
}

// A body a route's schema allows to be left out or to be any object (cancel, backup): empty, or
// a JSON object. What it holds is not read, but a body that is no JSON object is refused.
inline Status EmptyOrObject(const std::string& body) {
  auto j = ParseJsonBody(body, /*allow_empty=*/true);
  if (!j.ok()) return j.status();
  if (!j->is_object()) return Status::InvalidArgument("body", "must be a JSON object, or left out");
  return Status::Ok();
}

// Whether a message may hold keys that its type does not know: kClosed where its schema says
// additionalProperties false (schema/openapi.json).
enum class Keys { kOpen, kClosed };

// Converts a worker message with its nlohmann conversions; a wrong type names the message.
template <typename T>
inline Result<T> ParseMessage(const std::string& body, const char* what, bool allow_empty, Keys keys = Keys::kOpen) {
  auto j = ParseJsonBody(body, allow_empty);
  if (!j.ok()) return j.status();
  if (!j->is_object()) return Status::InvalidArgument("body", std::string(what) + " must be a JSON object");
  if (keys == Keys::kClosed) {
    const json known = T{};  // every field, as its conversion writes them
    for (const auto& [key, value] : j->items()) {
      if (!known.contains(key)) return Status::InvalidArgument(key, std::string("is not a field of ") + what);
    }
  }
  try {
    return j->template get<T>();
  } catch (const json::exception& e) {
    return Status::InvalidArgument("body", std::string("not a valid ") + what + ": " + e.what());
  }
}

inline Result<int64_t> ParseInt(const std::string& text, const std::string& field, int64_t min, int64_t max) {
  int64_t v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size()) {
    return Status::InvalidArgument(field, "must be an integer, got \"" + text + "\"");
  }
  if (v < min || v > max) {
    return Status::InvalidArgument(
        field, "must be in [" + std::to_string(min) + ", " + std::to_string(max) + "], got " + text);
  }
  return v;
}

inline Result<int64_t> PathId(const Call& c, size_t index = 1) {
  return ParseInt(c.req.matches[index].str(), "id", 1, INT64_MAX);
}

// The ETA of what is left of a sweep or a campaign run (server/store/cost_model.h ReadEta), from
// the daemon's EtaCache when it has one.
inline Result<std::optional<Eta>> EtaOf(const Call& c, EtaScope scope, int64_t id) {
  if (c.deps.etas != nullptr) return c.deps.etas->Get(scope, id, c.deps.clock->Now(), c.deps.engine_slots);
  return ReadEta(*c.deps.store, scope, id, c.deps.clock->Now(), c.deps.engine_slots);
}

inline std::string PathToken(const Call& c) { return c.req.matches[1].str(); }

// Optional integer query parameter.
inline Result<std::optional<int64_t>> QueryInt(const Call& c, const std::string& name, int64_t min, int64_t max) {
  if (!c.req.has_param(name.c_str())) return std::optional<int64_t>();
  auto v = ParseInt(c.req.get_param_value(name.c_str()), name, min, max);
  if (!v.ok()) return v.status();
  return std::optional<int64_t>(*v);
}

struct PageArgs {
  int64_t after_id = 0;
  int limit = 100;
};

inline Result<PageArgs> ParsePage(const Call& c) {
  PageArgs page;
  auto cursor = QueryInt(c, "cursor", 0, INT64_MAX);
  if (!cursor.ok()) return cursor.status();
  auto limit = QueryInt(c, "limit", 1, 1000);
  if (!limit.ok()) return limit.status();
  if (*cursor) page.after_id = **cursor;
  if (*limit) page.limit = static_cast<int>(**limit);
  return page;
}

// Cursors are opaque strings to clients (today: the last id of the page).
inline void CursorToString(json& page) {
  auto it = page.find("next_cursor");
  if (it != page.end() && it->is_number_integer()) *it = std::to_string(it->get<int64_t>());
}

inline bool WantsCsv(const Call& c) {
  if (c.req.has_param("format")) return c.req.get_param_value("format") == "csv";
  return c.req.get_header_value("Accept").find("text/csv") != std::string::npos;
}

// Streams `size` bytes of `file` as the response body, a MiB at a time.
inline void SendFile(Call& c, std::shared_ptr<std::ifstream> file, size_t size, const char* content_type) {
  c.res.set_content_provider(size, content_type, [file](size_t offset, size_t length, httplib::DataSink& sink) {
    std::vector<char> buffer(std::min<size_t>(length, size_t{1} << 20));
    file->seekg(static_cast<std::streamoff>(offset));
    file->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    std::streamsize got = file->gcount();
    if (got <= 0) return false;
    return sink.write(buffer.data(), static_cast<size_t>(got));
  });
}

// Submits a POST /api/v1/sweeps body (server/jobs/submission.h ParseSubmitRequest, with the
// Idempotency-Key header) and answers 201 with the submission and its Location, or the problem.
// POST /api/v1/campaigns/{name}/runs answers through it too (server/http/sweep_routes.cc).
void AnswerSubmission(Call& c, const json& body);

// ---- A row of the route table ------------------------------------------------------------------

using Handler = void (*)(Call&);

struct Route {
  const char* method;
  const char* path;
  Access access;
  BodyKind body;
  Handler handler;
};

// Each resource's routes (its *_routes.cc), in the order a reader of the API meets them.
const std::vector<Route>& SweepsRoutes();      // sweeps, runs, beds
const std::vector<Route>& CampaignsRoutes();   // campaigns and campaign runs
const std::vector<Route>& FiguresRoutes();     // figures, fits, reports, snapshots
const std::vector<Route>& LiveRoutes();        // the dashboard's live feed
const std::vector<Route>& WorkerRoutes();      // the worker protocol
const std::vector<Route>& OperationsRoutes();  // API description, health, metrics, cost model, backup

}  // namespace routes
}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_CALL_H_
