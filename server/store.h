// Store: the daemon's one SQLite file (sweeps, runs, beds, results, trajectories, events), and
// the read queries the REST API answers from. This is the only file that includes sqlite3.h.
//
// Open() creates the file and its parent directory if needed, turns on WAL, foreign keys,
// synchronous=NORMAL, temp_store=MEMORY (statement journals in memory: a file one cost 3 of every 4
// write calls of the lease queue) and a busy timeout, and applies the numbered migrations of schema/*.sql
// (compiled in) that the file has not seen yet, each in one transaction, recorded in
// `schema_migrations` and in PRAGMA user_version. A file with a newer schema than this binary
// knows is refused (Status kFailedPrecondition).
//
// Writes go through a Transaction (BEGIN IMMEDIATE): every state change of the daemon is one
// transaction, so a crash at any instant leaves a consistent file. A Transaction that is
// destroyed without Commit() rolls back. Submission (submission.h) and the lease queue
// (lease_queue.h) write their SQL through Transaction/Statement; the read queries below are
// methods of Store.
//
// Group commit: Write() runs a change in a write transaction that it shares with the changes other
// threads hand to Write() at the same time. One of the callers (the leader) runs the queued
// changes one after the other, each inside its own SAVEPOINT (a change that returns an error or
// throws is rolled back alone, as if it had never run), then commits them all at once; every
// caller returns only after that COMMIT, so its change is as durable as with its own transaction.
// If the COMMIT fails, every change of the group is rolled back and every caller gets the error.
// This is how the lease queue's hot path (lease, heartbeat, complete) writes: one commit (one WAL
// append of the pages the group dirtied) for many state changes.
//
// Thread safety: Store owns one connection guarded by one mutex. A Transaction holds that mutex
// for its whole life, and every read query takes it for its duration, so Store is safe to use
// from any number of threads (httplib's pool); work is serialised. Do not call Store's read
// methods or open a second Transaction on the same thread while a Transaction is alive
// (self-deadlock). Statements are only valid inside the Transaction that prepared them.
#ifndef SANDSWIM_SERVER_STORE_H_
#define SANDSWIM_SERVER_STORE_H_

#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"
#include "core/point.h"
#include "core/status.h"

struct sqlite3;
struct sqlite3_stmt;

namespace sandswim {

class Store;

// A prepared statement of the connection (cached by SQL text; reset when this handle dies).
// Bind indexes are 1-based as in SQLite; column indexes are 0-based.
class Statement {
 public:
  Statement(Statement&& other) noexcept;
  Statement& operator=(Statement&&) = delete;
  Statement(const Statement&) = delete;
  ~Statement();

  Statement& Bind(int index, int64_t v);
  Statement& Bind(int index, int v) { return Bind(index, static_cast<int64_t>(v)); }
  Statement& Bind(int index, bool v) { return Bind(index, static_cast<int64_t>(v ? 1 : 0)); }
  Statement& Bind(int index, double v);
  Statement& Bind(int index, std::string_view v);
  Statement& Bind(int index, const std::string& v) { return Bind(index, std::string_view(v)); }
  Statement& Bind(int index, const char* v) { return Bind(index, std::string_view(v)); }
  Statement& BindBlob(int index, std::string_view bytes);
  Statement& BindNull(int index);
  template <typename T>
  Statement& Bind(int index, const std::optional<T>& v) {
    return v ? Bind(index, *v) : BindNull(index);
  }

  // Advances: true when a row is available, false when the statement is done.
  Result<bool> Step();
  // Steps until done (for INSERT/UPDATE/DELETE).
  Status Run();
  // Makes the statement ready to bind and step again (one statement reused across many rows of
  // a transaction). Bindings not rebound keep their values.
  void Reset();

  bool IsNull(int col) const;
  int64_t Int(int col) const;
  double Double(int col) const;
  std::string Text(int col) const;  // "" for NULL
  std::optional<int64_t> OptInt(int col) const;
  std::optional<double> OptDouble(int col) const;
  std::optional<std::string> OptText(int col) const;

 private:
  friend class Transaction;
  Statement(sqlite3_stmt* stmt, Store* store, bool owned);
  sqlite3_stmt* stmt_;
  Store* store_;
  bool owned_;         // finalized on destruction (else: returned to the store's cache)
  Status bind_error_;  // the first failed Bind(), reported by Step()
};

// A transaction holding the store's lock. Write transactions are BEGIN IMMEDIATE; read
// transactions are deferred BEGIN (a consistent snapshot for multi-query reads).
class Transaction {
 public:
  Transaction(Transaction&& other) noexcept;
  Transaction& operator=(Transaction&&) = delete;
  Transaction(const Transaction&) = delete;
  ~Transaction();  // rolls back unless committed

  Statement Prepare(const std::string& sql);  // a bad SQL text surfaces at Step()/Run()
  Status Exec(const std::string& sql);        // one or more statements without parameters
  int64_t LastInsertId() const;
  int64_t Changes() const;  // rows changed by the last statement

  // Appends an audit event (events table): kind like "run.leased", subject like "run/12".
  Status Event(double time, std::string_view kind, std::string_view subject,
               const nlohmann::json& detail = nlohmann::json::object());
  // Adds `delta` to a persistent counter (counters table), for Metrics.
  Status Count(std::string_view counter, int64_t delta = 1);

  Status Commit();

 private:
  friend class Store;
  Transaction(Store* store, std::unique_lock<std::mutex> lock);
  Store* store_;
  std::unique_lock<std::mutex> lock_;
  bool open_ = false;
};

// ---- Read models (values; JSON shapes are those of the REST API) -------------------------------

// A database migration compiled in: schema/NNN_name.sql applies version NNN. Migrations() lists
// every one, by version; Store::Open requires them numbered 1, 2, ... without gaps.
struct Migration {
  int version = 0;
  std::string file;  // "schema/007_uz_blocks.sql"
};
std::vector<Migration> Migrations();

struct RunCounts {
  int64_t queued = 0, running = 0, done = 0, failed = 0, cancelled = 0;
  int64_t total() const { return queued + running + done + failed + cancelled; }
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
  std::vector<SweepInfo> sweeps;          // ascending id
  std::optional<int64_t> next_cursor;     // pass as after_id for the next page
};
void to_json(nlohmann::json& j, const SweepPage& p);  // {"sweeps":[...], "next_cursor": id|null}

struct Progress {
  double sim_time_s = 0;
  double so_z = 0;
  int64_t step = 0;
  std::optional<double> heartbeat_at;
};
void to_json(nlohmann::json& j, const Progress& p);

// A run's result row: the measured figures plus how it was executed.
struct StoredResult {
  api::RunResult result;
  api::Execution execution;
  std::string key;       // the run key the result was computed under
  double created_at = 0;
};
// The RunResult fields flat, plus "engine_version","host","ranks","launcher","wall_s","cpu_s",
// "lease_to_start_s" (0 for results stored before migration 4), "key","created_at".
void to_json(nlohmann::json& j, const StoredResult& r);

struct RunSummary {
  int64_t id = 0;
  std::string key;
  std::string state;  // queued | running | done | failed | cancelled
  Point point;
  double run_duration_s = 0;
  int64_t steps = 0;
  int64_t bed_id = 0;
  int attempts = 0;
  std::string worker;  // "" unless leased at least once
  Progress progress;
  double created_at = 0;
  std::optional<double> started_at, finished_at;
  std::optional<double> uz;               // from the result row, when there is one
  std::string uz_text;                    // DescribeUz of that result ("" without one)
  std::optional<api::Failure> last_error;
};
// {"id","key","state","point":{PointToJson},"run_duration_s","steps","bed_id","attempts",
//  "worker","progress":{...},"created_at","started_at"?,"finished_at"?,"uz"?,"uz_text"?,
//  "last_error"?}
void to_json(nlohmann::json& j, const RunSummary& r);

struct RunFilter {
  std::optional<int64_t> sweep_id;
  std::optional<std::string> state;  // REQUIRES: one of the five states (else InvalidArgument)
  int64_t after_id = 0;              // cursor: runs with id > after_id
  int limit = 100;                   // clamped to [1, 1000]
};

struct RunPage {
  std::vector<RunSummary> runs;       // ascending id
  std::optional<int64_t> next_cursor; // set when more rows may follow
};
void to_json(nlohmann::json& j, const RunPage& p);  // {"runs":[...], "next_cursor": id|null}

struct RunDetail {
  RunSummary summary;
  std::string deck;
  std::string bed_key;
  std::string bed_state;
  std::vector<int64_t> sweep_ids;
  std::optional<StoredResult> result;
  std::optional<api::Trajectory> trajectory;
  std::string log_tail;
};
// The summary's fields plus "deck","bed_key","bed_state","sweeps":[ids],"result"?,
// "trajectory"?,"log_tail".
void to_json(nlohmann::json& j, const RunDetail& r);

// One row of a sweep's results: its point and, when done, U_z and the other figures.
struct ResultRow {
  int64_t run_id = 0;
  std::string key;
  std::string state;
  Point point;
  double run_duration_s = 0;
  std::optional<StoredResult> result;
};
// The API's JSON of a result row is core/result_table.h's (server/routes.cc ResultRowJson).

struct CampaignRunInfo {
  int64_t id = 0;
  std::string campaign;
  std::string scale;
  std::string trigger;  // "manual" | "schedule"
  std::optional<double> due_time;
  double created_at = 0;
  std::vector<int64_t> sweep_ids;
  RunCounts counts;  // of the distinct runs of its sweeps
};
void to_json(nlohmann::json& j, const CampaignRunInfo& c);

struct StoredCampaign {
  std::string name;
  nlohmann::json definition;  // as accepted by ParseCampaign()
  std::optional<std::string> schedule;
  double drift_tolerance_mps = 0;
  double updated_at = 0;
};
void to_json(nlohmann::json& j, const StoredCampaign& c);

struct Metrics {
  RunCounts runs;   // by state
  RunCounts beds;   // by state (cancelled is always 0)
  int64_t sweeps = 0;
  int64_t leases_granted = 0;
  int64_t completions = 0;   // accepted completions (not duplicates)
  int64_t expirations = 0;   // leases that ran out
  int64_t pilots_gone = 0;   // leases reclaimed early: their Slurm job was gone (server/pilot_watch.h)
  int64_t duplicates = 0;    // repeated completions answered "duplicate"
};
void to_json(nlohmann::json& j, const Metrics& m);

class Store {
 public:
  // Opens (creating if needed) the SQLite file at `path` and migrates it.
  static Result<std::unique_ptr<Store>> Open(const std::string& path);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  const std::string& path() const { return path_; }
  int schema_version() const { return schema_version_; }

  // Blocks until the lock is free. Write: BEGIN IMMEDIATE.
  Result<Transaction> Begin();
  Result<Transaction> BeginRead();

  // Runs `change` inside a grouped write transaction (see the top of this file) and returns its
  // status once the group has committed (or the commit's error). `change` must not commit, must
  // not call the Store, and may run on another thread than the caller's (it is called before
  // Write returns, so it may capture the caller's locals by reference).
  Status Write(const std::function<Status(Transaction&)>& change);

  // Write() for a change that returns a value: the value once committed, else the error.
  template <typename T>
  Result<T> WriteResult(const std::function<Result<T>(Transaction&)>& change) {
    std::optional<Result<T>> out;
    Status s = Write([&](Transaction& t) {
      out.emplace(change(t));
      return out->status();
    });
    if (!s.ok()) return s;
    return std::move(*out);
  }

  // ---- Reads for the REST API. NotFound when the id does not exist. ----
  Result<SweepPage> ListSweeps(int64_t after_id = 0, int limit = 100);
  Result<SweepInfo> GetSweep(int64_t id);
  Result<RunPage> ListRuns(const RunFilter& filter);
  Result<RunDetail> GetRun(int64_t id);
  // Every run of the sweep in its expansion order (sweep_runs.position).
  Result<std::vector<ResultRow>> SweepResults(int64_t sweep_id);
  Result<CampaignRunInfo> GetCampaignRun(int64_t id);
  // Newest first; `campaign` empty for all campaigns.
  Result<std::vector<CampaignRunInfo>> ListCampaignRuns(const std::string& campaign, int limit = 20);
  Result<std::optional<StoredCampaign>> GetCampaign(const std::string& name);
  // Inserts or replaces a campaign definition (the scheduler reads schedules from here).
  Status PutCampaign(const StoredCampaign& c);
  Result<std::vector<StoredCampaign>> ListCampaigns();
  Result<Metrics> GetMetrics();
  // OK when the file answers a trivial query and the schema is current.
  Status HealthCheck();

  // Re-analyses every result made by an older analysis than api::kAnalysisVersion from its stored
  // trajectory (the run's drive frequency, its bed's surface and its scale's floor, the stop the
  // engine reported), in pages of rows written one transaction each; such a result says
  // analysed_from "trajectory". A result with no trajectory that can be re-analysed keeps its old
  // numbers, stays inconclusive with the reason and is marked "unreadable", never tried again.
  // Idempotent: the daemon calls it at start-up.
  struct Reanalysis {
    int64_t reanalysed = 0;
    int64_t kept_old = 0;  // marked unreadable by this call
  };
  Result<Reanalysis> ReanalyzeOldResults();
  // Rows in a table (tests and diagnostics). REQUIRES: `table` is one of the schema's tables.
  Result<int64_t> CountRows(const std::string& table);

 private:
  friend class Transaction;
  friend class Statement;
  Store() = default;
  Status Migrate();
  sqlite3_stmt* Cached(const std::string& sql, Status* error);
  struct PendingWrite;
  void RunGroup(const std::vector<PendingWrite*>& group);

  std::string path_;
  sqlite3* db_ = nullptr;
  int schema_version_ = 0;
  std::mutex mu_;
  std::map<std::string, sqlite3_stmt*> cache_;  // guarded by mu_
  std::set<sqlite3_stmt*> in_use_;              // cached statements held by a Statement

  // Group commit (Write): changes waiting for a leader, and whether one is running a group.
  std::mutex group_mu_;
  std::condition_variable group_cv_;
  std::vector<PendingWrite*> pending_;  // guarded by group_mu_
  bool leading_ = false;                // guarded by group_mu_
  bool gathering_ = false;              // the leader waits for a group to fill; guarded by group_mu_
  size_t last_group_ = 1;               // size of the previous group; guarded by group_mu_
  std::condition_variable leader_cv_;   // wakes a gathering leader
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_H_
