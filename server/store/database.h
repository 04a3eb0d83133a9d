// Database: the daemon's one SQLite file (sweeps, runs, beds, results, trajectories, events) as
// an adapter: statements, transactions, group commit and migrations. Its .cc is the only file that
// includes sqlite3.h. What the rows mean lives beside it in the store room (server/store/), the
// only place with SQL text: the read views of the REST API in store.h (a Store holds the Database
// and reads through it) and the tables the job flow writes through, each function inside its
// caller's Transaction (job_table.h, submission_table.h, schedule_table.h, drift_table.h,
// campaigns.h, cost_model.h).
//
// Opening it (Database::Open, through Store::Open) creates the file and its parent directory if needed, turns on WAL, foreign keys,
// synchronous=NORMAL, temp_store=MEMORY (statement journals in memory: a file one cost 3 of every 4
// write calls of the lease queue) and a busy timeout, and applies the numbered migrations of schema/*.sql
// (compiled in) that the file has not seen yet, each in one transaction, recorded in
// `schema_migrations` and in PRAGMA user_version. A file with a newer schema than this binary
// knows is refused (Status kFailedPrecondition).
//
// Writes go through a Transaction (BEGIN IMMEDIATE): every state change of the daemon is one
// transaction, so a crash at any instant leaves a consistent file. A Transaction that is
// destroyed without Commit() rolls back. The modules that decide a change (submission, the lease
// queue, the scheduler, drift reports: server/jobs/, server/analysis/) open the Transaction and
// call the store room's tables inside it, so their decision and its rows commit together.
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
// Reads off the writer's path: beside the connection that writes, a file database has a small pool
// of read-only connections (kReadConnections); BeginRead() takes a free one. In WAL mode a reader
// sees the last commit before its transaction began and never waits for a writer, nor a writer for
// it: a 100,000-run results read does not hold up heartbeats and completions.
//
// Thread safety: each connection is guarded by its own mutex. A Transaction holds its
// connection's mutex for its whole life, so a Database is safe to use from any number of threads
// (httplib's pool); writes are serialised, reads run beside them and each other (up to the pool's
// size). Do not open a write Transaction on a thread that holds one already (self-deadlock).
// Statements are only valid inside the Transaction that prepared them.
#ifndef SANDSWIM_SERVER_STORE_DATABASE_H_
#define SANDSWIM_SERVER_STORE_DATABASE_H_

#include <atomic>
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

#include "core/job_state.h"
#include "core/status.h"

struct sqlite3;
struct sqlite3_stmt;

namespace sandswim {

// One SQLite connection: its handle, the lock that serialises its use and its statement cache
// (defined in database.cc).
struct Connection;

class Database;

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
  // A state column's job state (core/job_state.h); Corruption naming the column and its text when
  // the text is no job state (never a default).
  Result<JobState> State(int col) const;

 private:
  friend class Transaction;
  Statement(sqlite3_stmt* stmt, Connection* conn, bool owned);
  sqlite3_stmt* stmt_;
  Connection* conn_;
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
  friend class Database;
  Transaction(Connection* conn, std::unique_lock<std::mutex> lock);
  Connection* conn_;
  std::unique_lock<std::mutex> lock_;
  bool open_ = false;
};

// A database migration compiled in: schema/NNN_name.sql applies version NNN. Migrations() lists
// every one, by version; opening a Database requires them numbered 1, 2, ... without gaps.
struct Migration {
  int version = 0;
  std::string file;  // "schema/007_uz_blocks.sql"
};
std::vector<Migration> Migrations();

class Database {
 public:
  // Opens (creating if needed) the SQLite file at `path` (":memory:" for an in-memory one) and
  // migrates it (see the top of this file).
  static Result<std::unique_ptr<Database>> Open(const std::string& path);
  ~Database();
  Database(const Database&) = delete;
  Database& operator=(const Database&) = delete;

  const std::string& path() const { return path_; }
  int schema_version() const { return schema_version_; }

  // Blocks until the lock is free. Write: BEGIN IMMEDIATE.
  Result<Transaction> Begin();
  // A read transaction on one of the read-only connections (see the top of this file), waiting
  // only for other readers when all of them are taken; on the writer's connection for an
  // in-memory database. REQUIRES: nothing is written in it.
  Result<Transaction> BeginRead();
  // Write transactions committed on the writer's connection since Open (grouped or not; a read of
  // an in-memory database, which runs there, counts too). A cache of what was read keeps its
  // answer while this is unchanged: no change can have reached the file since (eta_cache.h).
  uint64_t commits() const;
  // Read-only connections opened beside the writer's (0 for an in-memory database).
  int read_connections() const { return static_cast<int>(readers_.size()); }

  // Runs `change` inside a grouped write transaction (see the top of this file) and returns its
  // status once the group has committed (or the commit's error). `change` must not commit, must
  // not call the Database, and may run on another thread than the caller's (it is called before
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

  // OK when the file answers a trivial query and the schema is current.
  Status HealthCheck();
  // Rows in a table (tests and diagnostics). REQUIRES: `table` is one of the schema's tables.
  Result<int64_t> CountRows(const std::string& table);

  // A consistent copy of the whole database at `path` (replaced if there), made while the daemon
  // serves: SQLite's online backup, a few hundred pages at a time with the lock released between
  // steps, so writers wait for one step, never for the whole copy (writes made meanwhile through
  // this connection reach the copy too). The copy passes PRAGMA quick_check before it is renamed
  // into place; a failed backup leaves `path` as it was. Returns its size in bytes.
  Result<int64_t> BackupTo(const std::string& path);

 private:
  friend class Transaction;
  Database();
  Status OpenFile(const std::string& path);
  friend class Statement;
  Status Migrate();
  Status OpenReaders(int n);
  struct PendingWrite;
  void RunGroup(const std::vector<PendingWrite*>& group);

  std::string path_;
  int schema_version_ = 0;
  std::unique_ptr<Connection> writer_;                // every write, and reads of an in-memory database
  std::vector<std::unique_ptr<Connection>> readers_;  // read-only (WAL): reads never wait for a writer
  std::atomic<size_t> next_reader_{0};

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

#endif  // SANDSWIM_SERVER_STORE_DATABASE_H_
