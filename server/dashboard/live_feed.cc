#include "server/dashboard/live_feed.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "core/api.h"
#include "server/store/cost_model.h"
#include "server/store/rounds.h"

namespace sandswim {

using json = nlohmann::json;

LiveFeed::LiveFeed(Store* store, Clock* clock, double tick_s, int max_streams, int sweeps, int campaign_runs,
                   int max_streams_per_client)
    : store_(store),
      clock_(clock),
      tick_s_(tick_s),
      max_streams_(max_streams),
      sweeps_(sweeps),
      campaign_runs_(campaign_runs),
      max_streams_per_client_(max_streams_per_client) {}

std::string LiveFeed::BuildContent() {
  try {
    return BuildContentOrThrow();
  } catch (const std::exception& e) {  // e.g. a string that is not UTF-8: keep the last snapshot
    spdlog::warn("live feed: cannot build a snapshot ({}); pages keep the last one, marked stale", e.what());
    return "";
  }
}

json LiveFeed::EtaOf(EtaScope scope, int64_t id) {
  Result<std::optional<Eta>> eta = etas_ != nullptr ? etas_->Get(scope, id, clock_->Now(), engine_slots_.load())
                                                    : ReadEta(*store_, scope, id, clock_->Now(), engine_slots_.load());
  if (!eta.ok()) {
    spdlog::warn("live feed: no ETA ({})", eta.status().ToString());
    return nullptr;
  }
  json j = EtaJson(*eta);
  // Whole seconds: a snapshot changes when the estimate does, not with every clock tick's fraction.
  if (j.is_object()) {
    for (const char* k : {"s", "low_s", "high_s"}) j[k] = std::round(j[k].get<double>());
  }
  return j;
}

// How far an adaptive campaign run's rounds are: rounds planned, looks taken, whether they stopped.
json LiveFeed::RoundsOf(int64_t campaign_run_id) {
  Result<std::vector<rounds::RoundRow>> rows = rounds::ListRounds(*store_, campaign_run_id);
  if (!rows.ok()) {
    spdlog::warn("live feed: no rounds of campaign run {} ({})", campaign_run_id, rows.status().ToString());
    return nullptr;
  }
  int looks = 0;
  bool stopped = false;
  for (const rounds::RoundRow& r : *rows) {
    looks += r.finished_at.has_value();
    stopped = stopped || r.stop_reason.has_value();
  }
  return {{"rounds", rows->size()}, {"looks", looks}, {"stopped", stopped}};
}

std::string LiveFeed::BuildContentOrThrow() {
  Result<LiveBoard> board = store_->ReadLiveBoard(sweeps_, campaign_runs_, 1000);
  if (!board.ok()) {
    spdlog::warn("live feed: cannot read the board ({}); pages keep the last snapshot, marked stale", board.status().ToString());
    return "";
  }
  json sweeps = json::array();
  for (const SweepInfo& s : board->sweeps) {
    json j = s;
    j.erase("spec");
    if (auto it = board->sweep_started_at.find(s.id); it != board->sweep_started_at.end()) j["started_at"] = it->second;
    if (s.counts.queued + s.counts.running > 0) j["eta"] = EtaOf(EtaScope::kSweep, s.id);
    sweeps.push_back(std::move(j));
  }
  json campaign_runs = json::array();
  for (const CampaignRunInfo& c : board->campaign_runs) {
    json j = c;
    if (auto it = board->campaign_run_started_at.find(c.id); it != board->campaign_run_started_at.end()) {
      j["started_at"] = it->second;
    }
    if (c.counts.queued + c.counts.running > 0) j["eta"] = EtaOf(EtaScope::kCampaignRun, c.id);
    if (rounds::RunsInRounds(c)) j["rounds"] = RoundsOf(c.id);
    campaign_runs.push_back(std::move(j));
  }
  json running = json::array();
  std::set<int64_t> running_ids;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const RunSummary& r : board->running) {
      running_ids.insert(r.id);
      json j = r;
      auto sweeps = board->running_sweeps.find(r.id);
      j["sweeps"] = sweeps == board->running_sweeps.end() ? std::vector<int64_t>() : sweeps->second;
      auto it = trails_.find(r.id);
      j["trail_points"] = it == trails_.end() ? 0 : it->second.t.size();
      running.push_back(std::move(j));
    }
    // Trails of runs the board shows not running end (runs past the board's 1,000 are left to
    // RecordBeat's idle sweep).
    for (auto it = trails_.begin(); it != trails_.end();) {
      it = running_ids.count(it->first) || board->running.size() >= 1000 ? std::next(it) : trails_.erase(it);
    }
  }
  json content = {
      {"runs", board->runs}, {"sweeps", sweeps}, {"campaign_runs", campaign_runs}, {"running", running}};
  return content.dump();
}

std::shared_ptr<const LiveFeed::Snapshot> LiveFeed::Current() {
  std::lock_guard<std::mutex> build(build_mu_);
  const double now = clock_->Monotonic();
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (current_ && now - built_at_ < tick_s_) return current_;
  }
  std::string content = BuildContent();
  builds_.fetch_add(1);
  std::lock_guard<std::mutex> lock(mu_);
  built_at_ = now;
  bool stale = false;
  if (content.empty()) {  // the read failed: pages keep what they have, told that it is stale
    if (current_) {
      stale = true;
      content = last_content_;
    } else {
      content = json{{"error", "the daemon cannot read its database; see its log"}}.dump();
    }
  } else {
    content_built_at_ = clock_->Now();
  }
  // Becoming stale or fresh again is a change: a client holding the last ETag must hear of it.
  const bool changed = !current_ || content != last_content_ || stale != stale_;
  stale_ = stale;
  if (changed) {
    // Versions start from the daemon's clock in ms, so a page's version or ETag from before a
    // restart is never taken for a newer snapshot's.
    version_ = version_ == 0 ? std::max<uint64_t>(1, static_cast<uint64_t>(clock_->Now() * 1000)) : version_ + 1;
    last_content_ = std::move(content);
  }
  // {"version":N,"time":T, ...content}: the content's leading brace is replaced. The time is the
  // build's even when the content is unchanged (a page's ETA counts from it).
  auto snap = std::make_shared<Snapshot>();
  snap->version = version_;
  char stale_fields[64] = "";
  if (stale_) std::snprintf(stale_fields, sizeof stale_fields, ",\"stale\":true,\"built_at\":%.3f", content_built_at_);
  char head[160];
  std::snprintf(head, sizeof head, "{\"version\":%llu,\"time\":%.3f%s%s", static_cast<unsigned long long>(version_),
                clock_->Now(), stale_fields, last_content_.size() > 2 ? "," : "");
  snap->json = head + last_content_.substr(1);
  current_ = std::move(snap);
  if (changed) changed_.notify_all();
  return current_;
}

std::shared_ptr<const LiveFeed::Snapshot> LiveFeed::WaitNewer(uint64_t version, double wait_s) {
  using Steady = std::chrono::steady_clock;
  const Steady::time_point deadline =
      Steady::now() + std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(wait_s));
  while (true) {
    std::shared_ptr<const Snapshot> snap = Current();
    if (snap->version > version || stopped() || Steady::now() >= deadline) return snap;
    std::unique_lock<std::mutex> lock(mu_);
    // The wait is real time (a condition variable's); whether a tick has passed is the clock's (Current).
    const Steady::time_point until =
        std::min(deadline, Steady::now() + std::chrono::duration_cast<Steady::duration>(std::chrono::duration<double>(tick_s_)));
    changed_.wait_until(lock, until, [&] { return stopped() || (current_ && current_->version > version); });
  }
}

void LiveFeed::Stop() {
  stopped_.store(true);
  std::lock_guard<std::mutex> lock(mu_);
  changed_.notify_all();
}

bool LiveFeed::OpenStream(const std::string& client) {
  std::lock_guard<std::mutex> lock(clients_mu_);
  int& mine = streams_by_client_[client];
  if (mine >= max_streams_per_client_ || streams_.load() >= max_streams_ || stopped()) {
    if (mine == 0) streams_by_client_.erase(client);
    return false;
  }
  ++mine;
  streams_.fetch_add(1);
  return true;
}

void LiveFeed::CloseStream(const std::string& client) {
  std::lock_guard<std::mutex> lock(clients_mu_);
  auto it = streams_by_client_.find(client);
  if (it != streams_by_client_.end() && --it->second <= 0) streams_by_client_.erase(it);
  streams_.fetch_sub(1);
}

void LiveFeed::RecordBeat(int64_t run_id, double sim_time_s, double so_z) {
  const double now = clock_->Monotonic();
  std::lock_guard<std::mutex> lock(mu_);
  // Trails of runs that stopped beating end, whether or not a page asked for a snapshot since.
  if (!last_idle_sweep_ || now - *last_idle_sweep_ > kTrailIdleS) {
    last_idle_sweep_ = now;
    for (auto it = trails_.begin(); it != trails_.end();) {
      it = now - it->second.last_beat > kTrailIdleS ? trails_.erase(it) : std::next(it);
    }
  }
  Trail& trail = trails_[run_id];
  trail.last_beat = now;
  if (!trail.t.empty() && sim_time_s == trail.t.back()) return;  // the same beat again (a retried request)
  if (!trail.t.empty() && sim_time_s < trail.t.back()) {          // an attempt started again: a new trail
    trail.t.clear();
    trail.z.clear();
  }
  trail.t.push_back(sim_time_s);
  trail.z.push_back(so_z);
  if (trail.t.size() >= kMaxTrailPoints) {  // keep the whole run at half the resolution, and its last point
    size_t w = 0;
    for (size_t i = 0; i + 1 < trail.t.size(); i += 2, ++w) {
      trail.t[w] = trail.t[i];
      trail.z[w] = trail.z[i];
    }
    trail.t[w] = trail.t.back();
    trail.z[w] = trail.z.back();
    trail.t.resize(w + 1);
    trail.z.resize(w + 1);
  }
}

LiveFeed::Trail LiveFeed::TrailOf(int64_t run_id) const {
  std::lock_guard<std::mutex> lock(mu_);
  auto it = trails_.find(run_id);
  if (it == trails_.end()) return Trail{};
  Trail copy;
  copy.t = it->second.t;
  copy.z = it->second.z;
  return copy;
}

}  // namespace sandswim
