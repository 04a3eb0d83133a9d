#include "cli/snapshot.h"

#include <algorithm>
#include <charconv>
#include <set>
#include <vector>

namespace sandswim::cli {
namespace {

using json = nlohmann::json;

double NumOr(const json& j, const char* key, double fallback) {
  auto it = j.find(key);
  return it != j.end() && it->is_number() ? it->get<double>() : fallback;
}

std::string FailureReason(const json& run) {
  auto it = run.find("last_error");
  if (it == run.end() || !it->is_object()) return "(no reason recorded)";
  std::string kind = it->value("kind", "");
  std::string message = it->value("message", "");
  if (kind.empty()) return message.empty() ? "(no reason recorded)" : message;
  return message.empty() ? kind : kind + ": " + message;
}

// The daemon's "eta" object (server/store/cost_model.h EtaJson), absent or null: none.
std::optional<Snapshot::DaemonEta> EtaFrom(const json& j) {
  auto it = j.find("eta");
  if (it == j.end() || !it->is_object() || !(*it)["s"].is_number()) return std::nullopt;
  return Snapshot::DaemonEta{(*it)["s"].get<double>(), NumOr(*it, "rel_error", 0), it->value("basis", ""),
                             NumOr(*it, "low_s", 0), NumOr(*it, "high_s", 0)};
}

// A running run as GET /api/v1/runs and the progress board list it.
RunInFlight InFlight(const json& run) {
  const json progress = run.value("progress", json::object());
  RunInFlight r;
  r.id = run.value("id", int64_t{0});
  r.point = FormatPoint(run.value("point", json::object()));
  r.sim_time_s = NumOr(progress, "sim_time_s", 0);
  r.duration_s = NumOr(run, "run_duration_s", 0);
  r.so_z = NumOr(progress, "so_z", 0);
  r.worker = run.value("worker", "");
  return r;
}

std::string SweepTitle(int64_t id, const json& sweep) {
  return "sweep " + std::to_string(id) + " " + sweep.value("name", "") + " (scale " + sweep.value("scale", "?") +
         (sweep.value("cancelled", false) ? ", cancelled" : "") + ")";
}

std::string CampaignRunTitle(int64_t id, const json& run) {
  return "campaign run cr:" + std::to_string(id) + " " + run.value("campaign", "") + " (scale " +
         run.value("scale", "?") + ", " + run.value("trigger", "manual") + ")";
}

// Adds the runs of one sweep (running and failed) to the snapshot, skipping run ids already seen
// (campaign runs share runs between sweeps).
Status AddRuns(DaemonClient& client, int64_t sweep_id, Snapshot& s, std::set<int64_t>& seen) {
  for (const char* state : {"running", "failed"}) {
    RunQuery query;
    query.sweep = sweep_id;
    query.state = state;
    auto runs = client.ListRuns(query);
    if (!runs.ok()) return runs.status();
    for (const json& run : *runs) {
      int64_t id = run.value("id", int64_t{0});
      if (!seen.insert(id).second) continue;
      if (std::string(state) == "running") {
        s.running.push_back(InFlight(run));
      } else {
        s.failed.push_back({id, FormatPoint(run.value("point", json::object())), FailureReason(run)});
      }
    }
  }
  return Status::Ok();
}

// When runs are queued and none runs: the state of the bed the first queued run of `sweep_ids`
// waits for (two small requests).
Status AddWaitingBedState(DaemonClient& client, const std::vector<int64_t>& sweep_ids, Snapshot& s);

// Runs in flight the progress board lists at most (server/dashboard/live_feed.cc).
constexpr size_t kBoardRunning = 1000;

// Live()'s failures that say this daemon has no board at all: no such route (404, a daemon from
// before the board) or the 503 of a daemon serving no live feed (server/http/live_routes.cc).
bool NoBoard(const Status& s) {
  return s.code() == StatusCode::kNotFound ||
         (s.code() == StatusCode::kUnavailable && s.reason().find("serves no live feed") != std::string::npos);
}

}  // namespace

std::string Target::ToString() const { return (kind == Kind::kCampaignRun ? "cr:" : "") + std::to_string(id); }

Result<int64_t> ParseId(const std::string& text, const std::string& field) {
  int64_t v = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (text.empty() || ec != std::errc() || end != text.data() + text.size() || v < 1) {
    return Status::InvalidArgument(field, "expected a positive integer id, got \"" + text + "\"");
  }
  return v;
}

Result<Target> ParseTarget(const std::string& text, const std::string& field) {
  Target t;
  std::string id = text;
  if (text.rfind("cr:", 0) == 0) {
    t.kind = Target::Kind::kCampaignRun;
    id = text.substr(3);
  } else if (text.rfind("sweep:", 0) == 0) {
    id = text.substr(6);
  }
  auto v = ParseId(id, field);
  if (!v.ok()) {
    return Status::InvalidArgument(field, "expected a sweep id (12) or a campaign run id (cr:7), got \"" + text + "\"");
  }
  t.id = *v;
  return t;
}

Result<Snapshot> FetchSnapshot(DaemonClient& client, const Target& target) {
  Snapshot s;
  std::vector<int64_t> sweep_ids;
  if (target.kind == Target::Kind::kSweep) {
    auto sweep = client.GetSweep(target.id);
    if (!sweep.ok()) return sweep.status();
    s.title = SweepTitle(target.id, *sweep);
    s.counts = CountsFromJson(sweep->value("counts", json::object()));
    s.eta = EtaFrom(*sweep);
    sweep_ids.push_back(target.id);
  } else {
    auto run = client.GetCampaignRun(target.id);
    if (!run.ok()) return run.status();
    s.title = CampaignRunTitle(target.id, *run);
    s.counts = CountsFromJson(run->value("counts", json::object()));
    s.eta = EtaFrom(*run);
    s.adaptive = run->value("adaptive", json());
    s.rounds = run->value("rounds", json::array());
    for (const json& id : run->value("sweeps", json::array())) {
      if (id.is_number_integer()) sweep_ids.push_back(id.get<int64_t>());
    }
  }
  std::set<int64_t> seen;
  for (int64_t sweep_id : sweep_ids) {
    SANDSWIM_RETURN_IF_ERROR(AddRuns(client, sweep_id, s, seen));
  }
  SANDSWIM_RETURN_IF_ERROR(AddWaitingBedState(client, sweep_ids, s));
  return s;
}

Result<Snapshot> FetchSnapshotFromBoard(DaemonClient& client, const Target& target, bool* board_usable) {
  if (*board_usable) {
    Result<json> board = client.Live();
    if (board.ok()) {
      std::vector<int64_t> sweep_ids;
      BoardMiss miss = BoardMiss::kThisRefresh;
      Result<std::optional<Snapshot>> view = SnapshotFromBoard(*board, target, &sweep_ids, &miss);
      if (view.ok() && view->has_value()) {
        Snapshot s = std::move(**view);
        SANDSWIM_RETURN_IF_ERROR(AddWaitingBedState(client, sweep_ids, s));
        return s;
      }
      // Older than everything the board lists, or a board from before runs named their sweeps: it
      // will not show the target later either. Otherwise (newer than the board, which is rebuilt
      // at most once a tick; more runs in flight than it lists; unreadable; stale): this refresh only.
      if (view.ok() && miss == BoardMiss::kForGood) *board_usable = false;
    } else if (NoBoard(board.status())) {
      *board_usable = false;  // an older daemon (no route), or one without a live feed
    }
    // Any other failure (a busy daemon, a 500) may pass: the target's own routes for this refresh,
    // the board again at the next. A daemon that cannot be reached fails those too: Watch skips
    // the refresh (watch.h).
  }
  return FetchSnapshot(client, target);
}

Result<std::optional<Snapshot>> SnapshotFromBoard(const json& board, const Target& target,
                                                  std::vector<int64_t>* target_sweeps, BoardMiss* miss) {
  BoardMiss ignored;
  if (miss == nullptr) miss = &ignored;
  *miss = BoardMiss::kNone;
  // A board the daemon failed to rebuild (server/dashboard/live_feed.h) may show a target as it
  // was: its own routes for this refresh, the board again at the next.
  if (auto stale = board.find("stale"); stale != board.end() && *stale == true) {
    *miss = BoardMiss::kThisRefresh;
    return std::optional<Snapshot>();
  }
  try {
    Snapshot s;
    std::vector<int64_t> sweep_ids;  // the target's, in its own order
    const char* list = target.kind == Target::Kind::kSweep ? "sweeps" : "campaign_runs";
    const json listed = board.value(list, json::array());
    const json* entry = nullptr;
    std::optional<int64_t> oldest_listed;
    for (const json& e : listed) {
      const int64_t id = e.value("id", int64_t{0});
      if (id == target.id) entry = &e;
      oldest_listed = std::min(id, oldest_listed.value_or(id));
    }
    if (entry == nullptr) {
      // The board lists the newest sweeps and campaign runs: one older than all it lists is never
      // on it; a newer one is once the board is rebuilt.
      *miss = oldest_listed && target.id < *oldest_listed ? BoardMiss::kForGood : BoardMiss::kThisRefresh;
      return std::optional<Snapshot>();
    }
    if (target.kind == Target::Kind::kSweep) {
      s.title = SweepTitle(target.id, *entry);
      sweep_ids.push_back(target.id);
    } else {
      s.title = CampaignRunTitle(target.id, *entry);
      for (const json& id : entry->value("sweeps", json::array())) {
        const int64_t sweep = id.get<int64_t>();
        if (std::find(sweep_ids.begin(), sweep_ids.end(), sweep) == sweep_ids.end()) sweep_ids.push_back(sweep);
      }
    }
    s.counts = CountsFromJson(entry->value("counts", json::object()));
    s.eta = EtaFrom(*entry);
    const json running = board.value("running", json::array());
    std::vector<std::set<int64_t>> in_sweeps;  // each running run's sweeps, as the board lists them
    for (const json& run : running) {
      auto in = run.find("sweeps");
      if (in == run.end() || !in->is_array()) {  // a board from before "sweeps": it never will say
        *miss = BoardMiss::kForGood;
        return std::optional<Snapshot>();
      }
      in_sweeps.emplace_back();
      for (const json& id : *in) in_sweeps.back().insert(id.get<int64_t>());
    }
    // Grouped by sweep, in the target's order (a run in two of its sweeps under the first), as
    // FetchSnapshot lists them.
    std::set<int64_t> seen;
    for (int64_t sweep : sweep_ids) {
      for (size_t i = 0; i < running.size(); ++i) {
        if (in_sweeps[i].count(sweep) == 0) continue;
        const RunInFlight r = InFlight(running[i]);
        if (seen.insert(r.id).second) s.running.push_back(r);
      }
    }
    // The board lists at most kBoardRunning runs in flight: past it, some of the target's may be missing.
    if (static_cast<int64_t>(s.running.size()) < s.counts.running && running.size() >= kBoardRunning) {
      *miss = BoardMiss::kThisRefresh;
      return std::optional<Snapshot>();
    }
    if (target_sweeps != nullptr) *target_sweeps = sweep_ids;
    return std::optional<Snapshot>(std::move(s));
  } catch (const json::exception& e) {
    *miss = BoardMiss::kThisRefresh;
    return Status::Corruption(std::string("the daemon's progress board is unreadable: ") + e.what());
  }
}

namespace {

Status AddWaitingBedState(DaemonClient& client, const std::vector<int64_t>& sweep_ids, Snapshot& s) {
  if (s.counts.running != 0 || s.counts.queued == 0) return Status::Ok();
  // Two small requests, only while nothing runs: the first queued run names its bed's state.
  for (int64_t sweep_id : sweep_ids) {
    RunQuery query;
    query.sweep = sweep_id;
    query.state = "queued";
    query.limit = 1;
    auto runs = client.ListRuns(query);
    if (!runs.ok()) return runs.status();
    if (runs->empty()) continue;
    auto run = client.GetRun((*runs)[0].value("id", int64_t{0}));
    if (!run.ok()) return run.status();
    s.waiting_bed_state = run->value("bed_state", "");
    break;
  }
  return Status::Ok();
}

}  // namespace

Result<json> FetchResults(DaemonClient& client, const Target& target) {
  auto reply =
      target.kind == Target::Kind::kSweep ? client.SweepResults(target.id) : client.CampaignRunResults(target.id);
  if (!reply.ok()) return reply.status();
  auto rows = reply->find("results");
  if (rows == reply->end() || !rows->is_array()) {
    return Status::Corruption("the daemon's results for " + target.ToString() + " have no \"results\" array");
  }
  json out = *reply;
  if (!out.contains("aggregates") || !out["aggregates"].is_array()) out["aggregates"] = json::array();
  return out;
}

}  // namespace sandswim::cli
