// LiveFeed: what the dashboard shows as it changes -- every recent sweep's and campaign run's
// counts (done / running / queued / failed / cancelled) with when their first run started (the
// page's ETA), and every running run's simulated time and z -- as one JSON snapshot that every
// open page shares.
//
// Cost: a snapshot is built at most once per tick however many pages watch, and only while
// someone asks (nothing runs when no page is open). Pages either wait for the next version
// (WaitNewer: GET /api/v1/live/events, server-sent events, one HTTP thread each, at most
// max_streams at once and max_streams_per_client from one peer address) or poll (Current: GET /api/v1/live, with an ETag). A snapshot whose
// content equals the last keeps its version, so a page hears only of changes.
//
// Trails: a running run's z(t) as its heartbeats reported it (one point per heartbeat), kept in
// memory for the run's page while it runs (ended when a snapshot shows the run not running, or
// after kTrailIdle without a beat); its stored trajectory replaces it at completion. A restarted
// daemon starts trails afresh (each run's latest progress is in the database anyway). Versions
// start from the clock in ms, so they never repeat across restarts.
//
// Stale: a rebuild that fails (the database cannot be read) serves the last snapshot's content
// with "stale": true and "built_at" (the daemon's clock when that content was read, s), under a new
// version, until a rebuild succeeds (then a new version again, without them). Absent otherwise.
//
// Snapshot JSON: {"version", "time" (the daemon's clock, s), "stale"?, "built_at"?, "runs": counts,
//   "sweeps": [{id, name, scale, campaign_run_id?, cancelled, counts, runs, created_at, started_at?}],
//   "campaign_runs": [{id, campaign, scale, trigger, created_at, sweeps, counts, started_at?,
//     rounds? (an adaptive one, server/jobs/rounds.h: {"rounds", "looks", "stopped"}, so that its
//     page asks for its rounds again only when the daemon has planned or looked)}],
//   "running": [{id, state, point, run_duration_s, progress, worker, attempts, started_at?, trail_points,
//                sweeps (the ids of the sweeps it is in)}]}
//
// Thread safety: every member is safe from any thread.
#ifndef SANDSWIM_SERVER_LIVE_FEED_H_
#define SANDSWIM_SERVER_LIVE_FEED_H_

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <optional>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "platform/clock.h"
#include "server/store/cost_model.h"
#include "server/store/eta_cache.h"
#include "server/store/store.h"

namespace sandswim {

class LiveFeed {
 public:
  struct Snapshot {
    uint64_t version = 0;
    std::string json;  // the whole snapshot, as sent
  };
  struct Trail {
    std::vector<double> t, z;  // simulated time (s) and the SO's z (m), one point per heartbeat
    double last_beat = 0;  // the clock's monotonic time (s) of its last beat
  };

  // Shown: the newest `sweeps` sweeps and `campaign_runs` campaign runs, and up to 1,000 running
  // runs. REQUIRES: store and clock outlive the feed; tick_s > 0.
  LiveFeed(Store* store, Clock* clock, double tick_s = 1.0, int max_streams = 128, int sweeps = 50,
           int campaign_runs = 20, int max_streams_per_client = 8);

  // The snapshot, rebuilt first when the last is a tick old (one caller builds; the others wait
  // for it and share it). A build that fails keeps the last snapshot's content, marked stale (logged).
  std::shared_ptr<const Snapshot> Current();
  // The first snapshot whose version is past `version`, or the current one after `wait_s` or
  // once Stop() was called.
  std::shared_ptr<const Snapshot> WaitNewer(uint64_t version, double wait_s);
  // Ends every wait; streams then close. Idempotent.
  void Stop();
  bool stopped() const { return stopped_.load(); }

  // A stream holds an HTTP thread: OpenStream says false once max_streams are open, or
  // max_streams_per_client from `client` (a peer address) (the page then polls). Every true is
  // paired with one CloseStream of the same client.
  bool OpenStream(const std::string& client = "");
  void CloseStream(const std::string& client = "");
  int open_streams() const { return streams_.load(); }

  // From a heartbeat the lease queue accepted. A beat earlier than the trail's last starts the
  // trail again (the run's next attempt); a trail no beat reached for kTrailIdleS ends (checked
  // at a beat, at most once per kTrailIdleS).
  void RecordBeat(int64_t run_id, double sim_time_s, double so_z);
  // The run's trail so far (empty when it is not running or no beat came since the daemon started).
  Trail TrailOf(int64_t run_id) const;

  // Engines the ETAs of unfinished sweeps and campaign runs spread work over, at least (server/store/cost_model.h).
  void set_engine_slots(int slots) { engine_slots_.store(slots); }
  // Where the board's ETAs come from: the routes' cache (server/store/eta_cache.h), so that a
  // sweep's status and the board share one read. nullptr (the default): read at each build.
  // REQUIRES: set before the feed is used; `etas` outlives it.
  void set_eta_cache(EtaCache* etas) { etas_ = etas; }

  uint64_t builds() const { return builds_.load(); }  // snapshots built (for tests and benchmarks)
  static constexpr size_t kMaxTrailPoints = 4096;     // past it, every other point is dropped
  static constexpr double kTrailIdleS = 600;  // a trail no beat reached for this long (s) ends

 private:
  std::string BuildContent();  // the snapshot without version and time; "" when it cannot
  std::string BuildContentOrThrow();
  nlohmann::json EtaOf(EtaScope scope, int64_t id);  // EtaJson, null when it cannot be read
  // An adaptive campaign run's {"rounds","looks","stopped"}; null when it cannot be read.
  nlohmann::json RoundsOf(int64_t campaign_run_id);

  Store* store_;
  Clock* clock_;
  const double tick_s_;
  const int max_streams_, sweeps_, campaign_runs_, max_streams_per_client_;

  std::mutex build_mu_;  // one builder at a time
  mutable std::mutex mu_;
  std::condition_variable changed_;
  std::shared_ptr<const Snapshot> current_;
  double built_at_ = 0;  // the clock's monotonic time of the last build
  std::string last_content_;
  double content_built_at_ = 0;  // the clock's wall time when last_content_ was read
  bool stale_ = false;           // the last build failed: current_ serves older content
  std::atomic<int> engine_slots_{0};
  EtaCache* etas_ = nullptr;
  uint64_t version_ = 0;
  std::map<int64_t, Trail> trails_;
  std::optional<double> last_idle_sweep_;  // monotonic; unset before the first beat

  std::atomic<bool> stopped_{false};
  std::atomic<int> streams_{0};
  std::mutex clients_mu_;
  std::map<std::string, int> streams_by_client_;
  std::atomic<uint64_t> builds_{0};
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_LIVE_FEED_H_
