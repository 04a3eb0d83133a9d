#include "server/jobs/lease_queue.h"

#include <openssl/rand.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <set>
#include <utility>

#include <unistd.h>

#include "core/deck.h"
#include "core/keys.h"
#include "core/snapshot.h"
#include "core/point.h"
#include "core/scale.h"
#include "core/trajectory.h"
#include "platform/data_dir.h"
#include "platform/files.h"
#include "server/store/cost_model.h"
#include "server/store/rounds.h"

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

using jobs::JobRow;
using jobs::LeaseRow;
using jobs::Noun;
using jobs::Subject;

// The job id goes to squeue (server/jobs/pilot_watch.h): digits only, so that it can name no other.
Status CheckLeaseRequest(const api::LeaseRequest& request, const std::string& field) {
  const std::string& job = request.slurm_job;
  if (job.size() > 20 || job.find_first_not_of("0123456789") != std::string::npos) {
    return Status::InvalidArgument(field,
                                   "must be a Slurm job id (up to 20 digits), got \"" + job.substr(0, 40) + "\"");
  }
  return Status::Ok();
}

// kConflict unless `token` is the current lease of a running job.
Status RequireCurrent(const JobRow& job, const std::string& token, api::JobKind kind) {
  if (job.state != JobState::kRunning || job.lease_token != token) {
    return Status::Conflict("this lease on " + std::string(Noun(kind)) +
                            " is no longer held (it expired and the job was re-queued or "
                            "leased again); the job is " +
                            ToString(job.state));
  }
  return Status::Ok();
}

// The uploads' lease check: `token` is a current, uncompleted lease of `kind`; its lease row.
Result<LeaseRow> CurrentUploadLease(Transaction& t, const std::string& token, api::JobKind kind, int max_attempts) {
  Result<LeaseRow> lease = jobs::FindLease(t, token);
  if (!lease.ok()) return lease.status();
  const std::string noun = kind == api::JobKind::kBed ? "bed" : "run";
  if (lease->kind != kind) return Status::Conflict("this lease is not a " + noun + "'s");
  if (lease->completed) return Status::Conflict("this " + noun + " lease already completed");
  Result<JobRow> job = jobs::LoadJob(t, kind, lease->job_id, max_attempts);
  if (!job.ok()) return job.status();
  SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, kind));
  return lease;
}

// Moves a running job to queued (retry) or failed, recording why. Returns the new state.
Result<JobState> RetryOrFail(Transaction& t, api::JobKind kind, int64_t id, const JobRow& job,
                             const std::string& kind_text, const std::string& message, bool retryable, double now) {
  bool retry = retryable && job.attempts < job.max_attempts;
  // A lease the daemon reclaimed says nothing of the run itself (its worker vanished).
  const bool lost = kind_text == "lease_expired" || kind_text == "pilot_gone";
  if ((retry || lost) && kind == api::JobKind::kRun) {
    // A run whose every sweep was cancelled while it ran (its worker was told to stop, and then
    // lost: the lease expired) is not run again, nor failed when that was its last attempt: it is
    // cancelled, its attempt uncounted.
    Result<bool> wanted = jobs::RunWanted(t, id);
    if (!wanted.ok()) return wanted.status();
    if (!*wanted) {
      SANDSWIM_RETURN_IF_ERROR(jobs::MarkReleased(t, kind, id, /*wanted=*/false, now));
      SANDSWIM_RETURN_IF_ERROR(t.Event(now, "run.cancelled", Subject(kind, id),
                                       {{"kind", kind_text}, {"message", message + "; its sweeps were cancelled"}}));
      return JobState::kCancelled;
    }
  }
  const JobState state = retry ? JobState::kQueued : JobState::kFailed;
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkRetriedOrFailed(t, kind, id, state, kind_text, message, now));
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + (retry ? ".requeued" : ".failed"), Subject(kind, id),
                                   {{"kind", kind_text}, {"message", message}, {"attempts", job.attempts}}));
  if (!retry && kind == api::JobKind::kBed) {
    Result<int64_t> n =
        jobs::FailRunsOfBed(t, id, "bed " + std::to_string(id) + " failed: " + kind_text + ": " + message, now);
    if (!n.ok()) return n.status();
  }
  return state;
}

// Hands a running job back unfinished under its current lease `token` (Release, and the daemon's own
// hand-backs: see LeaseQueue::HandBackLeasesOf): queued again with the attempt uncounted, or
// cancelled when no live sweep wants the run -- unless it was handed back max_attempts times
// before: then it counts ("released"). The lease closes as "released". Returns the job's state.
Result<JobState> HandBackIn(Transaction& t, api::JobKind kind, int64_t id, const JobRow& job,
                            const std::string& token, const std::string& reason, double now) {
  Result<int64_t> released_before = jobs::CountRelease(t, kind, id);
  if (!released_before.ok()) return released_before.status();
  SANDSWIM_RETURN_IF_ERROR(jobs::CloseLease(t, token, now, "released"));
  if (*released_before >= job.max_attempts) {
    // Handed back this often, the job does not fit where it is leased (a run longer than any
    // allocation): from now on a hand-back is an attempt, so the job ends failed, not leased for ever.
    return RetryOrFail(t, kind, id, job, "released",
                       "handed back " + std::to_string(*released_before + 1) + " times (" + reason +
                           "): it never finished where it was leased; give the pilots a longer --time",
                       /*retryable=*/true, now);
  }
  // A run that no live sweep wants any more (its sweep was cancelled while it ran) is cancelled,
  // as Cancel() does with queued runs, rather than queued again.
  bool wanted = true;
  if (kind == api::JobKind::kRun) {
    Result<bool> live = jobs::RunWanted(t, id);
    if (!live.ok()) return live.status();
    wanted = *live;
  }
  // Otherwise back to the queue as if this lease had never been granted: the attempt is not counted.
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkReleased(t, kind, id, wanted, now));
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + (wanted ? ".released" : ".cancelled"),
                                   Subject(kind, id), {{"reason", reason}, {"attempts", job.attempts - 1}}));
  return wanted ? JobState::kQueued : JobState::kCancelled;
}

// The job leased together with the completion of `token` (leases.next_token), put back in the
// queue as if never leased (attempt uncounted) when it is still running under that grant.
Status TakeBackUnreceivedGrant(Transaction& t, const std::string& token, double now) {
  Result<std::optional<jobs::GrantRef>> grant = jobs::OpenNextGrant(t, token);
  if (!grant.ok()) return grant.status();
  if (!*grant) return Status::Ok();
  // A run whose sweeps were all cancelled since is cancelled, not queued again (as a released or
  // expired one is).
  bool wanted = true;
  if ((*grant)->kind == api::JobKind::kRun) {
    Result<bool> live = jobs::RunWanted(t, (*grant)->job_id);
    if (!live.ok()) return live.status();
    wanted = *live;
  }
  Result<bool> taken = jobs::TakeBackGrant(t, **grant, wanted, now);
  if (!taken.ok()) return taken.status();
  if (!*taken) return Status::Ok();  // it has moved on (expired, heartbeated, ...)
  const std::string message = "leased with a completion whose reply was lost; the worker asked again";
  return t.Event(now, std::string(Noun((*grant)->kind)) + (wanted ? ".requeued" : ".cancelled"),
                 Subject((*grant)->kind, (*grant)->job_id),
                 {{"kind", "unreceived"}, {"message", wanted ? message : message + "; its sweeps were cancelled"}});
}

// Running jobs whose lease is lost -- expired before `now` or, when `slurm_job` is set, granted to
// that Slurm job (which Slurm no longer runs) -- go back to the queue, their attempt counted, or
// fail at max_attempts. Returns how many.
// A Slurm job's leases are only reclaimed when they were granted at or before `asked_at` (when
// Slurm was asked) and their worker has been silent for at least `silent_s` (no heartbeat since
// now - silent_s): a worker that still heartbeats is alive, whatever squeue said.
// `left_by_stopped_daemon`: whether an expired lease is one a local worker of an earlier daemon held
// and never heartbeated since this daemon started (LeaseQueue::ExtendLeasesAfterRestart): it is handed
// back free (HandBackIn), the attempt uncounted -- the daemon stopping was not the job's fault.
Result<int64_t> ReclaimIn(Transaction& t, double now, int default_max, const std::string& slurm_job = "",
                          double asked_at = 0, double silent_s = 0, double ttl_s = 0,
                          const std::function<bool(const std::string& token)>& left_by_stopped_daemon = {}) {
  int64_t expired = 0, handed_back = 0;
  for (api::JobKind kind : {api::JobKind::kBed, api::JobKind::kRun}) {
    Result<std::vector<jobs::LostLease>> rows =
        slurm_job.empty() ? jobs::ExpiredLeases(t, kind, now, default_max)
                          : jobs::SlurmJobLeases(t, kind, slurm_job, now - silent_s + ttl_s, asked_at, default_max);
    if (!rows.ok()) return rows.status();
    for (const jobs::LostLease& e : *rows) {
      if (slurm_job.empty() && left_by_stopped_daemon && left_by_stopped_daemon(e.job.lease_token)) {
        Result<JobState> state =
            HandBackIn(t, kind, e.id, e.job, e.job.lease_token,
                       "its worker " + e.worker + " was a local worker of the daemon that stopped, and did not come back",
                       now);
        if (!state.ok()) return state.status();
        ++handed_back;
        continue;
      }
      Result<JobState> state =
          slurm_job.empty()
              ? RetryOrFail(t, kind, e.id, e.job, "lease_expired",
                            "worker " + e.worker + " stopped heartbeating (lease expired)", /*retryable=*/true, now)
              : RetryOrFail(t, kind, e.id, e.job, "pilot_gone",
                            "Slurm no longer runs job " + slurm_job + " of worker " + e.worker +
                                " (its leases were reclaimed before they expired)",
                            /*retryable=*/true, now);
      if (!state.ok()) return state.status();
      SANDSWIM_RETURN_IF_ERROR(jobs::MarkLeaseExpired(t, e.job.lease_token, now));
      ++expired;
    }
  }
  if (expired > 0) SANDSWIM_RETURN_IF_ERROR(t.Count(slurm_job.empty() ? "expirations" : "pilots_gone", expired));
  return expired + handed_back;
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
  return store_->db().WriteResult<Out>([&](Transaction& t) { return LeaseIn(t, request, clock_->Now()); });
}

Result<std::optional<api::LeaseGrant>> LeaseQueue::LeaseIn(Transaction& t, const api::LeaseRequest& request,
                                                           double now) {
  using Out = std::optional<api::LeaseGrant>;
  SANDSWIM_RETURN_IF_ERROR(CheckLeaseRequest(request, "slurm_job"));
  Result<int64_t> expired =
      ReclaimIn(t, now, options_.max_attempts, "", 0, 0, 0, [this](const std::string& token) { return LeftByStoppedDaemon(token); });
  if (!expired.ok()) return expired.status();

  api::LeaseGrant g;
  g.ttl_s = options_.ttl_s;
  g.wall_budget_s = options_.wall_budget_s;
  Result<bool> found = NextBed(t, g);
  if (found.ok() && !*found) found = NextRun(t, g, now);
  if (!found.ok()) return found.status();
  if (!*found) return Out();  // committed with the group when it expired leases or failed decks
  if (!(g.wall_budget_s > 0)) {  // none set by the operator: the cost model's (server/store/cost_model.h)
    const bool bed = g.kind == api::JobKind::kBed;
    Result<double> budget = WallBudget(t, bed, bed ? g.id : g.bed->id, g.steps);
    if (!budget.ok()) return budget.status();
    g.wall_budget_s = std::ceil(*budget);
  }
  Result<std::string> token = NewToken();
  if (!token.ok()) return token.status();
  g.token = *token;
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkLeased(t, g.kind, g.id, g.token, now + options_.ttl_s, request.worker, now));
  // With this job running, is anything else leasable now? When nothing is, the worker's idle
  // slots may lend this job their cores (core/api.h LeaseGrant::queue_dry). A run whose deck no
  // longer renders counts as leasable here (it fails when leased): the hint errs towards one rank.
  Result<std::optional<jobs::QueuedBed>> other_bed = jobs::NextQueuedBed(t);
  if (!other_bed.ok()) return other_bed.status();
  if (!*other_bed) {
    Result<std::optional<jobs::QueuedRun>> other_run = jobs::NextQueuedRun(t);
    if (!other_run.ok()) return other_run.status();
    g.queue_dry = !*other_run;
  }
  SANDSWIM_RETURN_IF_ERROR(jobs::InsertLease(t, g.token, g.kind, g.id, g.attempt, request, now));
  // Who pays for this attempt is decided now, once, from who holds the job now (issue 31).
  SANDSWIM_RETURN_IF_ERROR(rounds::DecideLeasePayer(t, g.token, g.kind, g.id));
  SANDSWIM_RETURN_IF_ERROR(t.Count("leases_granted"));
  SANDSWIM_RETURN_IF_ERROR(
      t.Event(now, std::string(Noun(g.kind)) + ".leased", Subject(g.kind, g.id),
              {{"worker", request.worker},
               {"host", request.host},
               {"ranks", request.ranks},
               {"attempt", g.attempt},
               {"queue_dry", g.queue_dry}}));
  return Out(std::move(g));
}

Result<bool> LeaseQueue::NextBed(Transaction& t, api::LeaseGrant& g) {
  // Beds first: a bed some queued run is waiting for.
  Result<std::optional<jobs::QueuedBed>> bed = jobs::NextQueuedBed(t);
  if (!bed.ok()) return bed.status();
  if (!*bed) return false;
  g.kind = api::JobKind::kBed;
  g.id = (*bed)->id;
  g.key = (*bed)->key;
  g.deck = (*bed)->deck;
  g.attempt = (*bed)->attempts + 1;
  // The bed's own step (its materials' TimeStep, core/materials.h), as its deck states it: a bed of
  // stiffer or smaller grains steps shorter than Table 1's 1e-5 s. Every bed deck states one; were
  // one not to, Table 1's (what every bed deck stated before materials could be set).
  const Result<double> dt = ReadTimeStep((*bed)->deck);
  g.dt_s = dt.ok() ? *dt : kMaterials.dt;
  g.key_engine = (*bed)->engine_version.value_or("");
  return true;
}

// The deck of a queued run, rendered from its point and its bed's scale and checked against the
// run's key, with the drive facts it states; else why it cannot be made (the run then fails with
// "deck_error").
Result<LeaseQueue::RunDeck> LeaseQueue::MakeRunDeck(const jobs::QueuedRun& run) {
  if (run.stored_deck) {  // runs submitted before migration 3: the stored deck says it
    Result<DriveInfo> drive = ReadDriveInfo(*run.stored_deck);
    if (!drive.ok()) return Status::FailedPrecondition("deck", "its stored deck: " + drive.status().reason());
    return RunDeck{*run.stored_deck, *drive, std::nullopt, {}};  // such runs have no target or snapshots
  }
  Result<Point> point = StoredPoint(run.mode, run.axis, run.A, run.f, run.Omega, run.omega, run.duration_s,
                                    run.materials, run.dt_s);
  const Scale* scale = FindScale(run.scale);
  Result<std::optional<PrecisionTarget>> precision = StoredPrecision(run.precision);
  Result<SnapshotFractions> snapshots = StoredSnapshotFractions(run.snapshots);
  if (!point.ok() || scale == nullptr || !precision.ok() || !snapshots.ok()) {
    return Status::FailedPrecondition("deck",
                                      "its stored point, precision target, snapshots or scale no longer parses");
  }
  const Point& p = *point;
  RunDeck out;
  out.precision = *precision;
  out.snapshots = *snapshots;
  try {
    out.deck = RenderDriveDeck(p, *scale, out.precision, out.snapshots);
  } catch (const std::exception& e) {
    return Status::FailedPrecondition("deck", std::string("its deck no longer renders: ") + e.what());
  }
  if (run.engine_version && RunKey(out.deck, run.bed_key, *run.engine_version) != run.key) {
    return Status::FailedPrecondition("deck",
                                      "its deck no longer renders to its key (the deck templates changed since it "
                                      "was submitted); submit its sweep again");
  }
  out.drive = DriveFacts(p, *scale);
  return out;
}

Result<bool> LeaseQueue::NextRun(Transaction& t, api::LeaseGrant& g, double now) {
  // The oldest queued run whose bed is done. A run whose deck cannot be made (the templates
  // changed since it was submitted) fails with "deck_error" and the next run is tried.
  while (true) {
    Result<std::optional<jobs::QueuedRun>> run = jobs::NextQueuedRun(t);
    if (!run.ok()) return run.status();
    if (!*run) return false;
    const jobs::QueuedRun& r = **run;
    Result<RunDeck> deck = MakeRunDeck(r);
    if (deck.ok()) {
      g.kind = api::JobKind::kRun;
      g.id = r.id;
      g.key = r.key;
      g.attempt = r.attempts + 1;
      g.duration_s = r.run_duration_s;
      g.steps = r.steps;
      g.bed = api::BedRef{r.bed_id, r.bed_sha256, "/api/v1/beds/" + std::to_string(r.bed_id) + "/restart", r.bed_key};
      // A stored deck (before migration 3) was not rendered here: its key is not checked against it.
      if (!r.stored_deck) g.key_engine = r.engine_version.value_or("");
      g.deck = std::move(deck->deck);
      g.dt_s = deck->drive.dt;
      g.f_hz = deck->drive.f;
      g.A_m = deck->drive.A;
      g.z_floor_m = deck->drive.z_floor;
      g.so_radius_m = deck->drive.so_radius;
      g.precision = deck->precision;
      g.snapshots = deck->snapshots;
      return true;
    }
    const std::string why = deck.status().reason();
    SANDSWIM_RETURN_IF_ERROR(jobs::FailRunDeck(t, r.id, why, now));
    SANDSWIM_RETURN_IF_ERROR(
        t.Event(now, "run.failed", Subject(api::JobKind::kRun, r.id), {{"kind", "deck_error"}, {"message", why}}));
  }
}

Result<api::HeartbeatReply> LeaseQueue::Heartbeat(const std::string& token, const api::Heartbeat& beat) {
  std::optional<int64_t> run_id;  // set once the beat is recorded
  Result<api::HeartbeatReply> reply = store_->db().WriteResult<api::HeartbeatReply>([&](Transaction& t) -> Result<api::HeartbeatReply> {
    run_id.reset();
    const double now = clock_->Now();
    Result<LeaseRow> lease = jobs::FindLease(t, token);
    if (!lease.ok()) return lease.status();
    Result<JobRow> job = jobs::LoadJob(t, lease->kind, lease->job_id, options_.max_attempts);
    if (!job.ok()) return job.status();
    SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, lease->kind));

    api::HeartbeatReply reply;
    reply.ttl_s = options_.ttl_s;
    if (lease->kind == api::JobKind::kRun) {
      SANDSWIM_RETURN_IF_ERROR(jobs::RecordProgress(t, lease->job_id, now + options_.ttl_s, beat, now));
      run_id = lease->job_id;
      // Stop only when no live sweep wants the run any more (it may be shared).
      Result<bool> wanted = jobs::RunWanted(t, lease->job_id);
      if (!wanted.ok()) return wanted.status();
      reply.cancel = !*wanted;
    } else {
      SANDSWIM_RETURN_IF_ERROR(jobs::ExtendBedLease(t, lease->job_id, now + options_.ttl_s, now));
    }
    return reply;
  });
  if (reply.ok() && run_id && progress_observer_) progress_observer_(*run_id, beat);
  if (reply.ok()) {
    // Its worker is alive after all (a local worker that outlived its daemon): from now on its
    // lease expires as any other's.
    std::lock_guard<std::mutex> lock(left_mu_);
    left_by_stopped_daemon_.erase(token);
  }
  return reply;
}

Result<api::CompletionReply> LeaseQueue::Complete(const std::string& token, const api::Completion& c) {
  // Snapshot files are read (if at all) before the write transaction, which other writers wait for.
  Result<std::map<int, HashedFile>> snapshots = HashListedSnapshots(token, c);
  if (!snapshots.ok()) return snapshots.status();
  return store_->db().WriteResult<api::CompletionReply>([&](Transaction& t) -> Result<api::CompletionReply> {
    const double now = clock_->Now();
    if (c.next) SANDSWIM_RETURN_IF_ERROR(CheckLeaseRequest(*c.next, "next.slurm_job"));
    Result<api::CompletionReply> reply = CompleteIn(t, token, c, now, *snapshots);
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
    if (*next) SANDSWIM_RETURN_IF_ERROR(jobs::SetNextToken(t, token, (*next)->token));
    reply->next = std::move(*next);
    return reply;
  });
}

Result<std::map<int, LeaseQueue::HashedFile>> LeaseQueue::HashListedSnapshots(const std::string& token,
                                                                               const api::Completion& c) {
  std::map<int, HashedFile> out;
  if (!c.ok || c.snapshots.empty() || options_.data_dir.empty()) return out;
  int64_t run_id = 0;
  {
    Result<Transaction> t = store_->db().BeginRead();
    if (!t.ok()) return t.status();
    Result<LeaseRow> lease = jobs::FindLease(*t, token);
    if (!lease.ok() || lease->kind != api::JobKind::kRun) return out;  // CompleteIn says why
    run_id = lease->job_id;
  }
  const DataDir data(options_.data_dir);
  for (const api::Snapshot& snap : c.snapshots) {
    const std::string path = data.Snapshot(run_id, snap.idx);
    Result<FileIdentity> now = IdentifyFile(path);
    if (!now.ok()) continue;
    {
      std::lock_guard<std::mutex> lock(written_mu_);
      auto it = written_snapshots_.find(path);
      if (it != written_snapshots_.end() && it->second.identity == *now) {
        out[snap.idx] = it->second;
        continue;
      }
    }
    Result<std::string> sha = Sha256OfFile(path);  // a file written before this daemon started
    if (!sha.ok()) continue;
    out[snap.idx] = HashedFile{*sha, *now};
  }
  return out;
}

Result<api::CompletionReply> LeaseQueue::CompleteIn(Transaction& t, const std::string& token, const api::Completion& c,
                                                    double now, const std::map<int, HashedFile>& snapshots) {
  Result<LeaseRow> lease = jobs::FindLease(t, token);
  if (!lease.ok()) return lease.status();
  if (lease->completed) {
    SANDSWIM_RETURN_IF_ERROR(t.Count("duplicates"));
    return api::CompletionReply{"duplicate"};
  }
  const api::JobKind kind = lease->kind;
  const int64_t id = lease->job_id;
  Result<JobRow> job = jobs::LoadJob(t, kind, id, options_.max_attempts);
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

  Result<JobState> state =
      c.ok ? (kind == api::JobKind::kRun ? CompleteRun(t, id, c, now, snapshots) : CompleteBed(t, id, c, now))
           : CompleteFailure(t, kind, id, *job, *c.failure, now);
  if (!state.ok()) return state.status();
  if (kind == api::JobKind::kRun && !c.log_tail.empty()) {
    SANDSWIM_RETURN_IF_ERROR(jobs::PutLogTail(t, id, c.log_tail));
  }
  if (*state == JobState::kDone) {
    SANDSWIM_RETURN_IF_ERROR(t.Event(now, std::string(Noun(kind)) + ".done", Subject(kind, id),
                                     {{"host", c.execution.host},
                                      {"ranks", c.execution.ranks},
                                      {"wall_s", c.execution.wall_s}}));
  }
  SANDSWIM_RETURN_IF_ERROR(jobs::CloseLease(t, token, now, ToString(*state)));
  SANDSWIM_RETURN_IF_ERROR(t.Count("completions"));
  return api::CompletionReply{ToString(*state)};
}

Result<JobState> LeaseQueue::CompleteRun(Transaction& t, int64_t id, const api::Completion& c, double now,
                                         const std::map<int, HashedFile>& snapshots) {
  const api::RunResult& r = *c.result;
  SANDSWIM_RETURN_IF_ERROR(jobs::PutResult(t, id, r, c.execution, now));
  if (c.trajectory) SANDSWIM_RETURN_IF_ERROR(jobs::PutTrajectory(t, id, *c.trajectory));
  std::vector<int> kept;
  for (size_t i = 0; i < c.snapshots.size(); ++i) {
    const api::Snapshot& snap = c.snapshots[i];
    const std::string field = "snapshots[" + std::to_string(i) + "]";
    if (options_.data_dir.empty()) return Status::FailedPrecondition(field, "this daemon keeps no snapshots");
    auto hashed = snapshots.find(snap.idx);
    if (hashed == snapshots.end())
      return Status::FailedPrecondition(field, "upload snapshot " + std::to_string(snap.idx) + " first");
    // The file hashed is still the one there (a stat, not a read), else a newer upload replaced it.
    Result<FileIdentity> there = IdentifyFile(DataDir(options_.data_dir).Snapshot(id, snap.idx));
    if (!there.ok() || *there != hashed->second.identity) {
      return Status::Unavailable("snapshot " + std::to_string(snap.idx) +
                                 "'s file was replaced while this completion was read; send the completion again");
    }
    const std::string& sha = hashed->second.sha256;
    if (sha != Lower(snap.sha256))
      return Status::FailedPrecondition(field + ".sha256", "differs from the uploaded snapshot's checksum " + sha);
    SANDSWIM_RETURN_IF_ERROR(jobs::PutSnapshot(t, id, snap, sha));
    kept.push_back(snap.idx);
  }
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkRunDone(t, id, r.sim_time_s, r.steps, now));
  if (!options_.data_dir.empty()) {
    RemoveSnapshotFiles(options_.data_dir, id, kept);
    ForgetWrittenSnapshots(id);
  }
  return JobState::kDone;
}

Result<JobState> LeaseQueue::CompleteBed(Transaction& t, int64_t id, const api::Completion& c, double now) {
  const api::BedResult& b = *c.bed_result;
  Result<jobs::BedRow> bed = jobs::LoadBed(t, id);
  if (!bed.ok()) return bed.status();
  if (!bed->path) {
    return Status::FailedPrecondition("bed_result", "upload the bed's restart file before completing it");
  }
  if (!b.sha256.empty() && Lower(b.sha256) != bed->sha256) {
    return Status::FailedPrecondition("bed_result.sha256", "differs from the uploaded restart file's checksum");
  }
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkBedDone(t, id, b, c.execution.ranks, now));
  return JobState::kDone;
}

Result<JobState> LeaseQueue::CompleteFailure(Transaction& t, api::JobKind kind, int64_t id, const JobRow& job,
                                             const api::Failure& f, double now) {
  if (f.kind != "cancelled") {
    // A failure that repeats by nature is not tried again (core/api.h AttemptsFor).
    return RetryOrFail(t, kind, id, job, f.kind, f.message,
                       /*retryable=*/job.attempts < api::AttemptsFor(f.kind, job.max_attempts), now);
  }
  // A bed is never cancelled (other sweeps may want it): it goes back to the queue.
  const JobState to = kind == api::JobKind::kRun ? JobState::kCancelled : JobState::kQueued;
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkCancelledOrQueued(t, kind, id, to, f.kind, f.message, now));
  SANDSWIM_RETURN_IF_ERROR(
      t.Event(now, std::string(Noun(kind)) + "." + ToString(to), Subject(kind, id), {{"message", f.message}}));
  return to;
}

Result<api::CompletionReply> LeaseQueue::Release(const std::string& token, const std::string& reason) {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->db().Begin();
  if (!begun.ok()) return begun.status();
  Transaction& t = *begun;
  Result<LeaseRow> lease = jobs::FindLease(t, token);
  if (!lease.ok()) return lease.status();
  if (lease->completed) return api::CompletionReply{"duplicate"};
  const api::JobKind kind = lease->kind;
  const int64_t id = lease->job_id;
  Result<JobRow> job = jobs::LoadJob(t, kind, id, options_.max_attempts);
  if (!job.ok()) return job.status();
  SANDSWIM_RETURN_IF_ERROR(RequireCurrent(*job, token, kind));
  Result<JobState> state = HandBackIn(t, kind, id, *job, token, reason, now);
  if (!state.ok()) return state.status();
  SANDSWIM_RETURN_IF_ERROR(t.Commit());
  return api::CompletionReply{ToString(*state)};
}

Result<std::vector<std::string>> LeaseQueue::RunningSlurmJobs() {
  Result<Transaction> t = store_->db().BeginRead();
  if (!t.ok()) return t.status();
  return jobs::SlurmJobsWithOpenLeases(*t);
}

Result<int64_t> LeaseQueue::ReclaimSlurmJob(const std::string& slurm_job, double asked_at) {
  if (slurm_job.empty()) return Status::InvalidArgument("slurm_job", "names no Slurm job");
  return store_->db().WriteResult<int64_t>([&](Transaction& t) {
    return ReclaimIn(t, clock_->Now(), options_.max_attempts, slurm_job, asked_at, options_.ttl_s / 2, options_.ttl_s);
  });
}

Result<int64_t> LeaseQueue::ExpireLeases() {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->db().Begin();
  if (!begun.ok()) return begun.status();
  Result<int64_t> n = ReclaimIn(*begun, now, options_.max_attempts, "", 0, 0, 0,
                                [this](const std::string& token) { return LeftByStoppedDaemon(token); });
  if (!n.ok()) return n.status();
  SANDSWIM_RETURN_IF_ERROR(begun->Commit());
  return n;
}

Result<int64_t> LeaseQueue::ExtendLeasesAfterRestart(const std::function<bool(const std::string& worker)>& local_of_earlier_daemon) {
  const double until = clock_->Now() + options_.ttl_s;
  Result<Transaction> begun = store_->db().Begin();
  if (!begun.ok()) return begun.status();
  Result<int64_t> extended = jobs::ExtendRunningLeases(*begun, until);
  if (!extended.ok()) return extended.status();
  std::set<std::string> left;
  if (local_of_earlier_daemon) {
    for (api::JobKind kind : {api::JobKind::kBed, api::JobKind::kRun}) {
      Result<std::vector<jobs::LostLease>> running = jobs::RunningLeases(*begun, kind, options_.max_attempts);
      if (!running.ok()) return running.status();
      for (const jobs::LostLease& e : *running) {
        if (local_of_earlier_daemon(e.worker)) left.insert(e.job.lease_token);
      }
    }
  }
  SANDSWIM_RETURN_IF_ERROR(begun->Commit());
  std::lock_guard<std::mutex> lock(left_mu_);
  left_by_stopped_daemon_ = std::move(left);
  return extended;
}

size_t LeaseQueue::LeasesLeftByStoppedDaemon() {
  std::lock_guard<std::mutex> lock(left_mu_);
  return left_by_stopped_daemon_.size();
}

bool LeaseQueue::LeftByStoppedDaemon(const std::string& token) {
  std::lock_guard<std::mutex> lock(left_mu_);
  return left_by_stopped_daemon_.count(token) > 0;
}

Result<int64_t> LeaseQueue::HandBackLeasesOf(const std::string& worker, const std::string& reason) {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->db().Begin();
  if (!begun.ok()) return begun.status();
  int64_t handed = 0;
  for (api::JobKind kind : {api::JobKind::kBed, api::JobKind::kRun}) {
    Result<std::vector<jobs::LostLease>> running = jobs::RunningLeases(*begun, kind, options_.max_attempts);
    if (!running.ok()) return running.status();
    for (const jobs::LostLease& e : *running) {
      if (e.worker != worker) continue;
      Result<JobState> state = HandBackIn(*begun, kind, e.id, e.job, e.job.lease_token, reason, now);
      if (!state.ok()) return state.status();
      ++handed;
    }
  }
  SANDSWIM_RETURN_IF_ERROR(begun->Commit());
  return handed;
}

Result<CancelSummary> LeaseQueue::Cancel(int64_t sweep_id) {
  const double now = clock_->Now();
  Result<Transaction> begun = store_->db().Begin();
  if (!begun.ok()) return begun.status();
  Transaction& t = *begun;
  SANDSWIM_RETURN_IF_ERROR(jobs::MarkSweepCancelled(t, sweep_id, now));
  Result<std::pair<int64_t, int64_t>> runs = jobs::CancelOrphanedRuns(t, sweep_id, now);
  if (!runs.ok()) return runs.status();
  CancelSummary out;
  out.cancelled = runs->first;
  out.stopping = runs->second;
  SANDSWIM_RETURN_IF_ERROR(t.Event(now, "sweep.cancelled", "sweep/" + std::to_string(sweep_id),
                                   {{"cancelled", out.cancelled}, {"stopping", out.stopping}}));
  SANDSWIM_RETURN_IF_ERROR(t.Commit());
  return out;
}

Status LeaseQueue::PutBedRestart(const std::string& token, std::string_view bytes, const std::string& sha256,
                                 const std::string& data_dir, const std::string& upload_file) {
  const std::string expected = Lower(sha256);
  const std::string actual = Sha256Hex(bytes);
  if (expected != actual) {
    return Status::InvalidArgument(
        "X-Sha256", "the body's SHA-256 is " + actual + ", not " + (expected.empty() ? "(none given)" : expected));
  }
  // Check the lease, write the file without holding the store, then record it under a second
  // check: the token may have been lost while the bytes were being written.
  auto check = [&](Transaction& t) -> Result<std::pair<int64_t, std::string>> {
    Result<LeaseRow> lease = CurrentUploadLease(t, token, api::JobKind::kBed, options_.max_attempts);
    if (!lease.ok()) return lease.status();
    Result<jobs::BedRow> bed = jobs::LoadBed(t, lease->job_id);
    if (!bed.ok()) return bed.status();
    return std::make_pair(lease->job_id, bed->key);
  };
  std::string key;
  {
    Result<Transaction> t = store_->db().BeginRead();
    if (!t.ok()) return t.status();
    auto found = check(*t);
    if (!found.ok()) return found.status();
    key = found->second;
  }
  const std::string path = DataDir(data_dir).BedRestart(key);
  SANDSWIM_RETURN_IF_ERROR(PlaceFile(path, bytes, upload_file));
  const double now = clock_->Now();
  Result<Transaction> t = store_->db().Begin();
  if (!t.ok()) return t.status();
  auto found = check(*t);
  if (!found.ok()) return found.status();
  SANDSWIM_RETURN_IF_ERROR(jobs::RecordBedUpload(*t, found->first, path, actual));
  SANDSWIM_RETURN_IF_ERROR(t->Event(now, "bed.uploaded", "bed/" + std::to_string(found->first),
                                    {{"sha256", actual}, {"bytes", bytes.size()}}));
  return t->Commit();
}

Status LeaseQueue::CheckUploadLease(const std::string& token, api::JobKind kind, std::optional<int64_t> job_id) {
  Result<Transaction> t = store_->db().BeginRead();
  if (!t.ok()) return t.status();
  Result<LeaseRow> lease = CurrentUploadLease(*t, token, kind, options_.max_attempts);
  if (!lease.ok()) return lease.status();
  if (job_id && lease->job_id != *job_id) {
    return Status::Conflict("this lease is for bed " + std::to_string(lease->job_id) + ", not bed " +
                            std::to_string(*job_id) + " (the path's id)");
  }
  return Status::Ok();
}

Status LeaseQueue::PutRunSnapshot(const std::string& token, int idx, std::string_view bytes,
                                  const std::string& sha256, const std::string& upload_file) {
  if (options_.data_dir.empty()) return Status::FailedPrecondition("n", "this daemon keeps no snapshots");
  const std::string actual = Sha256Hex(bytes);
  if (Lower(sha256) != actual) {
    return Status::InvalidArgument(
        "X-Sha256", "the body's SHA-256 is " + actual + ", not " + (sha256.empty() ? "(none given)" : sha256));
  }
  Result<BedSnapshot> snapshot = ParseBedSnapshot(bytes);
  if (!snapshot.ok()) return Status::InvalidArgument("body", "not a full-bed snapshot: " + snapshot.status().reason());
  int64_t run_id = 0;
  {
    Result<Transaction> t = store_->db().BeginRead();
    if (!t.ok()) return t.status();
    Result<LeaseRow> lease = CurrentUploadLease(*t, token, api::JobKind::kRun, options_.max_attempts);
    if (!lease.ok()) return lease.status();
    Result<std::optional<std::string>> stored = jobs::SnapshotsAsked(*t, lease->job_id);
    if (!stored.ok()) return stored.status();
    Result<SnapshotFractions> asked = StoredSnapshotFractions(*stored);
    if (!asked.ok()) return asked.status();
    if (idx < 0 || static_cast<size_t>(idx) >= asked->size())
      return Status::InvalidArgument("n", "run " + std::to_string(lease->job_id) + " asked for " +
                                              std::to_string(asked->size()) + " snapshots, numbered from 0");
    run_id = lease->job_id;
  }
  // A lease lost while the bytes are written leaves a file its completion never lists: the next
  // attempt overwrites it, and an unlisted one goes when the run completes or the daemon starts.
  const std::string path = DataDir(options_.data_dir).Snapshot(run_id, idx);
  SANDSWIM_RETURN_IF_ERROR(PlaceFile(path, bytes, upload_file));
  Result<FileIdentity> written = IdentifyFile(path);
  if (written.ok()) {
    std::lock_guard<std::mutex> lock(written_mu_);
    written_snapshots_[path] = HashedFile{actual, *written};
  }
  return Status::Ok();
}

void LeaseQueue::ForgetWrittenSnapshots(int64_t run_id) {
  const std::string dir = DataDir(options_.data_dir).RunSnapshots(run_id) + "/";
  std::lock_guard<std::mutex> lock(written_mu_);
  for (auto it = written_snapshots_.lower_bound(dir); it != written_snapshots_.end() && it->first.rfind(dir, 0) == 0;)
    it = written_snapshots_.erase(it);
}

Result<int64_t> LeaseQueue::RemoveUnrecordedSnapshots() {
  namespace fs = std::filesystem;
  if (options_.data_dir.empty()) return int64_t{0};
  const fs::path root = DataDir(options_.data_dir).Snapshots();
  std::error_code ec;
  if (!fs::is_directory(root, ec)) return int64_t{0};
  std::map<int64_t, std::vector<int>> recorded;
  std::set<int64_t> running;  // their workers may still complete them, listing what they uploaded
  {
    Result<Transaction> t = store_->db().BeginRead();
    if (!t.ok()) return t.status();
    Result<std::map<int64_t, std::vector<int>>> snapshots = jobs::RecordedSnapshots(*t);
    if (!snapshots.ok()) return snapshots.status();
    recorded = std::move(snapshots).value();
    Result<std::set<int64_t>> live = jobs::RunningRunIds(*t);
    if (!live.ok()) return live.status();
    running = std::move(live).value();
  }
  int64_t removed = 0;
  for (const auto& entry : fs::directory_iterator(root, ec)) {
    const std::string name = entry.path().filename().string();
    const std::string digits = name.rfind("run-", 0) == 0 ? name.substr(4) : "";
    if (digits.empty() || digits.size() > 18 || digits.find_first_not_of("0123456789") != std::string::npos) continue;
    const int64_t run_id = std::stoll(digits);
    if (running.count(run_id)) continue;
    auto it = recorded.find(run_id);
    removed += RemoveSnapshotFiles(options_.data_dir, run_id, it == recorded.end() ? std::vector<int>{} : it->second);
  }
  return removed;
}

Result<BedFile> LeaseQueue::GetBedRestart(int64_t bed_id) {
  Result<Transaction> t = store_->db().BeginRead();
  if (!t.ok()) return t.status();
  Result<jobs::BedRow> bed = jobs::LoadBed(*t, bed_id);
  if (!bed.ok()) return bed.status();
  if (bed->state != JobState::kDone || !bed->path) {
    return Status::FailedPrecondition("bed",
                                      "bed " + std::to_string(bed_id) + " is not prepared yet (" + ToString(bed->state) + ")");
  }
  return BedFile{bed_id, bed->key, *bed->path, bed->sha256};
}

}  // namespace sandswim
