#include "server/store/database.h"

#include <spdlog/spdlog.h>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <thread>
#include <utility>

#include "core/api.h"
#include "server/store/schema_files.h"

namespace sandswim {

std::vector<Migration> Migrations() {
  std::vector<Migration> out;
  constexpr std::string_view kPrefix = "schema/";
  for (std::string_view name : SchemaFileNames()) {
    if (name.substr(0, kPrefix.size()) != kPrefix) continue;
    std::string_view base = name.substr(kPrefix.size());
    if (base.size() < 9 || base[3] != '_' || base.substr(base.size() - 4) != ".sql") continue;
    int version = 0;
    bool digits = true;
    for (char c : base.substr(0, 3)) {
      digits = digits && c >= '0' && c <= '9';
      version = version * 10 + (c - '0');
    }
    if (digits) out.push_back({version, std::string(name)});
  }
  return out;  // sorted by name, hence by version
}

namespace {

constexpr const char* kTables[] = {
    "campaigns",    "campaign_runs",      "submissions",  "sweeps",   "beds",
    "runs",         "run_decks",          "sweep_runs",   "leases",   "results",
    "trajectories", "run_logs",           "events",       "counters", "schema_migrations",
    "sweep_counts", "campaign_schedules", "drift_reports", "campaign_versions"};

Status SqlError(sqlite3* db, const std::string& what) {
  int code = sqlite3_extended_errcode(db);
  std::string msg = what.empty() ? std::string(sqlite3_errmsg(db)) : what + ": " + sqlite3_errmsg(db);
  if ((code & 0xff) == SQLITE_BUSY || (code & 0xff) == SQLITE_LOCKED) {
    return Status::Unavailable(msg);
  }
  if ((code & 0xff) == SQLITE_CONSTRAINT) return Status::Conflict(msg);
  // Faults of the disk, not of the request: the operator's to fix, and the request can be retried
  // once they are (503).
  if ((code & 0xff) == SQLITE_FULL) {
    return Status::Unavailable(msg + ": the disk that holds the database is full; free space on it, and writes "
                                     "resume by themselves (nothing was written)");
  }
  if ((code & 0xff) == SQLITE_READONLY) {
    return Status::Unavailable(msg + ": the database cannot be written; make its file, its directory and their "
                                     "filesystem writable again (nothing was written)");
  }
  if ((code & 0xff) == SQLITE_CORRUPT || (code & 0xff) == SQLITE_NOTADB) {
    return Status::Corruption(msg);
  }
  if ((code & 0xff) == SQLITE_IOERR || (code & 0xff) == SQLITE_CANTOPEN) {
    return Status::IOError(msg);
  }
  return Status::Internal(msg);
}

Status ExecRaw(sqlite3* db, const std::string& sql) {
  char* err = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
    sqlite3_free(err);  // the same text as sqlite3_errmsg()
    return SqlError(db, "");
  }
  return Status::Ok();
}

}  // namespace

struct Connection {
  sqlite3* db = nullptr;
  std::mutex mu;
  std::map<std::string, sqlite3_stmt*> cache;  // guarded by mu
  std::set<sqlite3_stmt*> in_use;              // cached statements held by a Statement
  std::atomic<uint64_t> commits{0};            // COMMITs that succeeded (Database::commits)

  ~Connection() {
    for (auto& [sql, stmt] : cache) sqlite3_finalize(stmt);
    if (db != nullptr) sqlite3_close_v2(db);
  }
  sqlite3_stmt* Cached(const std::string& sql, Status* error) {
    auto it = cache.find(sql);
    if (it != cache.end()) return it->second;
    sqlite3_stmt* stmt = nullptr;
    if (sqlite3_prepare_v2(db, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
      *error = SqlError(db, "prepare \"" + sql.substr(0, 60) + "\"");
      return nullptr;
    }
    cache.emplace(sql, stmt);
    return stmt;
  }
};

// Read-only connections of a file database: enough for a few long reads (results, backups of
// figures) to run at once while short reads still find one free.
constexpr int kReadConnections = 4;

// ---- Statement ----------------------------------------------------------------------------------

Statement::Statement(sqlite3_stmt* stmt, Connection* conn, bool owned) : stmt_(stmt), conn_(conn), owned_(owned) {}

Statement::Statement(Statement&& o) noexcept
    : stmt_(o.stmt_), conn_(o.conn_), owned_(o.owned_), bind_error_(std::move(o.bind_error_)) {
  o.stmt_ = nullptr;
}

Statement::~Statement() {
  if (stmt_ == nullptr) return;
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
  if (owned_) {
    sqlite3_finalize(stmt_);
  } else {
    conn_->in_use.erase(stmt_);
  }
}

#define SANDSWIM_BIND(call)                                                    \
  do {                                                                         \
    if (stmt_ != nullptr && (call) != SQLITE_OK && bind_error_.ok()) {         \
      bind_error_ = SqlError(conn_->db, "bind " + std::to_string(index)); \
    }                                                                          \
    return *this;                                                              \
  } while (0)

Statement& Statement::Bind(int index, int64_t v) { SANDSWIM_BIND(sqlite3_bind_int64(stmt_, index, v)); }
Statement& Statement::Bind(int index, double v) { SANDSWIM_BIND(sqlite3_bind_double(stmt_, index, v)); }
Statement& Statement::Bind(int index, std::string_view v) {
  SANDSWIM_BIND(sqlite3_bind_text64(stmt_, index, v.data(), v.size(), SQLITE_TRANSIENT, SQLITE_UTF8));
}
Statement& Statement::BindBlob(int index, std::string_view v) {
  SANDSWIM_BIND(sqlite3_bind_blob64(stmt_, index, v.data(), v.size(), SQLITE_TRANSIENT));
}
Statement& Statement::BindNull(int index) { SANDSWIM_BIND(sqlite3_bind_null(stmt_, index)); }
#undef SANDSWIM_BIND

Result<bool> Statement::Step() {
  if (stmt_ == nullptr) return bind_error_.ok() ? Status::Internal("statement not prepared") : bind_error_;
  if (!bind_error_.ok()) return bind_error_;
  int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  Status s = SqlError(conn_->db, "step");
  sqlite3_reset(stmt_);
  return s;
}

Status Statement::Run() {
  while (true) {
    Result<bool> r = Step();
    if (!r.ok()) return r.status();
    if (!*r) return Status::Ok();
  }
}

void Statement::Reset() {
  if (stmt_ != nullptr) sqlite3_reset(stmt_);
  if (stmt_ != nullptr) bind_error_ = Status::Ok();
}

bool Statement::IsNull(int col) const { return sqlite3_column_type(stmt_, col) == SQLITE_NULL; }
int64_t Statement::Int(int col) const { return sqlite3_column_int64(stmt_, col); }
double Statement::Double(int col) const { return sqlite3_column_double(stmt_, col); }
std::string Statement::Text(int col) const {
  const unsigned char* p = sqlite3_column_text(stmt_, col);
  if (p == nullptr) return "";
  return std::string(reinterpret_cast<const char*>(p), sqlite3_column_bytes(stmt_, col));
}
Result<JobState> Statement::State(int col) const {
  const std::string text = Text(col);
  if (std::optional<JobState> s = ParseJobState(text)) return *s;
  const char* name = sqlite3_column_name(stmt_, col);
  return Status::Corruption(std::string("column ") + (name != nullptr ? name : std::to_string(col)) + " holds '" +
                            text + "', which is not a job state (" + std::string(JobStateNames()) + ")");
}
std::optional<int64_t> Statement::OptInt(int col) const {
  if (IsNull(col)) return std::nullopt;
  return Int(col);
}
std::optional<double> Statement::OptDouble(int col) const {
  if (IsNull(col)) return std::nullopt;
  return Double(col);
}
std::optional<std::string> Statement::OptText(int col) const {
  if (IsNull(col)) return std::nullopt;
  return Text(col);
}

// ---- Statement profile (a diagnostic) -----------------------------------------------------------

namespace {

// SANDSWIM_SQL_PROFILE=FILE: every connection counts each statement's runs and their time
// (SQLite's own measure, SQLITE_TRACE_PROFILE), written to FILE as a table when the process ends
// normally, most time first. This is how the store's statements under bench_load were ranked
// (issue #49); off, it costs nothing.
class SqlProfile {
 public:
  static SqlProfile* Get() {
    static SqlProfile* profile = [] {
      const char* path = std::getenv("SANDSWIM_SQL_PROFILE");
      return path != nullptr && *path != '\0' ? new SqlProfile(path) : nullptr;
    }();
    return profile;
  }
  void Attach(sqlite3* db) { sqlite3_trace_v2(db, SQLITE_TRACE_PROFILE, &SqlProfile::OnProfile, this); }

 private:
  struct Tally {
    int64_t runs = 0, ns = 0;
  };
  explicit SqlProfile(std::string path) : path_(std::move(path)) {
    std::atexit([] { Get()->Write(); });
  }
  static int OnProfile(unsigned, void* self, void* stmt, void* ns) {
    const char* sql = sqlite3_sql(static_cast<sqlite3_stmt*>(stmt));
    auto* profile = static_cast<SqlProfile*>(self);
    std::lock_guard<std::mutex> lock(profile->mu_);
    Tally& t = profile->by_sql_[sql != nullptr ? sql : "?"];
    ++t.runs;
    t.ns += *static_cast<int64_t*>(ns);
    return 0;
  }
  void Write() {
    std::lock_guard<std::mutex> lock(mu_);
    std::vector<std::pair<std::string, Tally>> rows(by_sql_.begin(), by_sql_.end());
    std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.second.ns > b.second.ns; });
    FILE* f = std::fopen(path_.c_str(), "w");
    if (f == nullptr) return;
    std::fprintf(f, "total_ms\truns\tmean_us\tsql\n");
    for (const auto& [sql, t] : rows) {
      std::fprintf(f, "%.1f\t%lld\t%.1f\t%s\n", static_cast<double>(t.ns) / 1e6, static_cast<long long>(t.runs),
                   static_cast<double>(t.ns) / 1e3 / static_cast<double>(std::max<int64_t>(1, t.runs)), sql.c_str());
    }
    std::fclose(f);
  }

  const std::string path_;
  std::mutex mu_;
  std::map<std::string, Tally> by_sql_;  // guarded by mu_
};

}  // namespace

// ---- Transaction --------------------------------------------------------------------------------

Transaction::Transaction(Connection* conn, std::unique_lock<std::mutex> lock)
    : conn_(conn), lock_(std::move(lock)), open_(true) {}

Transaction::Transaction(Transaction&& o) noexcept : conn_(o.conn_), lock_(std::move(o.lock_)), open_(o.open_) {
  o.open_ = false;
}

Transaction::~Transaction() {
  if (!open_) return;
  // A destructor cannot return the failure; the log says it, and SQLite itself rolls back a
  // transaction whose ROLLBACK failed when the connection closes.
  if (Status s = ExecRaw(conn_->db, "ROLLBACK"); !s.ok())
    spdlog::error("database: rolling back an abandoned transaction failed: {}", s.ToString());
}

Statement Transaction::Prepare(const std::string& sql) {
  Status error;
  sqlite3_stmt* stmt = conn_->Cached(sql, &error);
  if (stmt != nullptr && conn_->in_use.insert(stmt).second) {
    return Statement(stmt, conn_, /*owned=*/false);
  }
  if (stmt != nullptr) {
    // Its cached twin is held by a live Statement (nested use of one SQL text): a private copy.
    stmt = nullptr;
    if (sqlite3_prepare_v2(conn_->db, sql.c_str(), -1, &stmt, nullptr) != SQLITE_OK) {
      error = SqlError(conn_->db, "prepare");
      sqlite3_finalize(stmt);
      stmt = nullptr;
    }
    if (stmt != nullptr) return Statement(stmt, conn_, /*owned=*/true);
  }
  Statement st(nullptr, conn_, /*owned=*/true);
  st.bind_error_ = error;
  return st;
}

Status Transaction::Exec(const std::string& sql) { return ExecRaw(conn_->db, sql); }
int64_t Transaction::LastInsertId() const { return sqlite3_last_insert_rowid(conn_->db); }
int64_t Transaction::Changes() const { return sqlite3_changes(conn_->db); }

Status Transaction::Event(double time, std::string_view kind, std::string_view subject, const nlohmann::json& detail) {
  Statement st = Prepare("INSERT INTO events (time, kind, subject, detail) VALUES (?, ?, ?, ?)");
  st.Bind(1, time).Bind(2, kind).Bind(3, subject).Bind(4, api::ToJsonText(detail));
  return st.Run();
}

Status Transaction::Count(std::string_view counter, int64_t delta) {
  Statement st = Prepare(
      "INSERT INTO counters (name, value) VALUES (?, ?) "
      "ON CONFLICT (name) DO UPDATE SET value = value + excluded.value");
  st.Bind(1, counter).Bind(2, delta);
  return st.Run();
}

Status Transaction::Commit() {
  if (!open_) return Status::Internal("transaction already finished");
  Status s = ExecRaw(conn_->db, "COMMIT");
  if (!s.ok()) return s;  // still open: the destructor rolls back
  open_ = false;
  conn_->commits.fetch_add(1, std::memory_order_release);
  return Status::Ok();
}

// ---- Database -----------------------------------------------------------------------------------

namespace {

// Why `path` (or, while it does not exist, its directory) cannot be written, said for an error
// that SQLite words as "unable to open database file"; "" when nothing is found.
std::string WhyNotWritable(const std::string& path) {
  std::error_code ec;
  std::string target = std::filesystem::exists(path, ec) ? path : std::filesystem::path(path).parent_path().string();
  if (target.empty()) target = ".";
  if (access(target.c_str(), W_OK) == 0) return "";
  const int err = errno;
  if (err == EROFS) {
    return " (" + target + " is on a read-only filesystem: check the filesystem and remount it read-write, or "
           "move the database)";
  }
  return " (" + target + " cannot be written: " + std::strerror(err) + ")";
}

}  // namespace

Status Database::OpenFile(const std::string& path) {
  path_ = path;
  if (path != ":memory:") {
    std::error_code ec;
    std::filesystem::path parent = std::filesystem::path(path).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent, ec);
    if (ec) return Status::IOError("cannot create " + parent.string() + ": " + ec.message());
  }
  // No global memory statistics: they take a process-wide mutex on every allocation (~6% of a
  // 100,000-run submission). Only possible before SQLite initialises; later calls are no-ops.
  static const bool kConfigured = [] {
    sqlite3_config(SQLITE_CONFIG_MEMSTATUS, 0);
    return true;
  }();
  (void)kConfigured;
  writer_ = std::make_unique<Connection>();
  int rc =
      sqlite3_open_v2(path.c_str(), &writer_->db, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) {
    std::string msg = writer_->db ? sqlite3_errmsg(writer_->db) : "out of memory";
    return Status::IOError("cannot open database " + path + ": " + msg + WhyNotWritable(path));
  }
  sqlite3_busy_timeout(writer_->db, 5000);
  if (SqlProfile* profile = SqlProfile::Get()) profile->Attach(writer_->db);
  // The first statement is where a database that cannot be written fails (its WAL cannot be made).
  if (Status s = ExecRaw(writer_->db,
                         "PRAGMA journal_mode = WAL; PRAGMA foreign_keys = ON; "
                         "PRAGMA synchronous = NORMAL; PRAGMA temp_store = MEMORY; PRAGMA cache_size = "
                         "-65536; PRAGMA wal_autocheckpoint = 10000;");
      !s.ok()) {
    return Status(s.code(), "cannot open database " + path + ": " + s.reason() + WhyNotWritable(path));
  }
  SANDSWIM_RETURN_IF_ERROR(Migrate());
  return OpenReaders(kReadConnections);
}

Result<std::unique_ptr<Database>> Database::Open(const std::string& path) {
  std::unique_ptr<Database> db(new Database());
  SANDSWIM_RETURN_IF_ERROR(db->OpenFile(path));
  return db;
}

Database::Database() = default;
Database::~Database() = default;

Status Database::OpenReaders(int n) {
  if (path_.empty() || path_ == ":memory:" || path_.rfind("file:", 0) == 0) return Status::Ok();
  for (int i = 0; i < n; ++i) {
    auto reader = std::make_unique<Connection>();
    if (sqlite3_open_v2(path_.c_str(), &reader->db, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr) != SQLITE_OK) {
      return Status::IOError("cannot open a read connection to " + path_ + ": " +
                             (reader->db ? sqlite3_errmsg(reader->db) : "out of memory"));
    }
    sqlite3_busy_timeout(reader->db, 5000);
    if (SqlProfile* profile = SqlProfile::Get()) profile->Attach(reader->db);
    // query_only: a write slipped into a read transaction fails here instead of waiting on the lock.
    SANDSWIM_RETURN_IF_ERROR(ExecRaw(reader->db, "PRAGMA query_only = 1; PRAGMA foreign_keys = ON; PRAGMA temp_store = MEMORY; "
                                                 "PRAGMA cache_size = -16384;"));
    readers_.push_back(std::move(reader));
  }
  return Status::Ok();
}

Status Database::Migrate() {
  std::unique_lock<std::mutex> lock(writer_->mu);
  SANDSWIM_RETURN_IF_ERROR(ExecRaw(writer_->db,
                                   "CREATE TABLE IF NOT EXISTS schema_migrations ("
                                   " version INTEGER PRIMARY KEY, name TEXT NOT NULL,"
                                   " applied_at REAL NOT NULL)"));
  auto user_version = [this]() -> int {
    sqlite3_stmt* st = nullptr;
    int v = 0;
    if (sqlite3_prepare_v2(writer_->db, "PRAGMA user_version", -1, &st, nullptr) == SQLITE_OK &&
        sqlite3_step(st) == SQLITE_ROW) {
      v = sqlite3_column_int(st, 0);
    }
    sqlite3_finalize(st);
    return v;
  };
  int current = user_version();
  const std::vector<Migration> migrations = Migrations();
  for (size_t i = 0; i < migrations.size(); ++i) {
    if (migrations[i].version != static_cast<int>(i) + 1) {
      return Status::Internal("migration " + migrations[i].file + " should be number " + std::to_string(i + 1) +
                              ": the schema/NNN_*.sql files must be numbered 001, 002, ... without gaps");
    }
  }
  if (migrations.empty()) return Status::Internal("no migration compiled in (schema/NNN_*.sql)");
  int latest = migrations.back().version;
  if (current > latest) {
    return Status::FailedPrecondition("schema", "database " + path_ + " has schema version " + std::to_string(current) +
                                                    "; this sandswimd knows up to " + std::to_string(latest));
  }
  for (const Migration& m : migrations) {
    if (m.version <= current) continue;
    std::optional<std::string_view> sql = SchemaFile(m.file);
    if (!sql) return Status::Internal("migration not compiled in: " + m.file);
    SANDSWIM_RETURN_IF_ERROR(ExecRaw(writer_->db, "BEGIN IMMEDIATE"));
    Status s = ExecRaw(writer_->db, std::string(*sql));
    if (s.ok()) {
      s = ExecRaw(writer_->db, "INSERT INTO schema_migrations (version, name, applied_at) VALUES (" +
                           std::to_string(m.version) + ", '" + m.file + "', CAST(strftime('%s','now') AS REAL))");
    }
    if (s.ok()) s = ExecRaw(writer_->db, "PRAGMA user_version = " + std::to_string(m.version));
    if (s.ok()) s = ExecRaw(writer_->db, "COMMIT");
    if (!s.ok()) {
      std::string reason = std::string("migration ") + m.file + ": " + s.reason();
      if (Status r = ExecRaw(writer_->db, "ROLLBACK"); !r.ok()) reason += " (and its rollback failed: " + r.reason() + ")";
      return Status(s.code(), reason);
    }
    current = m.version;
  }
  schema_version_ = current;
  return Status::Ok();
}

Result<Transaction> Database::Begin() {
  std::unique_lock<std::mutex> lock(writer_->mu);
  SANDSWIM_RETURN_IF_ERROR(ExecRaw(writer_->db, "BEGIN IMMEDIATE"));
  return Transaction(writer_.get(), std::move(lock));
}

uint64_t Database::commits() const { return writer_->commits.load(std::memory_order_acquire); }

Result<Transaction> Database::BeginRead() {
  Connection* conn = writer_.get();
  std::unique_lock<std::mutex> lock;
  if (readers_.empty()) {
    lock = std::unique_lock<std::mutex>(conn->mu);
  } else {
    // A free reader, starting from the next in turn; when all are taken, wait for that one.
    const size_t first = next_reader_.fetch_add(1) % readers_.size();
    for (size_t i = 0; i < readers_.size() && !lock.owns_lock(); ++i) {
      conn = readers_[(first + i) % readers_.size()].get();
      lock = std::unique_lock<std::mutex>(conn->mu, std::try_to_lock);
    }
    if (!lock.owns_lock()) {
      conn = readers_[first].get();
      lock = std::unique_lock<std::mutex>(conn->mu);
    }
  }
  SANDSWIM_RETURN_IF_ERROR(ExecRaw(conn->db, "BEGIN"));
  return Transaction(conn, std::move(lock));
}

// ---- Group commit -------------------------------------------------------------------------------

struct Database::PendingWrite {
  const std::function<Status(Transaction&)>* change;
  Status result;
  bool done = false;
};

// A group bounded so that no caller waits behind an unbounded number of others.
constexpr size_t kMaxGroup = 256;
// How long a leader waits for a group to fill (far less than one commit costs here).
constexpr std::chrono::microseconds kGather(200);

Status Database::Write(const std::function<Status(Transaction&)>& change) {
  PendingWrite mine{&change, Status::Ok(), false};
  std::unique_lock<std::mutex> g(group_mu_);
  pending_.push_back(&mine);
  if (gathering_ && pending_.size() >= last_group_) leader_cv_.notify_one();
  while (!mine.done) {
    if (leading_) {
      group_cv_.wait(g);
      continue;
    }
    // Lead: take what has queued up (while the previous group committed) and run it. Callers
    // answered by the previous group come back within microseconds; when that group was larger
    // than what is queued now, wait a moment (at most kGather) for them to join this one.
    leading_ = true;
    if (last_group_ > 1 && pending_.size() < last_group_) {
      gathering_ = true;
      leader_cv_.wait_for(g, kGather, [this] { return pending_.size() >= last_group_; });
      gathering_ = false;
    }
    std::vector<PendingWrite*> group;
    const size_t n = std::min(pending_.size(), kMaxGroup);
    group.assign(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
    pending_.erase(pending_.begin(), pending_.begin() + static_cast<std::ptrdiff_t>(n));
    last_group_ = n;
    g.unlock();
    try {
      RunGroup(group);
    } catch (...) {  // bad_alloc and the like: fail the group, never leave its callers waiting
      for (PendingWrite* w : group) {
        if (w->result.ok()) w->result = Status::Internal("the commit group failed (out of memory?)");
      }
    }
    g.lock();
    for (PendingWrite* w : group) w->done = true;
    leading_ = false;
    group_cv_.notify_all();
  }
  return mine.result;
}

void Database::RunGroup(const std::vector<PendingWrite*>& group) {
  size_t i = 0;
  while (i < group.size()) {
    Result<Transaction> t = Begin();
    if (!t.ok()) {
      for (; i < group.size(); ++i) group[i]->result = t.status();
      return;
    }
    std::vector<PendingWrite*> members;  // changes held by this transaction
    Status broken;                       // set when the transaction itself was lost
    for (; i < group.size() && broken.ok(); ++i) {
      PendingWrite* w = group[i];
      Status s = ExecRaw(writer_->db, "SAVEPOINT grouped_change");
      if (s.ok()) {
        try {
          s = (*w->change)(*t);
        } catch (const std::exception& e) {
          s = Status::Internal(std::string("exception in a store change: ") + e.what());
        } catch (...) {
          s = Status::Internal("exception in a store change");
        }
      }
      if (sqlite3_get_autocommit(writer_->db)) {
        // SQLite rolled the whole transaction back (I/O error, disk full, ...): the changes
        // already in it are gone too.
        broken = s.ok() ? Status::Internal("the transaction ended inside a change") : s;
        w->result = broken;
        break;
      }
      if (s.ok()) {
        s = ExecRaw(writer_->db, "RELEASE grouped_change");
      } else {
        Status undo = ExecRaw(writer_->db, "ROLLBACK TO grouped_change");
        if (undo.ok()) undo = ExecRaw(writer_->db, "RELEASE grouped_change");
        if (!undo.ok()) {
          // The failed change's writes could not be undone alone: drop the whole transaction
          // rather than commit them with the others.
          broken = Status::Internal("cannot roll back a failed change: " + undo.reason());
          w->result = s;
          break;
        }
      }
      w->result = s;
      if (s.ok()) members.push_back(w);
    }
    if (broken.ok()) {
      Status c = t->Commit();
      if (!c.ok()) {
        for (PendingWrite* w : members) w->result = c;
      }
    } else {
      ++i;  // past the change that broke it
      for (PendingWrite* w : members) {
        w->result = Status(broken.code(), "rolled back with its commit group: " + broken.reason());
      }
    }
    // `t` ends here: a transaction that did not commit rolls back, and the lock is released so
    // that reads get in between groups.
  }
}

Status Database::HealthCheck() {
  Result<Transaction> t = BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare("PRAGMA user_version");
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row || st.Int(0) != schema_version_) {
    return Status::Unavailable("database schema changed under the daemon");
  }
  return Status::Ok();
}

Result<int64_t> Database::CountRows(const std::string& table) {
  bool known = false;
  for (const char* t : kTables) known = known || table == t;
  if (!known) return Status::InvalidArgument("table", "unknown table '" + table + "'");
  Result<Transaction> t = BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare("SELECT COUNT(*) FROM " + table);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  return st.Int(0);
}

Result<int64_t> Database::BackupTo(const std::string& path) {
  const std::string partial = path + ".partial";
  std::error_code ec;
  std::filesystem::remove(partial, ec);
  sqlite3* dest = nullptr;
  auto fail = [&](const std::string& what) -> Status {
    std::string msg = dest ? sqlite3_errmsg(dest) : "out of memory";
    if (dest) sqlite3_close(dest);
    std::error_code ignored;
    std::filesystem::remove(partial, ignored);
    return Status::IOError("backup to " + path + ": " + what + ": " + msg +
                           " (check that the directory exists, is writable and has room)");
  };
  if (sqlite3_open_v2(partial.c_str(), &dest, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr) != SQLITE_OK) {
    return fail("cannot create " + partial);
  }
  sqlite3_backup* backup = nullptr;
  {
    std::lock_guard<std::mutex> lock(writer_->mu);
    backup = sqlite3_backup_init(dest, "main", writer_->db, "main");
  }
  if (backup == nullptr) return fail("cannot start the backup");
  // Another process holding the file's lock (BUSY) is waited for, but not for ever.
  const auto busy_limit = std::chrono::seconds(60);
  auto busy_since = std::chrono::steady_clock::time_point::max();
  int rc = SQLITE_OK;
  while (rc == SQLITE_OK || rc == SQLITE_BUSY || rc == SQLITE_LOCKED) {
    {
      std::lock_guard<std::mutex> lock(writer_->mu);
      rc = sqlite3_backup_step(backup, 256);
    }
    if (rc == SQLITE_BUSY || rc == SQLITE_LOCKED) {
      const auto now = std::chrono::steady_clock::now();
      if (busy_since == std::chrono::steady_clock::time_point::max()) busy_since = now;
      if (now - busy_since > busy_limit) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    } else {
      busy_since = std::chrono::steady_clock::time_point::max();
    }
  }
  {
    std::lock_guard<std::mutex> lock(writer_->mu);
    sqlite3_backup_finish(backup);
  }
  if (rc != SQLITE_DONE) {
    return fail(rc == SQLITE_BUSY || rc == SQLITE_LOCKED ? "the database stayed locked by another process for 60 s"
                                                         : "copying pages");
  }
  // The copy is a plain rollback-journal file, checked before it is named as a backup.
  if (!ExecRaw(dest, "PRAGMA journal_mode = DELETE").ok()) return fail("setting its journal mode");
  sqlite3_stmt* check = nullptr;
  std::string verdict;
  if (sqlite3_prepare_v2(dest, "PRAGMA quick_check", -1, &check, nullptr) == SQLITE_OK &&
      sqlite3_step(check) == SQLITE_ROW) {
    verdict = reinterpret_cast<const char*>(sqlite3_column_text(check, 0));
  }
  sqlite3_finalize(check);
  if (verdict != "ok") return fail("the copy failed its quick_check (" + verdict + ")");
  if (sqlite3_close(dest) != SQLITE_OK) return fail("closing the copy");
  dest = nullptr;
  std::filesystem::rename(partial, path, ec);
  if (ec) {
    std::filesystem::remove(partial, ec);
    return Status::IOError("backup to " + path + ": cannot rename the finished copy into place: " + ec.message());
  }
  const auto bytes = std::filesystem::file_size(path, ec);
  if (ec) return Status::IOError("backup to " + path + ": " + ec.message());
  return static_cast<int64_t>(bytes);
}

}  // namespace sandswim
