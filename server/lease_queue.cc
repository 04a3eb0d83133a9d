#include "server/lease_queue.h"

#include <openssl/rand.h>

#include <cctype>
#include <cstdio>
#include <filesystem>
#include <utility>

#include <unistd.h>

#include "core/deck.h"
#include "core/keys.h"
#include "core/point.h"
#include "core/scale.h"

namespace sandswim {
namespace {

Result<std::string> NewToken() {
  unsigned char bytes[16];
  if (RAND_bytes(bytes, sizeof bytes) != 1) return Status::Internal("no randomness for a token");
  static const char kHex[] = "0123456789abcdef";
  std::string out;
  for (unsigned char b : bytes) {
    out.push_back(kHex[b >> 4]);
    out.push_back(kHex[b & 15]);
  }
  return out;
}

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

const char* Table(api::JobKind kind) { return kind == api::JobKind::kBed ? "beds" : "runs"; }
const char* Noun(api::JobKind kind) { return kind == api::JobKind::kBed ? "bed" : "run"; }
std::string Subject(api::JobKind kind, int64_t id) {
  return std::string(Noun(kind)) + "/" + std::to_string(id);
}

struct LeaseRow {
  api::JobKind kind = api::JobKind::kRun;
  int64_t job_id = 0;
  bool completed = false;
  std::string outcome;
};

// The lease a token names, or kConflict for a token this daemon never granted.
Result<LeaseRow> FindLease(Transaction& t, const std::string& token) {
  Statement st = t.Prepare("SELECT kind, job_id, completed_at, outcome FROM leases WHERE token = ?");
  st.Bind(1, token);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Conflict("unknown lease token");
  LeaseRow l;
  l.kind = st.Text(0) == "bed" ? api::JobKind::kBed : api::JobKind::kRun;
  l.job_id = st.Int(1);
  l.completed = !st.IsNull(2);
  l.outcome = st.Text(3);
  return l;
}

// The job id goes to squeue (server/pilot_watch.h): digits only, so that it can name no other.
Status CheckLeaseRequest(const api::LeaseRequest& request, const std::string& field) {
  const std::string& job = request.slurm_job;
  if (job.size() > 20 || job.find_first_not_of("0123456789") != std::string::npos) {
    return Status::InvalidArgument(field, "must be a Slurm job id (up to 20 digits), got \"" + job.substr(0, 40) + "\"");
  }
  return Status::Ok();
}

struct JobRow {
  std::string state;
  std::string lease_token;
  int attempts = 0;
  int max_attempts = 0;
};

Result<JobRow> LoadJob(Transaction& t, api::JobKind kind, int64_t id, int default_max) {
  Statement st = t.Prepare(std::string("SELECT state, lease_token, attempts, max_attempts FROM ") +
                           Table(kind) + " WHERE id = ?");
  st.Bind(1, id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Conflict(std::string(Noun(kind)) + " of this lease no longer exists");
  JobRow j;
  j.state = st.Text(0);
  j.lease_token = st.Text(1);
  j.attempts = static_cast<int>(st.Int(2));
  j.max_attempts = static_cast<int>(st.OptInt(3).value_or(default_max));
  return j;
}

// kConflict unless `token` is the current lease of a running job.
Status RequireCurrent(const JobRow& job, const std::string& token, api::JobKind kind) {
  if (job.state != "running" || job.lease_token != token) {
    return Status::Conflict("this lease on " + std::string(Noun(kind)) +
                            " is no longer held (it expired and the job was re-queued or "
                            "leased again); the job is " + job.state);
  }
  return Status::Ok();
}

// Fails the queued runs waiting for a bed that failed for good.
Status FailBedRuns(Transaction& t, int64_t bed_id, const std::string& reason, double now) {
  Statement st = t.Prepare(
      "UPDATE runs SET state = 'failed', finished_at = ?, last_error_kind = 'bed_failed', "
      "last_error = ? WHERE bed_id = ? AND state = 'queued'");
  st.Bind(1, now).Bind(2, reason).Bind(3, bed_id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  int64_t n = t.Changes();
  if (n > 0) {
    SANDSWIM_RETURN_IF_ERROR(t.Event(now, "runs.failed", "bed/" + std::to_string(bed_id),
                                     {{"runs", n}, {"reason", reason}}));
  }
  return Status::Ok();
}

// Moves a running job to queued (retry) or failed, recording why. Returns the new state.
Result<std::string> RetryOrFail(Transaction& t, api::JobKind kind, int64_t id, const JobRow& job,
                                const std::string& kind_text, const std::string& message,
                                bool retryable, double now) {
  bool retry = retryable && job.attempts < job.max_attempts;
  std::string state = retry ? "queued" : "failed";
  std::string sql = std::string("UPDATE ") + Table(kind) +
                    " SET state = ?, lease_expires_at = NULL, last_error_kind = ?, "
                    "last_error = ?, finished_at = CASE WHEN ? = 'failed' THEN ? ELSE NULL END";
  if (kind == api::JobKind::kRun) sql += ", queued_at = ?6";
  sql += " WHERE id = ?7";
  Statement st = t.Prepare(sql);
  st.Bind(1, state).Bind(2, kind_text).Bind(3, message).Bind(4, state).Bind(5, now);
  if (kind == api::JobKind::kRun) st.Bind(6, now);
  st.Bind(7, id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + (retry ? ".requeued" : ".failed"),
                                   Subject(kind, id),
                                   {{"kind", kind_text},
                                    {"message", message},
                                    {"attempts", job.attempts}}));
  if (!retry && kind == api::JobKind::kBed) {
    SANDSWIM_RETURN_IF_ERROR(FailBedRuns(
        t, id, "bed " + std::to_string(id) + " failed: " + kind_text + ": " + message, now));
  }
  return state;
}

// The job leased together with the completion of `token` (leases.next_token), put back in the
// queue as if never leased (attempt uncounted) when it is still running under that grant.
Status TakeBackUnreceivedGrant(Transaction& t, const std::string& token, double now) {
  Statement find = t.Prepare(
      "SELECT n.token, n.kind, n.job_id FROM leases l JOIN leases n ON n.token = l.next_token "
      "WHERE l.token = ? AND n.completed_at IS NULL AND n.outcome IS NULL");
  find.Bind(1, token);
  Result<bool> row = find.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Ok();
  const std::string next_token = find.Text(0);
  const api::JobKind kind = find.Text(1) == "bed" ? api::JobKind::kBed : api::JobKind::kRun;
  const int64_t id = find.Int(2);
  Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) +
                           " SET state = 'queued', attempts = attempts - 1, lease_token = NULL, "
                           "lease_expires_at = NULL WHERE id = ? AND state = 'running' AND lease_token = ?");
  st.Bind(1, id).Bind(2, next_token);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  if (t.Changes() == 0) return Status::Ok();  // it has moved on (expired, heartbeated, ...)
  Statement done = t.Prepare("UPDATE leases SET completed_at = ?, outcome = 'unreceived' WHERE token = ?");
  done.Bind(1, now).Bind(2, next_token);
  SANDSWIM_RETURN_IF_ERROR(done.Run());
  return t.Event(now, std::string(Noun(kind)) + ".requeued", Subject(kind, id),
                 {{"kind", "unreceived"},
                  {"message", "leased with a completion whose reply was lost; the worker asked again"}});
}

// Running jobs whose lease is lost -- expired before `now` or, when `slurm_job` is set, granted to
// that Slurm job (which Slurm no longer runs) -- go back to the queue, their attempt counted, or
// fail at max_attempts. Returns how many.
// A Slurm job's leases are only reclaimed when they were granted at or before `asked_at` (when
// Slurm was asked) and their worker has been silent for at least `silent_s` (no heartbeat since
// now - silent_s): a worker that still heartbeats is alive, whatever squeue said.
Result<int64_t> ReclaimIn(Transaction& t, double now, int default_max, const std::string& slurm_job = "",
                          double asked_at = 0, double silent_s = 0, double ttl_s = 0) {
  int64_t expired = 0;
  for (api::JobKind kind : {api::JobKind::kBed, api::JobKind::kRun}) {
    struct Expired {
      int64_t id;
      JobRow job;
      std::string worker;
    };
    std::vector<Expired> rows;
    {
      // lease_expires_at is the last heartbeat (or the grant) plus the TTL.
      const std::string lost = slurm_job.empty()
                                   ? "j.lease_expires_at < ?1"
                                   : "j.lease_expires_at <= ?1 AND j.lease_token IN (SELECT token FROM leases "
                                     "WHERE slurm_job = ?2 AND completed_at IS NULL AND outcome IS NULL AND "
                                     "granted_at <= ?3)";
      Statement st = t.Prepare(std::string("SELECT j.id, j.lease_token, j.attempts, j.max_attempts, j.worker "
                                           "FROM ") +
                               Table(kind) + " j WHERE j.state = 'running' AND " + lost + " ORDER BY j.id");
      if (slurm_job.empty()) {
        st.Bind(1, now);
      } else {
        st.Bind(1, now - silent_s + ttl_s).Bind(2, slurm_job).Bind(3, asked_at);
      }
      while (true) {
        Result<bool> row = st.Step();
        if (!row.ok()) return row.status();
        if (!*row) break;
        Expired e;
        e.id = st.Int(0);
        e.job.state = "running";
        e.job.lease_token = st.Text(1);
        e.job.attempts = static_cast<int>(st.Int(2));
        e.job.max_attempts = static_cast<int>(st.OptInt(3).value_or(default_max));
        e.worker = st.Text(4);
        rows.push_back(std::move(e));
      }
    }
    for (const Expired& e : rows) {
      Result<std::string> state =
          slurm_job.empty()
              ? RetryOrFail(t, kind, e.id, e.job, "lease_expired",
                            "worker " + e.worker + " stopped heartbeating (lease expired)", /*retryable=*/true, now)
              : RetryOrFail(t, kind, e.id, e.job, "pilot_gone",
                            "Slurm no longer runs job " + slurm_job + " of worker " + e.worker +
                                " (its leases were reclaimed before they expired)",
                            /*retryable=*/true, now);
      if (!state.ok()) return state.status();
      Statement st = t.Prepare("UPDATE leases SET outcome = 'expired' WHERE token = ?");
      st.Bind(1, e.job.lease_token);
      SANDSWIM_RETURN_IF_ERROR(st.Run());
      ++expired;
    }
  }
  if (expired > 0) SANDSWIM_RETURN_IF_ERROR(t.Count(slurm_job.empty() ? "expirations" : "pilots_gone", expired));
  return expired;
}

}  // namespace

void to_json(nlohmann::json& j, const CancelSummary& c) {
  j = nlohmann::json{{"cancelled", c.cancelled}, {"stopping", c.stopping}};
}

LeaseQueue::LeaseQueue(Store* store, Clock* clock, LeaseQueueOptions options)
    : store_(store), clock_(clock), options_(options) {}

Result<std::optional<api::LeaseGrant>> LeaseQueue::Lease(const api::LeaseRequest& request) {
  using Out = std::optional<api::LeaseGrant>;
  // Group commit (store.h): this change shares its transaction with concurrent ones.
  return store_->WriteResult<Out>([&](Transaction& t) { return LeaseIn(t, request, clock_->Now()); });
}

Result<std::optional<api::LeaseGrant>> LeaseQueue::LeaseIn(Transaction& t, const api::LeaseRequest& request,
                                                           double now) {
  using Out = std::optional<api::LeaseGrant>;
  SANDSWIM_RETURN_IF_ERROR(CheckLeaseRequest(request, "slurm_job"));
  Result<int64_t> expired = ReclaimIn(t, now, options_.max_attempts);
  if (!expired.ok()) return expired.status();

  api::LeaseGrant g;
  g.ttl_s = options_.ttl_s;
  g.wall_budget_s = options_.wall_budget_s;
  bool found = false;
  {
    // Beds first: a bed some queued run is waiting for.
    Statement st = t.Prepare(
        "SELECT b.id, b.key, b.deck, b.attempts FROM beds b WHERE b.state = 'queued' AND "
        "EXISTS (SELECT 1 FROM runs r WHERE r.bed_id = b.id AND r.state = 'queued') "
        "ORDER BY b.id LIMIT 1");
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (*row) {
      found = true;
      g.kind = api::JobKind::kBed;
      g.id = st.Int(0);
      g.key = st.Text(1);
      g.deck = st.Text(2);
      g.attempt = static_cast<int>(st.Int(3)) + 1;
    }
  }
  // Then the oldest queued run whose bed is done. Its deck is rendered from its point and its
  // bed's scale (runs submitted before migration 3 have it stored in run_decks) and checked
  // against the run's key; a run whose deck no longer renders to its key (the templates changed
  // since it was submitted) fails with "deck_error" and the next run is tried.
  while (!found) {
    Statement st = t.Prepare(
        "SELECT r.id, r.key, d.deck, r.attempts, r.run_duration_s, r.steps, b.id, b.sha256, "
        "r.mode, r.A, r.f, r.osc_omega, r.rot_omega, r.axis, r.duration_s, b.scale, b.key, "
        "b.engine_version "
        "FROM runs r JOIN beds b ON b.id = r.bed_id LEFT JOIN run_decks d ON d.run_id = r.id "
        "WHERE r.state = 'queued' AND b.state = 'done' ORDER BY r.id LIMIT 1");
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    g.kind = api::JobKind::kRun;
    g.id = st.Int(0);
    g.key = st.Text(1);
    g.attempt = static_cast<int>(st.Int(3)) + 1;
    g.duration_s = st.Double(4);
    g.steps = st.Int(5);
    int64_t bed_id = st.Int(6);
    g.bed = api::BedRef{bed_id, st.Text(7), "/api/v1/beds/" + std::to_string(bed_id) + "/restart"};
    if (!st.IsNull(2)) {
      g.deck = st.Text(2);
      found = true;
      break;
    }
    Point p;
    std::optional<Mode> mode = ParseMode(st.Text(8));
    std::optional<RotationAxis> axis = ParseAxis(st.Text(13));
    p.A = st.Double(9);
    p.f = st.Double(10);
    p.Omega = st.Double(11);
    p.omega = st.Double(12);
    p.duration_s = st.Double(14);
    const Scale* scale = FindScale(st.Text(15));
    const std::string bed_key = st.Text(16);
    const std::optional<std::string> engine_version = st.OptText(17);
    std::string why;
    if (!mode || !axis || scale == nullptr) {
      why = "its stored point or scale no longer parses";
    } else {
      p.mode = *mode;
      p.axis = *axis;
      try {
        g.deck = RenderDriveDeck(p, *scale);
      } catch (const std::exception& e) {
        why = std::string("its deck no longer renders: ") + e.what();
      }
      if (why.empty() && engine_version && RunKey(g.deck, bed_key, *engine_version) != g.key) {
        why = "its deck no longer renders to its key (the deck templates changed since it was "
              "submitted); submit its sweep again";
      }
    }
    if (why.empty()) {
      found = true;
      break;
    }
    Statement fail = t.Prepare(
        "UPDATE runs SET state = 'failed', finished_at = ?, last_error_kind = 'deck_error', "
        "last_error = ? WHERE id = ?");
    fail.Bind(1, now).Bind(2, why).Bind(3, g.id);
    SANDSWIM_RETURN_IF_ERROR(fail.Run());
    SANDSWIM_RETURN_IF_ERROR(t.Event(now, "run.failed", Subject(api::JobKind::kRun, g.id),
                                     {{"kind", "deck_error"}, {"message", why}}));
  }
  if (!found) return Out();  // committed with the group when it expired leases or failed decks
  Result<std::string> token = NewToken();
  if (!token.ok()) return token.status();
  g.token = *token;
  {
    Statement st = t.Prepare(std::string("UPDATE ") + Table(g.kind) +
                             " SET state = 'running', attempts = attempts + 1, lease_token = ?, "
                             "lease_expires_at = ?, worker = ?, started_at = ? WHERE id = ?");
    st.Bind(1, g.token).Bind(2, now + options_.ttl_s).Bind(3, request.worker).Bind(4, now);
    st.Bind(5, g.id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  {
    Statement st = t.Prepare(
        "INSERT INTO leases (token, kind, job_id, attempt, worker, host, ranks, granted_at, slurm_job) "
        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)");
    st.Bind(1, g.token).Bind(2, Noun(g.kind)).Bind(3, g.id).Bind(4, g.attempt);
    st.Bind(5, request.worker).Bind(6, request.host).Bind(7, request.ranks).Bind(8, now);
    if (request.slurm_job.empty()) {
      st.BindNull(9);
    } else {
      st.Bind(9, request.slurm_job);
    }
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  SANDSWIM_RETURN_IF_ERROR(t.Count("leases_granted"));
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(g.kind)) + ".leased",
                                   Subject(g.kind, g.id),
                                   {{"worker", request.worker},
                                    {"host", request.host},
                                    {"ranks", request.ranks},
                                    {"attempt", g.attempt}}));
  return Out(std::move(g));
}

Result<api::HeartbeatReply> LeaseQueue::Heartbeat(const std::string& token,
                                                  const api::Heartbeat& beat) {
  return store_->WriteResult<api::HeartbeatReply>([&](Transaction& t) -> Result<api::HeartbeatReply> {
    const double now = clock_->Now();
    Result<LeaseRow> lease = FindLease(t, token);
    if (!lease.ok()) return lease.status();
    Result<JobRow> job = LoadJob(t, lease->kind, lease->job_id, options_.max_attempts);
    if (!job.ok()) return job.status();
    SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, lease->kind));

    api::HeartbeatReply reply;
    reply.ttl_s = options_.ttl_s;
    if (lease->kind == api::JobKind::kRun) {
      Statement st = t.Prepare(
          "UPDATE runs SET lease_expires_at = ?, sim_time_s = ?, so_z = ?, step = ?, "
          "heartbeat_at = ? WHERE id = ?");
      st.Bind(1, now + options_.ttl_s).Bind(2, beat.sim_time_s).Bind(3, beat.so_z);
      st.Bind(4, beat.step).Bind(5, now).Bind(6, lease->job_id);
      SANDSWIM_RETURN_IF_ERROR(st.Run());
      // Stop only when no live sweep wants the run any more (it may be shared).
      Statement live = t.Prepare(
          "SELECT EXISTS (SELECT 1 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
          "WHERE sr.run_id = ? AND s.cancelled_at IS NULL)");
      live.Bind(1, lease->job_id);
      Result<bool> row = live.Step();
      if (!row.ok()) return row.status();
      reply.cancel = *row && live.Int(0) == 0;
    } else {
      Statement st = t.Prepare("UPDATE beds SET lease_expires_at = ? WHERE id = ?");
      st.Bind(1, now + options_.ttl_s).Bind(2, lease->job_id);
      SANDSWIM_RETURN_IF_ERROR(st.Run());
    }
    return reply;
  });
}

Result<api::CompletionReply> LeaseQueue::Complete(const std::string& token,
                                                  const api::Completion& c) {
  return store_->WriteResult<api::CompletionReply>([&](Transaction& t) -> Result<api::CompletionReply> {
    const double now = clock_->Now();
    if (c.next) SANDSWIM_RETURN_IF_ERROR(CheckLeaseRequest(*c.next, "next.slurm_job"));
    Result<api::CompletionReply> reply = CompleteIn(t, token, c, now);
    if (!reply.ok() || !c.next) return reply;
    if (reply->state == "duplicate") {
      // A retry: the reply to the first completion was lost, and with it the job it leased. That
      // job was never started: take it back (queued, attempt uncounted) before leasing again.
      SANDSWIM_RETURN_IF_ERROR(TakeBackUnreceivedGrant(t, token, now));
    }
    // The worker's next job, in the same transaction, after the completion (so the bed just
    // done counts; a run just failed and queued for a retry may come straight back).
    Result<std::optional<api::LeaseGrant>> next = LeaseIn(t, *c.next, now);
    if (!next.ok()) return next.status();
    if (*next) {
      Statement st = t.Prepare("UPDATE leases SET next_token = ? WHERE token = ?");
      st.Bind(1, (*next)->token).Bind(2, token);
      SANDSWIM_RETURN_IF_ERROR(st.Run());
    }
    reply->next = std::move(*next);
    return reply;
  });
}

Result<api::CompletionReply> LeaseQueue::CompleteIn(Transaction& t, const std::string& token,
                                                    const api::Completion& c, double now) {
  Result<LeaseRow> lease = FindLease(t, token);
  if (!lease.ok()) return lease.status();
  if (lease->completed) {
    SANDSWIM_RETURN_IF_ERROR(t.Count("duplicates"));
    return api::CompletionReply{"duplicate"};
  }
  const api::JobKind kind = lease->kind;
  const int64_t id = lease->job_id;
  Result<JobRow> job = LoadJob(t, kind, id, options_.max_attempts);
  if (!job.ok()) return job.status();
  SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, kind));

  if (c.ok && kind == api::JobKind::kRun && !c.result) {
    return Status::InvalidArgument("result", "an ok run completion carries its result");
  }
  if (c.ok && kind == api::JobKind::kBed && !c.bed_result) {
    return Status::InvalidArgument("bed_result", "an ok bed completion carries its bed_result");
  }
  if (!c.ok && !c.failure) {
    return Status::InvalidArgument("failure", "a failed completion says why");
  }

  std::string state;
  if (c.ok && kind == api::JobKind::kRun) {
    const api::RunResult& r = *c.result;
    const api::Execution& e = c.execution;
    {
      Statement key = t.Prepare("SELECT key FROM runs WHERE id = ?");
      key.Bind(1, id);
      Result<bool> row = key.Step();
      if (!row.ok()) return row.status();
      // A forced rerun replaces the old result here, in the same transaction as the state.
      Statement st = t.Prepare(
          "INSERT OR REPLACE INTO results (run_id, uz, uz_stderr, window_t0, window_t1, dz, "
          "z_osc_amplitude, x_drift, broke_surface, near_floor, stop_reason, sim_time_s, steps, "
          "grains, z0, engine_version, host, ranks, launcher, wall_s, cpu_s, key, created_at, "
          "lease_to_start_s, uz_ci95, uz_stderr_note, uz_blocks, block_s, window_end, conclusive, "
          "inconclusive_reason, dz_rate, analysis, block_kind) "
          "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)");
      st.Bind(1, id).Bind(2, r.uz).Bind(3, r.uz_stderr).Bind(4, r.window_t0).Bind(5, r.window_t1);
      st.Bind(6, r.dz).Bind(7, r.z_osc_amplitude).Bind(8, r.x_drift).Bind(9, r.broke_surface);
      st.Bind(10, r.near_floor).Bind(11, r.stop_reason).Bind(12, r.sim_time_s).Bind(13, r.steps);
      st.Bind(14, r.grains).Bind(15, r.z0).Bind(16, e.engine_version).Bind(17, e.host);
      st.Bind(18, e.ranks).Bind(19, e.launcher).Bind(20, e.wall_s).Bind(21, e.cpu_s);
      st.Bind(22, key.Text(0)).Bind(23, now).Bind(24, e.lease_to_start_s);
      st.Bind(25, r.uz_ci95).Bind(26, r.uz_stderr_note).Bind(27, r.uz_blocks).Bind(28, r.block_s);
      st.Bind(29, r.window_end).Bind(30, r.conclusive).Bind(31, r.inconclusive_reason).Bind(32, r.dz_rate);
      st.Bind(33, r.analysis).Bind(34, r.block_kind);
      SANDSWIM_RETURN_IF_ERROR(st.Run());
    }
    if (c.trajectory) {
      Statement st = t.Prepare("INSERT OR REPLACE INTO trajectories (run_id, data) VALUES (?, ?)");
      st.Bind(1, id).Bind(2, nlohmann::json(*c.trajectory).dump());
      SANDSWIM_RETURN_IF_ERROR(st.Run());
    }
    Statement st = t.Prepare(
        "UPDATE runs SET state = 'done', lease_expires_at = NULL, finished_at = ?, "
        "last_error_kind = NULL, last_error = NULL, sim_time_s = ?, step = ? WHERE id = ?");
    st.Bind(1, now).Bind(2, r.sim_time_s).Bind(3, r.steps).Bind(4, id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    state = "done";
  } else if (c.ok) {
    const api::BedResult& b = *c.bed_result;
    Statement cur = t.Prepare("SELECT path, sha256 FROM beds WHERE id = ?");
    cur.Bind(1, id);
    Result<bool> row = cur.Step();
    if (!row.ok()) return row.status();
    if (cur.IsNull(0)) {
      return Status::FailedPrecondition("bed_result",
                                        "upload the bed's restart file before completing it");
    }
    if (!b.sha256.empty() && Lower(b.sha256) != cur.Text(1)) {
      return Status::FailedPrecondition("bed_result.sha256",
                                        "differs from the uploaded restart file's checksum");
    }
    Statement st = t.Prepare(
        "UPDATE beds SET state = 'done', lease_expires_at = NULL, finished_at = ?, grains = ?, "
        "result = ?, last_error_kind = NULL, last_error = NULL WHERE id = ?");
    st.Bind(1, now).Bind(2, b.grains).Bind(3, api::ToJsonText(nlohmann::json(b))).Bind(4, id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    state = "done";
  } else {
    const api::Failure& f = *c.failure;
    if (f.kind == "cancelled") {
      // A bed is never cancelled (other sweeps may want it): it goes back to the queue.
      std::string to = kind == api::JobKind::kRun ? "cancelled" : "queued";
      Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) +
                               " SET state = ?, lease_expires_at = NULL, last_error_kind = ?, "
                               "last_error = ?, finished_at = ? WHERE id = ?");
      st.Bind(1, to).Bind(2, f.kind).Bind(3, f.message);
      if (to == "cancelled") st.Bind(4, now); else st.BindNull(4);
      st.Bind(5, id);
      SANDSWIM_RETURN_IF_ERROR(st.Run());
      SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + "." + to,
                                       Subject(kind, id), {{"message", f.message}}));
      state = to;
    } else {
      Result<std::string> s = RetryOrFail(t, kind, id, *job, f.kind, f.message,
                                          /*retryable=*/f.kind != "deck_error", now);
      if (!s.ok()) return s.status();
      state = *s;
    }
  }
  if (kind == api::JobKind::kRun && !c.log_tail.empty()) {
    Statement st = t.Prepare("INSERT OR REPLACE INTO run_logs (run_id, log_tail) VALUES (?, ?)");
    st.Bind(1, id).Bind(2, c.log_tail);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  if (state == "done") {
    SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + ".done", Subject(kind, id),
                                     {{"host", c.execution.host},
                                      {"wall_s", c.execution.wall_s}}));
  }
  {
    Statement st = t.Prepare("UPDATE leases SET completed_at = ?, outcome = ? WHERE token = ?");
    st.Bind(1, now).Bind(2, state).Bind(3, token);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  SANDSWIM_RETURN_IF_ERROR(t.Count("completions"));
  return api::CompletionReply{state};
}

Result<api::CompletionReply> LeaseQueue::Release(const std::string& token, const std::string& reason) {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->Begin();
  if (!begun.ok()) return begun.status();
  Transaction& t = *begun;
  Result<LeaseRow> lease = FindLease(t, token);
  if (!lease.ok()) return lease.status();
  if (lease->completed) return api::CompletionReply{"duplicate"};
  const api::JobKind kind = lease->kind;
  const int64_t id = lease->job_id;
  Result<JobRow> job = LoadJob(t, kind, id, options_.max_attempts);
  if (!job.ok()) return job.status();
  SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, kind));
  int64_t released_before = 0;
  {
    Statement st = t.Prepare(std::string("SELECT releases FROM ") + Table(kind) + " WHERE id = ?");
    st.Bind(1, id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (*row) released_before = st.Int(0);
  }
  {
    Statement st = t.Prepare(std::string("UPDATE ") + Table(kind) + " SET releases = releases + 1 WHERE id = ?");
    st.Bind(1, id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    Statement up = t.Prepare("UPDATE leases SET completed_at = ?, outcome = 'released' WHERE token = ?");
    up.Bind(1, now).Bind(2, token);
    SANDSWIM_RETURN_IF_ERROR(up.Run());
  }
  if (released_before >= job->max_attempts) {
    // Handed back this often, the job does not fit where it is leased (a run longer than any
    // allocation): from now on a hand-back is an attempt, so the job ends failed, not leased for ever.
    Result<std::string> state = RetryOrFail(
        t, kind, id, *job, "released",
        "handed back " + std::to_string(released_before + 1) + " times (" + reason +
            "): it never finished where it was leased; give the pilots a longer --time",
        /*retryable=*/true, now);
    if (!state.ok()) return state.status();
    SANDSWIM_RETURN_IF_ERROR(t.Commit());
    return api::CompletionReply{*state};
  }
  // A run that no live sweep wants any more (its sweep was cancelled while it ran) is cancelled,
  // as Cancel() does with queued runs, rather than queued again.
  bool wanted = true;
  if (kind == api::JobKind::kRun) {
    Statement live = t.Prepare(
        "SELECT EXISTS (SELECT 1 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
        "WHERE sr.run_id = ? AND s.cancelled_at IS NULL)");
    live.Bind(1, id);
    Result<bool> row = live.Step();
    if (!row.ok()) return row.status();
    wanted = !*row || live.Int(0) != 0;
  }
  // Otherwise back to the queue as if this lease had never been granted: the attempt is not counted.
  std::string sql = std::string("UPDATE ") + Table(kind) +
                    (wanted ? " SET state = 'queued', attempts = MAX(attempts - 1, 0), lease_expires_at = NULL"
                            : " SET state = 'cancelled', attempts = MAX(attempts - 1, 0), lease_expires_at = NULL, "
                              "finished_at = ?1, last_error_kind = 'cancelled', "
                              "last_error = 'its sweeps were cancelled while it ran'");
  if (kind == api::JobKind::kRun && wanted) sql += ", queued_at = ?1";
  sql += " WHERE id = ?2";
  Statement st = t.Prepare(sql);
  if (kind == api::JobKind::kRun) st.Bind(1, now);
  st.Bind(2, id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + (wanted ? ".released" : ".cancelled"),
                                   Subject(kind, id), {{"reason", reason}, {"attempts", job->attempts - 1}}));
  SANDSWIM_RETURN_IF_ERROR(t.Commit());
  return api::CompletionReply{wanted ? "queued" : "cancelled"};
}

Result<std::vector<std::string>> LeaseQueue::RunningSlurmJobs() {
  Result<Transaction> t = store_->BeginRead();
  if (!t.ok()) return t.status();
  // Open leases (the partial index leases_open_by_slurm_job), their jobs found by primary key.
  Statement st = t->Prepare(
      "SELECT DISTINCT l.slurm_job FROM leases l WHERE l.slurm_job IS NOT NULL AND l.completed_at IS NULL "
      "AND l.outcome IS NULL AND ((l.kind = 'run' AND EXISTS (SELECT 1 FROM runs r WHERE r.id = l.job_id AND "
      "r.lease_token = l.token AND r.state = 'running')) OR (l.kind = 'bed' AND EXISTS (SELECT 1 FROM beds b "
      "WHERE b.id = l.job_id AND b.lease_token = l.token AND b.state = 'running'))) ORDER BY l.slurm_job");
  std::vector<std::string> jobs;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    jobs.push_back(st.Text(0));
  }
  return jobs;
}

Result<int64_t> LeaseQueue::ReclaimSlurmJob(const std::string& slurm_job, double asked_at) {
  if (slurm_job.empty()) return Status::InvalidArgument("slurm_job", "names no Slurm job");
  return store_->WriteResult<int64_t>([&](Transaction& t) {
    return ReclaimIn(t, clock_->Now(), options_.max_attempts, slurm_job, asked_at, options_.ttl_s / 2,
                     options_.ttl_s);
  });
}

Result<int64_t> LeaseQueue::ExpireLeases() {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->Begin();
  if (!begun.ok()) return begun.status();
  Result<int64_t> n = ReclaimIn(*begun, now, options_.max_attempts);
  if (!n.ok()) return n.status();
  SANDSWIM_RETURN_IF_ERROR(begun->Commit());
  return n;
}

Result<CancelSummary> LeaseQueue::Cancel(int64_t sweep_id) {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->Begin();
  if (!begun.ok()) return begun.status();
  Transaction& t = *begun;
  {
    Statement st = t.Prepare("SELECT cancelled_at FROM sweeps WHERE id = ?");
    st.Bind(1, sweep_id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) return Status::NotFound("no sweep " + std::to_string(sweep_id));
  }
  {
    Statement st = t.Prepare("UPDATE sweeps SET cancelled_at = ? WHERE id = ? AND cancelled_at IS NULL");
    st.Bind(1, now).Bind(2, sweep_id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  // Runs of this sweep that no live sweep still wants.
  const std::string orphaned =
      "id IN (SELECT run_id FROM sweep_runs WHERE sweep_id = ?2) AND NOT EXISTS ("
      "SELECT 1 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
      "WHERE sr.run_id = runs.id AND s.cancelled_at IS NULL)";
  CancelSummary out;
  {
    Statement st = t.Prepare(
        "UPDATE runs SET state = 'cancelled', finished_at = ?1, last_error_kind = 'cancelled', "
        "last_error = 'sweep ' || ?2 || ' was cancelled' WHERE state = 'queued' AND " + orphaned);
    st.Bind(1, now).Bind(2, sweep_id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    out.cancelled = t.Changes();
  }
  {
    Statement st = t.Prepare("UPDATE runs SET cancel_requested = 1 WHERE ?1 = ?1 AND "
                             "state = 'running' AND " + orphaned);
    st.Bind(1, now).Bind(2, sweep_id);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    out.stopping = t.Changes();
  }
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, "sweep.cancelled", "sweep/" + std::to_string(sweep_id),
                                   {{"cancelled", out.cancelled}, {"stopping", out.stopping}}));
  SANDSWIM_RETURN_IF_ERROR(t.Commit());
  return out;
}

Status LeaseQueue::PutBedRestart(const std::string& token, std::string_view bytes,
                                 const std::string& sha256, const std::string& data_dir) {
  const std::string expected = Lower(sha256);
  const std::string actual = Sha256Hex(bytes);
  if (expected != actual) {
    return Status::InvalidArgument("X-Sha256", "the body's SHA-256 is " + actual + ", not " +
                                                   (expected.empty() ? "(none given)" : expected));
  }
  // Check the lease, write the file without holding the store, then record it under a second
  // check: the token may have been lost while the bytes were being written.
  auto check = [&](Transaction& t) -> Result<std::pair<int64_t, std::string>> {
    Result<LeaseRow> lease = FindLease(t, token);
    if (!lease.ok()) return lease.status();
    if (lease->kind != api::JobKind::kBed) return Status::Conflict("this lease is not a bed's");
    if (lease->completed) return Status::Conflict("this bed lease already completed");
    Result<JobRow> job = LoadJob(t, api::JobKind::kBed, lease->job_id, options_.max_attempts);
    if (!job.ok()) return job.status();
    SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, api::JobKind::kBed));
    Statement st = t.Prepare("SELECT key FROM beds WHERE id = ?");
    st.Bind(1, lease->job_id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    return std::make_pair(lease->job_id, st.Text(0));
  };
  std::string key;
  {
    Result<Transaction> t = store_->BeginRead();
    if (!t.ok()) return t.status();
    auto found = check(*t);
    if (!found.ok()) return found.status();
    key = found->second;
  }
  namespace fs = std::filesystem;
  const fs::path dir = fs::path(data_dir) / "beds";
  const fs::path path = dir / (key + ".restart");
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Status::IOError("cannot create " + dir.string() + ": " + ec.message());
  Result<std::string> suffix = NewToken();
  if (!suffix.ok()) return suffix.status();
  const fs::path tmp = dir / (key + ".restart.tmp." + suffix->substr(0, 8));
  {
    FILE* f = std::fopen(tmp.c_str(), "wb");
    if (f == nullptr) return Status::IOError("cannot write " + tmp.string());
    bool good = std::fwrite(bytes.data(), 1, bytes.size(), f) == bytes.size();
    good = std::fflush(f) == 0 && good;
    good = ::fsync(fileno(f)) == 0 && good;
    good = std::fclose(f) == 0 && good;
    if (!good) {
      fs::remove(tmp, ec);
      return Status::IOError("cannot write " + tmp.string());
    }
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return Status::IOError("cannot rename into " + path.string() + ": " + ec.message());
  }
  const double now = clock_->Now();
  Result<Transaction> t = store_->Begin();
  if (!t.ok()) return t.status();
  auto found = check(*t);
  if (!found.ok()) return found.status();
  {
    Statement st = t->Prepare("UPDATE beds SET path = ?, sha256 = ? WHERE id = ?");
    st.Bind(1, path.string()).Bind(2, actual).Bind(3, found->first);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  SANDSWIM_RETURN_IF_ERROR(t->Event(now, "bed.uploaded", "bed/" + std::to_string(found->first),
                                    {{"sha256", actual}, {"bytes", bytes.size()}}));
  return t->Commit();
}

Result<BedFile> LeaseQueue::GetBedRestart(int64_t bed_id) {
  Result<Transaction> t = store_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare("SELECT key, state, path, sha256 FROM beds WHERE id = ?");
  st.Bind(1, bed_id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::NotFound("no bed " + std::to_string(bed_id));
  if (st.Text(1) != "done" || st.IsNull(2)) {
    return Status::FailedPrecondition("bed", "bed " + std::to_string(bed_id) +
                                                 " is not prepared yet (" + st.Text(1) + ")");
  }
  return BedFile{bed_id, st.Text(0), st.Text(2), st.Text(3)};
}

}  // namespace sandswim
