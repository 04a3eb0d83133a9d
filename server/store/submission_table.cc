#include "server/store/submission_table.h"

#include <utility>

#include <nlohmann/json.hpp>

#include "core/deck.h"
#include "core/materials.h"
#include "core/point.h"
#include "core/precision.h"

namespace sandswim::submissions {

// ---- Submissions (idempotency) -------------------------------------------------------------------

Result<std::optional<StoredSubmission>> FindByIdempotencyKey(Transaction& t, const std::string& key) {
  Statement st = t.Prepare("SELECT fingerprint, response FROM submissions WHERE idempotency_key = ?");
  st.Bind(1, key);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<StoredSubmission>();
  return std::optional<StoredSubmission>(StoredSubmission{st.Text(0), st.Text(1)});
}

Result<std::optional<std::string>> ScheduledRunResponse(Transaction& t, const std::string& campaign,
                                                        double due_time) {
  Statement st = t.Prepare("SELECT id FROM campaign_runs WHERE campaign = ? AND due_time = ?");
  st.Bind(1, campaign).Bind(2, due_time);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<std::string>();
  const int64_t id = st.Int(0);
  Statement response = t.Prepare(
      "SELECT sub.response FROM sweeps s JOIN submissions sub ON sub.id = s.submission_id "
      "WHERE s.campaign_run_id = ? LIMIT 1");
  response.Bind(1, id);
  Result<bool> found = response.Step();
  if (!found.ok()) return found.status();
  if (!*found) return Status::Corruption("campaign run " + std::to_string(id) + " has no sweeps");
  return std::optional<std::string>(response.Text(0));
}

Result<int64_t> Insert(Transaction& t, const std::optional<std::string>& idempotency_key,
                       const std::string& fingerprint, double now) {
  Statement st = t.Prepare(
      "INSERT INTO submissions (idempotency_key, fingerprint, response, created_at) "
      "VALUES (?, ?, '{}', ?)");
  st.Bind(1, idempotency_key).Bind(2, fingerprint).Bind(3, now);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  return t.LastInsertId();
}

Status SetResponse(Transaction& t, int64_t submission_id, const std::string& response) {
  Statement st = t.Prepare("UPDATE submissions SET response = ? WHERE id = ?");
  st.Bind(1, response).Bind(2, submission_id);
  return st.Run();
}

// ---- Campaign runs and sweeps --------------------------------------------------------------------

Result<int64_t> InsertCampaignRun(Transaction& t, const NewCampaignRun& run, double now) {
  Statement st = t.Prepare(
      "INSERT INTO campaign_runs (campaign, scale, trigger, due_time, created_at, campaign_version, definition, "
      "definition_sha256) VALUES (?, ?, ?, ?, ?, ?, ?, ?)");
  st.Bind(1, run.campaign).Bind(2, run.scale).Bind(3, run.trigger);
  st.Bind(4, run.due_time).Bind(5, now).Bind(6, run.campaign_version);
  st.Bind(7, run.definition).Bind(8, run.definition_sha256);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  return t.LastInsertId();
}

Result<int64_t> InsertSweep(Transaction& t, const NewSweep& sweep, double now) {
  Statement st = t.Prepare(
      "INSERT INTO sweeps (name, scale, spec, campaign_run_id, submission_id, force, created_at)"
      " VALUES (?, ?, ?, ?, ?, ?, ?)");
  st.Bind(1, sweep.name).Bind(2, sweep.scale).Bind(3, sweep.spec);
  st.Bind(4, sweep.campaign_run_id).Bind(5, sweep.submission_id).Bind(6, sweep.force).Bind(7, now);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  return t.LastInsertId();
}

Status RecountSweeps(Transaction& t, const std::vector<int64_t>& sweep_ids) {
  Statement recount = t.Prepare(
      "UPDATE sweep_counts SET (queued, running, done, failed, cancelled) = ("
      "SELECT COALESCE(SUM(r.state = 'queued'), 0), COALESCE(SUM(r.state = 'running'), 0), "
      "COALESCE(SUM(r.state = 'done'), 0), COALESCE(SUM(r.state = 'failed'), 0), "
      "COALESCE(SUM(r.state = 'cancelled'), 0) "
      "FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id WHERE sr.sweep_id = ?1) "
      "WHERE sweep_id = ?1");
  for (int64_t id : sweep_ids) {
    recount.Reset();
    recount.Bind(1, id);
    SANDSWIM_RETURN_IF_ERROR(recount.Run());
  }
  return Status::Ok();
}

// ---- Beds ----------------------------------------------------------------------------------------

Status InsertBedIfNew(Transaction& t, const std::string& scale, const PlannedBed& bed,
                      const std::string& engine_version, double now) {
  Statement st = t.Prepare(
      "INSERT INTO beds (key, scale, deck, state, created_at, engine_version, replicate, seed_pour1, seed_pour2) "
      "VALUES (?, ?, ?, 'queued', ?, ?, ?, ?, ?) "
      "ON CONFLICT (key) DO UPDATE SET engine_version = excluded.engine_version "
      "WHERE engine_version IS NULL");
  st.Bind(1, bed.key).Bind(2, scale).Bind(3, bed.deck).Bind(4, now);
  st.Bind(5, engine_version).Bind(6, static_cast<int64_t>(bed.replicate));
  st.Bind(7, static_cast<int64_t>(bed.seeds.pour1)).Bind(8, static_cast<int64_t>(bed.seeds.pour2));
  return st.Run();
}

Result<BedByKey> FindBed(Transaction& t, const std::string& key) {
  Statement st = t.Prepare("SELECT id, state, last_error_kind, last_error FROM beds WHERE key = ?");
  st.Bind(1, key);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Internal("bed row vanished");
  Result<JobState> state = st.State(1);
  if (!state.ok()) return state.status();
  return BedByKey{st.Int(0), *state, st.Text(2), st.Text(3)};
}

Status RequeueFailedBed(Transaction& t, int64_t bed_id) {
  Statement st = t.Prepare(
      "UPDATE beds SET state = 'queued', attempts = 0, lease_token = NULL, "
      "lease_expires_at = NULL, last_error_kind = NULL, last_error = NULL WHERE id = ?");
  st.Bind(1, bed_id);
  return st.Run();
}

// ---- Runs ----------------------------------------------------------------------------------------

RunRows::RunRows(Transaction& t)
    : t_(t),
      insert_(t.Prepare("INSERT INTO runs (key, bed_id, mode, A, f, osc_omega, rot_omega, axis, duration_s, "
                        "run_duration_s, steps, state, created_at, queued_at, precision, snapshots, materials, dt_s) "
                        "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, 'queued', ?, ?, ?, ?, ?, ?) "
                        "ON CONFLICT (key) DO NOTHING")),
      find_(t.Prepare("SELECT id, state FROM runs WHERE key = ?")),
      member_(t.Prepare("INSERT INTO sweep_runs (sweep_id, run_id, position) VALUES (?, ?, ?) "
                        "ON CONFLICT DO NOTHING")) {}

Result<std::optional<int64_t>> RunRows::InsertIfNew(const PlannedRun& r, int64_t bed_id, double now) {
  insert_.Reset();
  insert_.Bind(1, r.key).Bind(2, bed_id).Bind(3, ModeName(r.point.mode)).Bind(4, r.point.A);
  insert_.Bind(5, r.point.f).Bind(6, r.point.Omega).Bind(7, r.point.omega);
  insert_.Bind(8, AxisName(r.point.axis)).Bind(9, r.point.duration_s);
  insert_.Bind(10, r.run_duration_s).Bind(11, static_cast<int64_t>(r.steps));
  insert_.Bind(12, now).Bind(13, now);
  if (r.precision) {
    insert_.Bind(14, PrecisionToJson(*r.precision).dump());
  } else {
    insert_.BindNull(14);
  }
  insert_.Bind(15, SnapshotFractionsText(r.snapshots));
  insert_.Bind(16, MaterialsText(r.point.materials));
  insert_.Bind(17, r.point.dt_s);
  SANDSWIM_RETURN_IF_ERROR(insert_.Run());
  if (t_.Changes() != 1) return std::optional<int64_t>();
  return std::optional<int64_t>(t_.LastInsertId());
}

Result<RunRows::Existing> RunRows::Find(const std::string& key) {
  find_.Reset();
  find_.Bind(1, key);
  Result<bool> row = find_.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Internal("run row vanished");
  Result<JobState> state = find_.State(1);
  if (!state.ok()) return state.status();
  Existing out{find_.Int(0), *state};
  find_.Reset();
  return out;
}

Status RunRows::AddToSweep(int64_t sweep_id, int64_t run_id, int64_t position) {
  member_.Reset();
  member_.Bind(1, sweep_id).Bind(2, run_id).Bind(3, position);
  return member_.Run();
}

Status RequeueRun(Transaction& t, int64_t run_id, double now) {
  Statement st = t.Prepare(
      "UPDATE runs SET state = 'queued', attempts = 0, lease_token = NULL, "
      "lease_expires_at = NULL, worker = NULL, sim_time_s = NULL, so_z = NULL, "
      "step = NULL, heartbeat_at = NULL, cancel_requested = 0, queued_at = ?, "
      "started_at = NULL, finished_at = NULL, last_error_kind = NULL, last_error = NULL "
      "WHERE id = ?");
  st.Bind(1, now).Bind(2, run_id);
  return st.Run();
}

Result<int64_t> CountQueuedOrRunning(Transaction& t) {
  Statement st = t.Prepare("SELECT COUNT(*) FROM runs WHERE state IN ('queued', 'running')");
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  return st.Int(0);
}

}  // namespace sandswim::submissions
