// Store: the daemon's data as the REST API reads it. A Store holds the daemon's Database
// (server/store/database.h: the SQLite adapter, transactions, group commit, migrations, db()) and
// gives the read views of the API: values whose JSON shapes are those of the REST API, each read
// in one read transaction. One write is its own: results stored by an older analysis, analysed
// again at the daemon's start (ReanalyzeOldResults). The other rows are written through the store
// room's tables by the modules that decide them: job_table.h (the lease queue),
// submission_table.h (submission), schedule_table.h (the scheduler), drift_table.h (drift
// reports), campaigns.h (campaigns and their versions).
//
// Thread safety: as Database: every read takes the connection's lock for its duration.
#ifndef SANDSWIM_SERVER_STORE_STORE_H_
#define SANDSWIM_SERVER_STORE_STORE_H_

#include <cstdint>
#include <memory>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/deck.h"
#include "core/job_state.h"
#include "core/point.h"
#include "core/result_fields.h"
#include "core/status.h"
#include "server/store/database.h"

namespace sandswim {

// ---- Read models (values; JSON shapes are those of the REST API) -------------------------------

struct RunCounts {
  int64_t queued = 0, running = 0, done = 0, failed = 0, cancelled = 0;
  int64_t total() const { return queued + running + done + failed + cancelled; }
  // The count of state `s` (the member of its name).
  int64_t& operator[](JobState s);
  int64_t operator[](JobState s) const { return const_cast<RunCounts&>(*this)[s]; }
};
void to_json(nlohmann::json& j, const RunCounts& c);  // {"queued":..,...,"cancelled":..}

struct SweepInfo {
  int64_t id = 0;
  std::string name;
  std::string scale;
  nlohmann::json spec;  // the sweep as submitted (normalised: values materialised)
  std::optional<int64_t> campaign_run_id;
  bool force = false;
  double created_at = 0;
  std::optional<double> cancelled_at;
  RunCounts counts;  // of its runs, by state
};
// {"id","name","scale","spec","campaign_run_id"?,"force","created_at","cancelled_at"?,
//  "cancelled": bool, "counts": {...}, "runs": total}
void to_json(nlohmann::json& j, const SweepInfo& s);

struct SweepPage {
  std::vector<SweepInfo> sweeps;       // ascending id
  std::optional<int64_t> next_cursor;  // pass as after_id for the next page
};
void to_json(nlohmann::json& j, const SweepPage& p);  // {"sweeps":[...], "next_cursor": id|null}

struct Progress {
  double sim_time_s = 0;
  double so_z = 0;
  int64_t step = 0;
  std::optional<double> heartbeat_at;
};
void to_json(nlohmann::json& j, const Progress& p);

// A run's result row: StoredResult (core/result_fields.h, every field described once), its JSON
// the fields under their names plus "uz_text".

struct RunSummary {
  int64_t id = 0;
  std::string key;
  JobState state = JobState::kQueued;
  Point point;
  double run_duration_s = 0;  // at most, with a precision target
  int64_t steps = 0;
  std::optional<PrecisionTarget> precision;  // the run's target (core/precision.h); absent: none
  SnapshotFractions snapshots;               // full-bed snapshots it takes (core/deck.h); empty: none
  int64_t bed_id = 0;
  int attempts = 0;
  std::string worker;  // "" unless leased at least once
  Progress progress;
  double created_at = 0;
  std::optional<double> started_at, finished_at;
  std::optional<double> uz;  // from the result row, when there is one
  std::string uz_text;       // DescribeUz of that result ("" without one)
  std::optional<api::Failure> last_error;
};
// {"id","key","state","point":{PointToJson},"run_duration_s","steps","precision"?,"snapshots"?,"bed_id","attempts",
//  "worker","progress":{...},"created_at","started_at"?,"finished_at"?,"uz"?,"uz_text"?,
//  "last_error"?}
void to_json(nlohmann::json& j, const RunSummary& r);

struct RunFilter {
  std::optional<int64_t> sweep_id;
  std::optional<JobState> state;
  int64_t after_id = 0;              // cursor: runs with id > after_id
  int limit = 100;                   // clamped to [1, 1000]
};

struct RunPage {
  std::vector<RunSummary> runs;        // ascending id
  std::optional<int64_t> next_cursor;  // set when more rows may follow
};
void to_json(nlohmann::json& j, const RunPage& p);  // {"runs":[...], "next_cursor": id|null}

struct RunDetail {
  RunSummary summary;
  std::string deck;
  std::string bed_key;
  JobState bed_state = JobState::kQueued;
  std::vector<int64_t> sweep_ids;
  std::optional<StoredResult> result;
  std::optional<api::Trajectory> trajectory;
  std::string log_tail;
  std::vector<api::Snapshot> snapshots;  // handed in (schema/010_snapshots.sql), by idx
};
// The summary's fields plus "deck","bed_key","bed_state","sweeps":[ids],"result"?,
// "trajectory"?,"log_tail","snapshots_taken":[api::Snapshot, each with "links" to its files].
void to_json(nlohmann::json& j, const RunDetail& r);

// One row of a sweep's results: its point and, when done, U_z and the other figures.
struct ResultRow {
  int64_t run_id = 0;
  std::string key;
  JobState state = JobState::kQueued;
  Point point;
  double run_duration_s = 0;
  int64_t bed_id = 0;
  int replicate = 0;  // its bed's replicate index (core/aggregate.h)
  std::optional<StoredResult> result;
  std::vector<std::string> sweeps;  // a campaign run's page: the names of its sweeps holding the run, by id
};
// The API's JSON of a result row is core/result_table.h's (server/http/result_rows.h ResultRowJson).

// Whose results a page (Store::ResultsPage) is of.
enum class ResultsOf {
  kSweep,        // a sweep's runs in its expansion order (sweep_runs.position)
  kCampaignRun,  // a campaign run's distinct runs: sweep by sweep (by id), each in its expansion
                 // order, a run once, where it first appears; each row names its sweeps
};
// Where a page of results starts: after this row of the order above. The default is before the
// first row. A cursor stays valid while the rows change (new results, states), since sweeps never
// gain or lose runs once submitted.
struct ResultCursor {
  int64_t sweep_id = 0;
  int64_t position = -1;
};
struct ResultPage {
  std::vector<ResultRow> rows;
  std::optional<ResultCursor> next;  // set when more rows may follow: pass it as `after`
};
inline constexpr int kMaxResultsPage = 10000;  // rows of a results page at most

struct CampaignRunInfo {
  int64_t id = 0;
  std::string campaign;
  std::string scale;
  std::string trigger;  // "manual" | "schedule"
  std::optional<double> due_time;
  double created_at = 0;
  std::vector<int64_t> sweep_ids;
  RunCounts counts;  // of the distinct runs of its sweeps
  // What it ran (schema/013_campaign_versions.sql): the campaign's version (0: built-in), the
  // resolved definition and its SHA-256 (campaigns.h DefinitionSha256). Unset/null/"" for a
  // campaign run made before the migration.
  std::optional<int> campaign_version;
  nlohmann::json definition;
  std::string definition_sha256;
};
// {"id","campaign","scale","trigger","created_at","sweeps","counts","due_time"?,
//  "campaign_version" (int|null),"definition_sha256" (string|null)}: the definition is left out.
void to_json(nlohmann::json& j, const CampaignRunInfo& c);

struct StoredCampaign {
  std::string name;
  nlohmann::json definition;  // as accepted by ParseCampaign()
  std::optional<std::string> schedule;
  double updated_at = 0;
  int version = 0;  // its current version (server/store/campaigns.h)
};
void to_json(nlohmann::json& j, const StoredCampaign& c);

// A bed as the API shows it: what it is (scale, replicate, seeds), its state and, once prepared,
// what it is like (api::BedResult: grains, height, the SO's depth, packing around the SO).
struct BedView {
  int64_t id = 0;
  std::string key;
  std::string scale;
  int replicate = 0;
  std::optional<int64_t> seed_pour1, seed_pour2;  // absent for beds made before replicates
  JobState state = JobState::kQueued;             // never cancelled
  int attempts = 0;
  std::optional<api::BedResult> result;
  // The MPI ranks it was prepared on; absent while not done, and for beds prepared before they
  // were recorded (the cost model counts those as one rank).
  std::optional<int> ranks;
  std::optional<api::Failure> last_error;
  int64_t runs = 0;  // runs on this bed
  double created_at = 0;
  std::optional<double> finished_at;
};
// {"id","key","scale","replicate","seeds":{"pour1","pour2"}?,"state","attempts","result"?,"ranks"?,
//  "last_error"?,"runs","created_at","finished_at"?}
void to_json(nlohmann::json& j, const BedView& b);

struct Metrics {
  RunCounts runs;  // by state
  RunCounts beds;  // by state (cancelled is always 0)
  int64_t sweeps = 0;
  int64_t leases_granted = 0;
  int64_t completions = 0;  // accepted completions (not duplicates)
  int64_t expirations = 0;  // leases that ran out
  int64_t pilots_gone = 0;  // leases reclaimed early: their Slurm job was gone (server/jobs/pilot_watch.h)
  int64_t duplicates = 0;   // repeated completions answered "duplicate"
};
void to_json(nlohmann::json& j, const Metrics& m);

// What the dashboard's live feed shows (server/dashboard/live_feed.h), read in one transaction: the newest
// sweeps and campaign runs with their counts (specs left out), every running run with its
// progress, and, for each sweep or campaign run with runs still to do, when its first run started.
struct LiveBoard {
  std::vector<SweepInfo> sweeps;               // newest first
  std::vector<CampaignRunInfo> campaign_runs;  // newest first
  std::vector<RunSummary> running;             // by id
  std::map<int64_t, std::vector<int64_t>> running_sweeps;  // the sweeps of each run in `running`, ascending
  std::map<int64_t, double> sweep_started_at;         // unfinished sweeps whose runs have started
  std::map<int64_t, double> campaign_run_started_at;  // the same, for campaign runs
  RunCounts runs;                                     // every run, by state
};

class Store {
 public:
  // Opens (creating if needed) the SQLite file at `path` and migrates it.
  static Result<std::unique_ptr<Store>> Open(const std::string& path);
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  // The database the reads go through, for the store-side tables (job_table.h, cost_model.h) and
  // the writes of the modules that own them (transactions, group commit, backups, health).
  Database& db() { return *db_; }
  const std::string& path() const { return db_->path(); }

  // ---- Reads for the REST API. NotFound when the id does not exist. ----
  Result<SweepPage> ListSweeps(int64_t after_id = 0, int limit = 100);
  Result<SweepInfo> GetSweep(int64_t id);
  Result<RunPage> ListRuns(const RunFilter& filter);
  // A run with its deck (GET /api/v1/runs/{id} shows it) or without (RunDetail::deck ""). A deck
  // is rendered on each read (a pure function of the point and the scale, not stored since
  // migration 3): the reads that do not show it -- figures, snapshots, reports -- leave it out.
  enum class Deck { kRendered, kLeftOut };
  Result<RunDetail> GetRun(int64_t id, Deck deck = Deck::kRendered);
  // The stored trajectory of every done run of the sweep that has one, by run id, in one read:
  // what the sweep's analysis draws (no run read, no deck, log or snapshot list per run). Runs not
  // done are not read (a trajectory they left that does not parse fails nothing).
  Result<std::map<int64_t, api::Trajectory>> SweepTrajectories(int64_t sweep_id);
  Result<BedView> GetBed(int64_t id);
  // Every bed, by id.
  Result<std::vector<BedView>> ListBeds();
  // Every run of the sweep in its expansion order (sweep_runs.position).
  Result<std::vector<ResultRow>> SweepResults(int64_t sweep_id);
  // At most `limit` (clamped to [1, kMaxResultsPage]) rows of a sweep's or a campaign run's
  // results after `after`, in one read transaction: what a page of GET .../results shows and what
  // a results stream reads at a time, so that no read holds a whole 100,000-run set in memory.
  Result<ResultPage> ResultsPage(ResultsOf of, int64_t id, const ResultCursor& after, int limit);
  // Every run of a sweep's or a campaign run's results that drives the SO as one of `points` does
  // (core/point.h SameDrive: all but the duration, materials included), each run once, in the
  // set's order: the runs a results page's aggregates are over, so that a point's aggregate is
  // never partial, wherever in the set its other runs stand. One read transaction: one pass over
  // the set's run ids and drive numbers, whole rows read only for those that match.
  Result<std::vector<ResultRow>> ResultsOfDrives(ResultsOf of, int64_t id, const std::vector<Point>& points);
  Result<CampaignRunInfo> GetCampaignRun(int64_t id);
  // Newest first; `campaign` empty for all campaigns.
  Result<std::vector<CampaignRunInfo>> ListCampaignRuns(const std::string& campaign, int limit = 20);
  Result<std::optional<StoredCampaign>> GetCampaign(const std::string& name);
  Result<std::vector<StoredCampaign>> ListCampaigns();
  Result<Metrics> GetMetrics();
  // REQUIRES: limits >= 1.
  Result<LiveBoard> ReadLiveBoard(int sweeps, int campaign_runs, int running);

  // Re-analyses every result made by analysis 1 or 2 (their numbers or intervals were wrong) by
  // api::kAnalysisVersion from its stored
  // trajectory (the run's drive frequency, its bed's surface and its scale's floor, the stop the
  // engine reported), in pages of rows written one transaction each; such a result says
  // analysed_from "trajectory". A result with no trajectory that can be re-analysed keeps its old
  // numbers, stays inconclusive with the reason and is marked "unreadable", never tried again.
  // A result of analysis 2 that its run's precision target did not end keeps its numbers (3 changed
  // only those) and is marked analysis 3. A result of analysis 3 keeps its numbers and its analysis
  // (store.cc kReanalysedBelow). Idempotent: the daemon calls it at start-up.
  struct Reanalysis {
    int64_t reanalysed = 0;
    int64_t kept_old = 0;   // marked unreadable by this call
    int64_t unchanged = 0;  // marked as this analysis's with their numbers kept
  };
  Result<Reanalysis> ReanalyzeOldResults();

 private:
  explicit Store(std::unique_ptr<Database> db) : db_(std::move(db)) {}
  std::unique_ptr<Database> db_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_STORE_H_
