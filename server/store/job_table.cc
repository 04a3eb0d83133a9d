#include "server/store/job_table.h"

#include <utility>

#include <nlohmann/json.hpp>

#include "server/store/result_columns.h"

namespace sandswim::jobs {
namespace {

const char* Table(api::JobKind kind) { return kind == api::JobKind::kBed ? "beds" : "runs"; }

api::JobKind KindOf(const std::string& noun) { return noun == "bed" ? api::JobKind::kBed : api::JobKind::kRun; }

// Steps a statement through its rows, calling `row` on each.
template <typename Fn>
Status EachRow(Statement& st, Fn row) {
  while (true) {
    Result<bool> more = st.Step();
    if (!more.ok()) return more.status();
    if (!*more) return Status::Ok();
    row(st);
  }
}

Result<std::vector<LostLease>> LostLeases(Statement& st, int default_max) {
  std::vector<LostLease> out;
  SANDSWIM_RETURN_IF_ERROR(EachRow(st, [&](const Statement& s) {
    LostLease e;
    e.id = s.Int(0);
    e.job.state = JobState::kRunning;
    e.job.lease_token = s.Text(1);
    e.job.attempts = static_cast<int>(s.Int(2));
    e.job.max_attempts = static_cast<int>(s.OptInt(3).value_or(default_max));
    e.worker = s.Text(4);
    out.push_back(std::move(e));
  }));
  return out;
}

constexpr const char* kLostColumns = "SELECT j.id, j.lease_token, j.attempts, j.max_attempts, j.worker FROM ";

}  // namespace

const char* Noun(api::JobKind kind) { return kind == api::JobKind::kBed ? "bed" : "run"; }

std::string Subject(api::JobKind kind, int64_t id) { return std::string(Noun(kind)) + "/" + std::to_string(id); }

// ---- Leases -------------------------------------------------------------------------------------

Result<LeaseRow> FindLease(Transaction& t, const std::string& token) {
  Statement st = t.Prepare("SELECT kind, job_id, completed_at, outcome FROM leases WHERE token = ?");
  st.Bind(1, token);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Conflict("unknown lease token");
  LeaseRow l;
  l.kind = KindOf(st.Text(0));
  l.job_id = st.Int(1);
  l.completed = !st.IsNull(2);
  l.outcome = st.Text(3);
  return l;
}

Status InsertLease(Transaction& t, const std::string& token, api::JobKind kind, int64_t job_id, int attempt,
                   const api::LeaseRequest& request, double now) {
  Statement st = t.Prepare(
      "INSERT INTO leases (token, kind, job_id, attempt, worker, host, ranks, granted_at, slurm_job) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)");
  st.Bind(1, token).Bind(2, Noun(kind)).Bind(3, job_id).Bind(4, attempt);
  st.Bind(5, request.worker).Bind(6, request.host).Bind(7, request.ranks).Bind(8, now);
  if (request.slurm_job.empty()) {
    st.BindNull(9);
  } else {
    st.Bind(9, request.slurm_job);
  }
  return st.Run();
}

namespace {

// The simulated time a lease's attempt reached, as the run's row holds it while that lease is its
// current one (a heartbeat's, or the result's once done); stamped once (the first stamp stands).
constexpr const char* kStampReach =
    "sim_time_s = COALESCE(sim_time_s, (SELECT r.sim_time_s FROM runs r WHERE leases.kind = 'run' "
    "AND r.id = leases.job_id AND r.lease_token = leases.token))";

// Before a run's progress is cleared (queued again, handed back): its current lease keeps what its
// attempt reached, for the ledger (server/store/rounds.h UnchargedAttempts).
Status StampRunReach(Transaction& t, int64_t run_id) {
  Statement st = t.Prepare(std::string("UPDATE leases SET ") + kStampReach +
                           " WHERE token = (SELECT lease_token FROM runs WHERE id = ?)");
  st.Bind(1, run_id);
  return st.Run();
}

}  // namespace

Status CloseLease(Transaction& t, const std::string& token, double now, const std::string& outcome) {
  Statement st = t.Prepare(std::string("UPDATE leases SET completed_at = ?1, closed_at = ?1, outcome = ?2, ") +
                           kStampReach + " WHERE token = ?3");
  st.Bind(1, now).Bind(2, outcome).Bind(3, token);
  return st.Run();
}

Status MarkLeaseExpired(Transaction& t, const std::string& token, double now) {
  Statement st = t.Prepare(std::string("UPDATE leases SET outcome = 'expired', closed_at = ?1, ") + kStampReach +
                           " WHERE token = ?2");
  st.Bind(1, now).Bind(2, token);
  return st.Run();
}

Status SetNextToken(Transaction& t, const std::string& token, const std::string& next_token) {
  Statement st = t.Prepare("UPDATE leases SET next_token = ? WHERE token = ?");
  st.Bind(1, next_token).Bind(2, token);
  return st.Run();
}

Result<std::optional<GrantRef>> OpenNextGrant(Transaction& t, const std::string& token) {
  Statement find = t.Prepare(
      "SELECT n.token, n.kind, n.job_id FROM leases l JOIN leases n ON n.token = l.next_token "
      "WHERE l.token = ? AND n.completed_at IS NULL AND n.outcome IS NULL");
  find.Bind(1, token);
  Result<bool> row = find.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<GrantRef>();
  return std::optional<GrantRef>(GrantRef{find.Text(0), KindOf(find.Text(1)), find.Int(2)});
}

Result<bool> TakeBackGrant(Transaction& t, const GrantRef& grant, bool wanted, double now) {
  const bool run = grant.kind == api::JobKind::kRun;
  std::string sql = std::string("UPDATE ") + Table(grant.kind) +
                    " SET attempts = attempts - 1, lease_token = NULL, lease_expires_at = NULL";
  if (wanted || !run) {
    sql += ", state = 'queued'";
    if (run) sql += ", queued_at = ?3, sim_time_s = NULL, step = NULL, so_z = NULL, heartbeat_at = NULL";
  } else {
    sql += ", state = 'cancelled', finished_at = ?3, last_error_kind = 'cancelled', "
           "last_error = 'its sweeps were cancelled before its worker received it'";
  }
  sql += " WHERE id = ?1 AND state = 'running' AND lease_token = ?2";
  Statement st = t.Prepare(sql);
  st.Bind(1, grant.job_id).Bind(2, grant.token);
  if (run) st.Bind(3, now);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  if (t.Changes() == 0) return false;
  SANDSWIM_RETURN_IF_ERROR(CloseLease(t, grant.token, now, "unreceived"));
  return true;
}

Result<std::vector<std::string>> SlurmJobsWithOpenLeases(Transaction& t) {
  // Open leases (the partial index leases_open_by_slurm_job), their jobs found by primary key.
  Statement st = t.Prepare(
      "SELECT DISTINCT l.slurm_job FROM leases l WHERE l.slurm_job IS NOT NULL AND l.completed_at IS NULL "
      "AND l.outcome IS NULL AND ((l.kind = 'run' AND EXISTS (SELECT 1 FROM runs r WHERE r.id = l.job_id AND "
      "r.lease_token = l.token AND r.state = 'running')) OR (l.kind = 'bed' AND EXISTS (SELECT 1 FROM beds b "
      "WHERE b.id = l.job_id AND b.lease_token = l.token AND b.state = 'running'))) ORDER BY l.slurm_job");
  std::vector<std::string> jobs;
  SANDSWIM_RETURN_IF_ERROR(EachRow(st, [&](const Statement& s) { jobs.push_back(s.Text(0)); }));
  return jobs;
}

Result<int64_t> ExtendRunningLeases(Transaction& t, double until) {
  int64_t extended = 0;
  for (api::JobKind kind : {api::JobKind::kRun, api::JobKind::kBed}) {
    Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) +
                             " SET lease_expires_at = ? WHERE state = 'running' AND lease_expires_at < ?");
    st.Bind(1, until).Bind(2, until);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    extended += t.Changes();
  }
  return extended;
}

// ---- Jobs ---------------------------------------------------------------------------------------

Result<JobRow> LoadJob(Transaction& t, api::JobKind kind, int64_t id, int default_max) {
  Statement st =
      t.Prepare(std::string("SELECT state, lease_token, attempts, max_attempts FROM ") + Table(kind) + " WHERE id = ?");
  st.Bind(1, id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Conflict(std::string(Noun(kind)) + " of this lease no longer exists");
  JobRow j;
  Result<JobState> state = st.State(0);
  if (!state.ok()) return state.status();
  j.state = *state;
  j.lease_token = st.Text(1);
  j.attempts = static_cast<int>(st.Int(2));
  j.max_attempts = static_cast<int>(st.OptInt(3).value_or(default_max));
  return j;
}

Result<std::vector<LostLease>> ExpiredLeases(Transaction& t, api::JobKind kind, double now, int default_max) {
  // lease_expires_at is the last heartbeat (or the grant) plus the TTL.
  Statement st = t.Prepare(std::string(kLostColumns) + Table(kind) +
                           " j WHERE j.state = 'running' AND j.lease_expires_at < ?1 ORDER BY j.id");
  st.Bind(1, now);
  return LostLeases(st, default_max);
}

Result<std::vector<LostLease>> RunningLeases(Transaction& t, api::JobKind kind, int default_max) {
  Statement st = t.Prepare(std::string(kLostColumns) + Table(kind) + " j WHERE j.state = 'running' ORDER BY j.id");
  return LostLeases(st, default_max);
}

Result<std::vector<LostLease>> SlurmJobLeases(Transaction& t, api::JobKind kind, const std::string& slurm_job,
                                              double expiring_by, double asked_at, int default_max) {
  Statement st = t.Prepare(std::string(kLostColumns) + Table(kind) +
                           " j WHERE j.state = 'running' AND j.lease_expires_at <= ?1 AND j.lease_token IN "
                           "(SELECT token FROM leases WHERE slurm_job = ?2 AND completed_at IS NULL AND "
                           "outcome IS NULL AND granted_at <= ?3) ORDER BY j.id");
  st.Bind(1, expiring_by).Bind(2, slurm_job).Bind(3, asked_at);
  return LostLeases(st, default_max);
}

Status MarkLeased(Transaction& t, api::JobKind kind, int64_t id, const std::string& token, double expires_at,
                  const std::string& worker, double now) {
  Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) +
                           " SET state = 'running', attempts = attempts + 1, lease_token = ?, "
                           "lease_expires_at = ?, worker = ?, started_at = ? WHERE id = ?");
  st.Bind(1, token).Bind(2, expires_at).Bind(3, worker).Bind(4, now);
  st.Bind(5, id);
  return st.Run();
}

Status MarkRetriedOrFailed(Transaction& t, api::JobKind kind, int64_t id, JobState state,
                           const std::string& error_kind, const std::string& message, double now) {
  std::string sql = std::string("UPDATE ") + Table(kind) +
                    " SET state = ?, lease_expires_at = NULL, last_error_kind = ?, "
                    "last_error = ?, finished_at = CASE WHEN ? = 'failed' THEN ? ELSE NULL END";
  // A run queued again starts again: the last attempt's progress is not this attempt's (it made a
  // queued run look 91 % done, and its ETA minutes where hours were left).
  if (kind == api::JobKind::kRun) {
    sql += ", queued_at = ?6";
    if (state == JobState::kQueued) sql += ", sim_time_s = NULL, step = NULL, so_z = NULL, heartbeat_at = NULL";
  }
  sql += " WHERE id = ?7";
  if (kind == api::JobKind::kRun) SANDSWIM_RETURN_IF_ERROR(StampRunReach(t, id));
  Statement st = t.Prepare(sql);
  st.Bind(1, JobStateName(state)).Bind(2, error_kind).Bind(3, message).Bind(4, JobStateName(state)).Bind(5, now);
  if (kind == api::JobKind::kRun) st.Bind(6, now);
  st.Bind(7, id);
  return st.Run();
}

Status MarkCancelledOrQueued(Transaction& t, api::JobKind kind, int64_t id, JobState state,
                             const std::string& error_kind, const std::string& message, double now) {
  Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) +
                           " SET state = ?, lease_expires_at = NULL, last_error_kind = ?, "
                           "last_error = ?, finished_at = ? WHERE id = ?");
  st.Bind(1, JobStateName(state)).Bind(2, error_kind).Bind(3, message);
  if (state == JobState::kCancelled) {
    st.Bind(4, now);
  } else {
    st.BindNull(4);
  }
  st.Bind(5, id);
  return st.Run();
}

Result<int64_t> CountRelease(Transaction& t, api::JobKind kind, int64_t id) {
  int64_t before = 0;
  {
    Statement st = t.Prepare(std::string("SELECT releases FROM ") + Table(kind) + " WHERE id = ?");
    st.Bind(1, id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (*row) before = st.Int(0);
  }
  Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) + " SET releases = releases + 1 WHERE id = ?");
  st.Bind(1, id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  return before;
}

Status MarkReleased(Transaction& t, api::JobKind kind, int64_t id, bool wanted, double now) {
  std::string sql = std::string("UPDATE ") + Table(kind) +
                    (wanted ? " SET state = 'queued', attempts = MAX(attempts - 1, 0), lease_expires_at = NULL"
                            : " SET state = 'cancelled', attempts = MAX(attempts - 1, 0), lease_expires_at = NULL, "
                              "finished_at = ?1, last_error_kind = 'cancelled', "
                              "last_error = 'its sweeps were cancelled while it ran'");
  if (kind == api::JobKind::kRun && wanted) sql += ", queued_at = ?1, sim_time_s = NULL, step = NULL, so_z = NULL, heartbeat_at = NULL";
  sql += " WHERE id = ?2";
  if (kind == api::JobKind::kRun) SANDSWIM_RETURN_IF_ERROR(StampRunReach(t, id));
  Statement st = t.Prepare(sql);
  if (kind == api::JobKind::kRun) st.Bind(1, now);
  st.Bind(2, id);
  return st.Run();
}

// ---- Beds ---------------------------------------------------------------------------------------

Result<std::optional<QueuedBed>> NextQueuedBed(Transaction& t) {
  Statement st = t.Prepare(
      "SELECT b.id, b.key, b.deck, b.attempts, b.engine_version FROM beds b WHERE b.state = 'queued' AND "
      "EXISTS (SELECT 1 FROM runs r WHERE r.bed_id = b.id AND r.state = 'queued') "
      "ORDER BY b.id LIMIT 1");
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<QueuedBed>();
  return std::optional<QueuedBed>(
      QueuedBed{st.Int(0), st.Text(1), st.Text(2), static_cast<int>(st.Int(3)), st.OptText(4)});
}

Status ExtendBedLease(Transaction& t, int64_t bed_id, double expires_at, double now) {
  Statement st = t.Prepare("UPDATE beds SET lease_expires_at = ?, heartbeat_at = ? WHERE id = ?");
  st.Bind(1, expires_at).Bind(2, now).Bind(3, bed_id);
  return st.Run();
}

Result<BedRow> LoadBed(Transaction& t, int64_t bed_id) {
  Statement st = t.Prepare("SELECT key, state, path, sha256 FROM beds WHERE id = ?");
  st.Bind(1, bed_id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::NotFound("no bed " + std::to_string(bed_id));
  Result<JobState> state = st.State(1);
  if (!state.ok()) return state.status();
  return BedRow{st.Text(0), *state, st.OptText(2), st.Text(3)};
}

Status RecordBedUpload(Transaction& t, int64_t bed_id, const std::string& path, const std::string& sha256) {
  Statement st = t.Prepare("UPDATE beds SET path = ?, sha256 = ? WHERE id = ?");
  st.Bind(1, path).Bind(2, sha256).Bind(3, bed_id);
  return st.Run();
}

Status MarkBedDone(Transaction& t, int64_t bed_id, const api::BedResult& result, int ranks, double now) {
  Statement st = t.Prepare(
      "UPDATE beds SET state = 'done', lease_expires_at = NULL, finished_at = ?, grains = ?, "
      "result = ?, ranks = ?, last_error_kind = NULL, last_error = NULL WHERE id = ?");
  st.Bind(1, now).Bind(2, result.grains).Bind(3, api::ToJsonText(nlohmann::json(result)));
  // A worker that says no rank count (0, an older worker's default is 1) leaves it unknown.
  st.Bind(4, ranks >= 1 ? std::optional<int64_t>(ranks) : std::nullopt).Bind(5, bed_id);
  return st.Run();
}

Result<int64_t> FailRunsOfBed(Transaction& t, int64_t bed_id, const std::string& reason, double now) {
  Statement st = t.Prepare(
      "UPDATE runs SET state = 'failed', finished_at = ?, last_error_kind = 'bed_failed', "
      "last_error = ? WHERE bed_id = ? AND state = 'queued'");
  st.Bind(1, now).Bind(2, reason).Bind(3, bed_id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  const int64_t n = t.Changes();
  if (n > 0) {
    SANDSWIM_RETURN_IF_ERROR(
        t.Event(now, "runs.failed", "bed/" + std::to_string(bed_id), {{"runs", n}, {"reason", reason}}));
  }
  return n;
}

// ---- Runs ---------------------------------------------------------------------------------------

Result<std::optional<QueuedRun>> NextQueuedRun(Transaction& t) {
  Statement st = t.Prepare(
      "SELECT r.id, r.key, d.deck, r.attempts, r.run_duration_s, r.steps, b.id, b.sha256, "
      "r.mode, r.A, r.f, r.osc_omega, r.rot_omega, r.axis, r.duration_s, b.scale, b.key, "
      "b.engine_version, r.precision, r.snapshots, r.materials, r.dt_s "
      "FROM runs r JOIN beds b ON b.id = r.bed_id LEFT JOIN run_decks d ON d.run_id = r.id "
      "WHERE r.state = 'queued' AND b.state = 'done' ORDER BY r.id LIMIT 1");
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<QueuedRun>();
  QueuedRun r;
  r.id = st.Int(0);
  r.key = st.Text(1);
  r.stored_deck = st.OptText(2);
  r.attempts = static_cast<int>(st.Int(3));
  r.run_duration_s = st.Double(4);
  r.steps = st.Int(5);
  r.bed_id = st.Int(6);
  r.bed_sha256 = st.Text(7);
  r.mode = st.Text(8);
  r.A = st.Double(9);
  r.f = st.Double(10);
  r.Omega = st.Double(11);
  r.omega = st.Double(12);
  r.axis = st.Text(13);
  r.duration_s = st.Double(14);
  r.scale = st.Text(15);
  r.bed_key = st.Text(16);
  r.engine_version = st.OptText(17);
  r.precision = st.OptText(18);
  r.snapshots = st.OptText(19);
  r.materials = st.OptText(20);
  r.dt_s = st.OptDouble(21);
  return std::optional<QueuedRun>(std::move(r));
}

Status FailRunDeck(Transaction& t, int64_t run_id, const std::string& why, double now) {
  Statement fail = t.Prepare(
      "UPDATE runs SET state = 'failed', finished_at = ?, last_error_kind = 'deck_error', "
      "last_error = ? WHERE id = ?");
  fail.Bind(1, now).Bind(2, why).Bind(3, run_id);
  return fail.Run();
}

Status RecordProgress(Transaction& t, int64_t run_id, double expires_at, const api::Heartbeat& beat, double now) {
  Statement st = t.Prepare(
      "UPDATE runs SET lease_expires_at = ?, sim_time_s = ?, so_z = ?, step = ?, "
      "heartbeat_at = ? WHERE id = ?");
  st.Bind(1, expires_at).Bind(2, beat.sim_time_s).Bind(3, beat.so_z);
  st.Bind(4, beat.step).Bind(5, now).Bind(6, run_id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  Statement mark = t.Prepare(
      "INSERT OR REPLACE INTO run_progress (run_id, at, step) SELECT ?1, ?2, ?3 WHERE NOT EXISTS "
      "(SELECT 1 FROM run_progress WHERE run_id = ?1 AND at > ?2 - ?4 AND at <= ?2)");
  mark.Bind(1, run_id).Bind(2, now).Bind(3, beat.step).Bind(4, kProgressMarkS);
  SANDSWIM_RETURN_IF_ERROR(mark.Run());
  if (t.Changes() == 0) return Status::Ok();
  // The table holds the last kProgressHorizonS of every run's marks: a few dozen rows a running run.
  // Marks from ahead of now (a clock that went back) go too: they would block new marks (the NOT
  // EXISTS above ignores them) and date the progress wrongly.
  Statement old = t.Prepare("DELETE FROM run_progress WHERE at < ?1 OR at > ?2");
  old.Bind(1, now - kProgressHorizonS).Bind(2, now);
  return old.Run();
}

Result<bool> RunWanted(Transaction& t, int64_t run_id) {
  Statement live = t.Prepare(
      "SELECT EXISTS (SELECT 1 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
      "WHERE sr.run_id = ? AND s.cancelled_at IS NULL)");
  live.Bind(1, run_id);
  Result<bool> row = live.Step();
  if (!row.ok()) return row.status();
  return !*row || live.Int(0) != 0;
}

Status PutResult(Transaction& t, int64_t run_id, const api::RunResult& r, const api::Execution& e, double now) {
  Statement key = t.Prepare("SELECT key FROM runs WHERE id = ?");
  key.Bind(1, run_id);
  Result<bool> row = key.Step();
  if (!row.ok()) return row.status();
  // A forced rerun replaces the old result here, in the same transaction as the state.
  return InsertResult(t, run_id, StoredResult{r, e, key.Text(0), now});
}

Status PutTrajectory(Transaction& t, int64_t run_id, const api::Trajectory& trajectory) {
  Statement st = t.Prepare("INSERT OR REPLACE INTO trajectories (run_id, data) VALUES (?, ?)");
  st.Bind(1, run_id).Bind(2, nlohmann::json(trajectory).dump());
  return st.Run();
}

Status PutLogTail(Transaction& t, int64_t run_id, const std::string& log_tail) {
  Statement st = t.Prepare("INSERT OR REPLACE INTO run_logs (run_id, log_tail) VALUES (?, ?)");
  st.Bind(1, run_id).Bind(2, log_tail);
  return st.Run();
}

Status MarkRunDone(Transaction& t, int64_t run_id, double sim_time_s, int64_t steps, double now) {
  Statement st = t.Prepare(
      "UPDATE runs SET state = 'done', lease_expires_at = NULL, finished_at = ?, "
      "last_error_kind = NULL, last_error = NULL, sim_time_s = ?, step = ? WHERE id = ?");
  st.Bind(1, now).Bind(2, sim_time_s).Bind(3, steps).Bind(4, run_id);
  return st.Run();
}

// ---- Run snapshots ------------------------------------------------------------------------------

Status PutSnapshot(Transaction& t, int64_t run_id, const api::Snapshot& s, const std::string& sha256) {
  Statement st = t.Prepare(
      "INSERT OR REPLACE INTO snapshots (run_id, idx, fraction, t_s, step, grains, bytes, sha256) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?)");
  st.Bind(1, run_id).Bind(2, static_cast<int64_t>(s.idx)).Bind(3, s.fraction).Bind(4, s.t_s);
  st.Bind(5, s.step).Bind(6, s.grains).Bind(7, s.bytes).Bind(8, sha256);
  return st.Run();
}

Result<std::optional<std::string>> SnapshotsAsked(Transaction& t, int64_t run_id) {
  Statement st = t.Prepare("SELECT snapshots FROM runs WHERE id = ?");
  st.Bind(1, run_id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<std::string>();
  return st.OptText(0);
}

Result<std::map<int64_t, std::vector<int>>> RecordedSnapshots(Transaction& t) {
  std::map<int64_t, std::vector<int>> out;
  Statement st = t.Prepare("SELECT run_id, idx FROM snapshots");
  Status s = EachRow(st, [&](const Statement& r) { out[r.Int(0)].push_back(static_cast<int>(r.Int(1))); });
  if (!s.ok()) return s;
  return out;
}

Result<std::set<int64_t>> RunningRunIds(Transaction& t) {
  std::set<int64_t> out;
  Statement st = t.Prepare("SELECT id FROM runs WHERE state = 'running'");
  Status s = EachRow(st, [&](const Statement& r) { out.insert(r.Int(0)); });
  if (!s.ok()) return s;
  return out;
}

// ---- Sweeps -------------------------------------------------------------------------------------

Status MarkSweepCancelled(Transaction& t, int64_t sweep_id, double now) {
  {
    Statement st = t.Prepare("SELECT cancelled_at FROM sweeps WHERE id = ?");
    st.Bind(1, sweep_id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) return Status::NotFound("no sweep " + std::to_string(sweep_id));
  }
  Statement st = t.Prepare("UPDATE sweeps SET cancelled_at = ? WHERE id = ? AND cancelled_at IS NULL");
  st.Bind(1, now).Bind(2, sweep_id);
  return st.Run();
}

Result<std::pair<int64_t, int64_t>> CancelOrphanedRuns(Transaction& t, int64_t sweep_id, double now) {
  // Runs of this sweep that no live sweep still wants.
  const std::string orphaned =
      "id IN (SELECT run_id FROM sweep_runs WHERE sweep_id = ?2) AND NOT EXISTS ("
      "SELECT 1 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
      "WHERE sr.run_id = runs.id AND s.cancelled_at IS NULL)";
  std::pair<int64_t, int64_t> out;
  {
    Statement st = t.Prepare(
        "UPDATE runs SET state = 'cancelled', finished_at = ?1, last_error_kind = 'cancelled', "
        "last_error = 'sweep ' || ?2 || ' was cancelled' WHERE state = 'queued' AND " +
        orphaned);
    st.Bind(1, now).Bind(2, sweep_id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    out.first = t.Changes();
  }
  Statement st = t.Prepare("UPDATE runs SET cancel_requested = 1 WHERE ?1 = ?1 AND state = 'running' AND " + orphaned);
  st.Bind(1, now).Bind(2, sweep_id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  out.second = t.Changes();
  return out;
}

}  // namespace sandswim::jobs
