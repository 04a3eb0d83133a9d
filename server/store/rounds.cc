#include "server/store/rounds.h"

#include <utility>

#include "core/scale.h"
#include "server/store/cost_model.h"
#include "server/store/submission_table.h"

namespace sandswim::rounds {
namespace {

using nlohmann::json;

json ParseOr(const std::string& text, json fallback) {
  if (text.empty()) return fallback;
  json j = json::parse(text, nullptr, /*allow_exceptions=*/false);
  return j.is_discarded() ? fallback : j;
}

Verdict VerdictOf(const std::string& name) {
  if (name == "holds") return Verdict::kHolds;
  if (name == "differs") return Verdict::kDiffers;
  return Verdict::kInconclusive;
}

}  // namespace

json ActionToJson(const AdaptiveAction& a) {
  json runs = json::array();
  for (const RunOrder& o : a.runs) {
    json r{{"sweep", o.sweep},
           {"point", PointToJson(o.point)},
           {"replicate", o.replicate},
           {"max_duration_s", o.max_duration_s},
           {"replaces", o.replaces}};
    if (o.precision) r["precision"] = PrecisionToJson(*o.precision);
    runs.push_back(std::move(r));
  }
  return {{"kind", ActionKindName(a.kind)}, {"claim", a.claim},   {"reason", a.reason},
          {"core_h", a.core_h},             {"sim_s", a.sim_s},   {"gain", a.gain},
          {"draws", a.draws},               {"new_beds", a.new_beds}, {"runs", runs}};
}

json RoundsToJson(const std::vector<RoundRow>& rows, double budget_core_h) {
  json out = json::array();
  double spent = 0;
  for (const RoundRow& r : rows) {
    json actions = json::array();
    for (const json& a : r.actions) {
      actions.push_back({{"kind", a.value("kind", "")},
                         {"claim", a.value("claim", "")},
                         {"reason", a.value("reason", "")},
                         {"core_h", a.value("core_h", 0.0)},
                         {"runs", a.contains("runs") ? a["runs"].size() : 0}});
    }
    json j{{"round", r.round},
           {"planned_at", r.planned_at},
           {"finished_at", r.finished_at ? json(*r.finished_at) : json(nullptr)},
           {"core_h_planned", r.core_h_planned},
           {"core_h_spent", r.core_h_spent ? json(*r.core_h_spent) : json(nullptr)},
           {"budget_left_core_h", nullptr},
           {"actions", actions},
           {"claims_after", r.verdicts_after},
           {"stop_reason", r.stop_reason ? json(*r.stop_reason) : json(nullptr)},
           {"rates", r.run_s_per_unit && r.bed_s_per_unit
                         ? json{{"run_s_per_unit", *r.run_s_per_unit}, {"bed_s_per_unit", *r.bed_s_per_unit}}
                         : json(nullptr)}};
    if (r.core_h_spent) {
      spent += *r.core_h_spent;
      j["budget_left_core_h"] = budget_core_h - spent;
    }
    out.push_back(std::move(j));
  }
  return out;
}

Result<std::vector<RoundRow>> ListRounds(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare(
      "SELECT round, planned_at, finished_at, core_h_planned, core_h_spent, actions, verdicts_after, stop_reason, "
      "run_s_per_unit, bed_s_per_unit FROM campaign_rounds WHERE campaign_run_id = ? ORDER BY round");
  st.Bind(1, campaign_run_id);
  std::vector<RoundRow> out;
  for (;;) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    RoundRow r;
    r.campaign_run_id = campaign_run_id;
    r.round = static_cast<int>(st.Int(0));
    r.planned_at = st.Double(1);
    r.finished_at = st.OptDouble(2);
    r.core_h_planned = st.Double(3);
    r.core_h_spent = st.OptDouble(4);
    r.actions = ParseOr(st.Text(5), json::array());
    r.verdicts_after = ParseOr(st.Text(6), json());
    r.stop_reason = st.OptText(7);
    r.run_s_per_unit = st.OptDouble(8);
    r.bed_s_per_unit = st.OptDouble(9);
    out.push_back(std::move(r));
  }
  return out;
}

Result<std::vector<RoundRow>> ListRounds(Store& store, int64_t campaign_run_id) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return ListRounds(*t, campaign_run_id);
}

Result<std::map<std::string, FrozenVerdict>> FrozenVerdicts(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare(
      "SELECT claim, verdict, round, frozen_at, decided_by FROM campaign_run_verdicts WHERE campaign_run_id = ?");
  st.Bind(1, campaign_run_id);
  std::map<std::string, FrozenVerdict> out;
  for (;;) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out[st.Text(0)] = FrozenVerdict{VerdictOf(st.Text(1)), static_cast<int>(st.Int(2)), st.Double(3),
                                    ParseOr(st.OptText(4).value_or(""), json())};
  }
  return out;
}

Result<std::map<std::string, FrozenVerdict>> FrozenVerdicts(Store& store, int64_t campaign_run_id) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return FrozenVerdicts(*t, campaign_run_id);
}

Result<std::vector<int64_t>> OpenAdaptiveCampaignRuns(Store& store) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(
      "SELECT cr.id FROM campaign_runs cr WHERE json_valid(cr.definition) "
      "AND json_type(cr.definition, '$.adaptive') IS 'object' "
      "AND NOT EXISTS (SELECT 1 FROM campaign_rounds r WHERE r.campaign_run_id = cr.id AND r.stop_reason IS NOT NULL) "
      "ORDER BY cr.id");
  std::vector<int64_t> out;
  for (;;) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out.push_back(st.Int(0));
  }
  return out;
}

Result<AdaptiveCost> AdaptiveCostNow(Store& store, const std::string& scale, double now) {
  AdaptiveCost cost;
  cost.scale = FindScale(scale);
  if (cost.scale == nullptr) return Status::InvalidArgument("scale", "unknown scale \"" + scale + "\"");
  Result<CostModelView> model = ReadCostModel(store, now);
  if (!model.ok()) return model.status();
  cost.run_rate = model->run_rate;
  cost.bed_rate = model->bed_rate;
  return cost;
}

Status InsertRound(Transaction& t, const RoundRow& r) {
  Statement st = t.Prepare(
      "INSERT INTO campaign_rounds (campaign_run_id, round, planned_at, finished_at, core_h_planned, core_h_spent, "
      "actions, verdicts_after, stop_reason, run_s_per_unit, bed_s_per_unit) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) "
      "ON CONFLICT DO NOTHING");
  st.Bind(1, r.campaign_run_id).Bind(2, r.round).Bind(3, r.planned_at).Bind(4, r.finished_at);
  st.Bind(5, r.core_h_planned).Bind(6, r.core_h_spent).Bind(7, r.actions.dump());
  if (r.verdicts_after.is_null()) {
    st.BindNull(8);
  } else {
    st.Bind(8, r.verdicts_after.dump());
  }
  st.Bind(9, r.stop_reason).Bind(10, r.run_s_per_unit).Bind(11, r.bed_s_per_unit);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  if (t.Changes() != 1) {
    return Status(StatusCode::kConflict,
                  "round " + std::to_string(r.round) + " of campaign run " + std::to_string(r.campaign_run_id) +
                      " is stored already",
                  "round");
  }
  return t.Event(r.planned_at, "campaign_run.round_planned", "campaign_run/" + std::to_string(r.campaign_run_id),
                 {{"round", r.round}, {"core_h_planned", r.core_h_planned}});
}

Status FinishRound(Transaction& t, int64_t campaign_run_id, int round, double now, double core_h_spent,
                   const json& verdicts_after, const std::optional<std::string>& stop_reason) {
  Statement st = t.Prepare(
      "UPDATE campaign_rounds SET finished_at = ?, core_h_spent = ?, verdicts_after = ?, stop_reason = ? "
      "WHERE campaign_run_id = ? AND round = ? AND finished_at IS NULL");
  st.Bind(1, now).Bind(2, core_h_spent).Bind(3, verdicts_after.dump()).Bind(4, stop_reason);
  st.Bind(5, campaign_run_id).Bind(6, round);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  if (t.Changes() != 1) {
    return Status(StatusCode::kConflict,
                  "round " + std::to_string(round) + " of campaign run " + std::to_string(campaign_run_id) +
                      " is not stored or its look was taken already",
                  "round");
  }
  json detail{{"round", round}, {"core_h_spent", core_h_spent}};
  if (stop_reason) detail["stop_reason"] = *stop_reason;
  return t.Event(now, stop_reason ? "campaign_run.rounds_stopped" : "campaign_run.round_finished",
                 "campaign_run/" + std::to_string(campaign_run_id), detail);
}

Status FreezeVerdicts(Transaction& t, int64_t campaign_run_id, int round, double now,
                      const std::map<std::string, Verdict>& frozen,
                      const std::map<std::string, json>& decided_by) {
  Statement st = t.Prepare(
      "INSERT INTO campaign_run_verdicts (campaign_run_id, claim, verdict, round, frozen_at, decided_by) "
      "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT DO NOTHING");
  for (const auto& [claim, verdict] : frozen) {
    if (verdict == Verdict::kInconclusive) continue;
    st.Reset();
    st.Bind(1, campaign_run_id).Bind(2, claim).Bind(3, VerdictName(verdict)).Bind(4, round).Bind(5, now);
    auto it = decided_by.find(claim);
    if (it == decided_by.end() || it->second.is_null()) {
      st.BindNull(6);
    } else {
      st.Bind(6, it->second.dump());
    }
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  return Status::Ok();
}

namespace {

// What "its runs" means, for the ledger (MyRunsSql), the look's wait (BusyJobs) and the payer a
// grant decides (DecideLeasePayer); the one home of that definition. A campaign run holds the
// members of its sweeps and both runs of each replacement there (a replaced run, or a failed
// longer one, leaves its sweeps, not its ledger). Rows (cr_id, run_id) of that relation, each side
// restricted by an SQL condition on its column (`cr`: "= ?1", `run`: "IS NOT NULL", say), so that
// either way round it reads by index.
std::string HoldsSql(const std::string& cr, const std::string& run) {
  return "SELECT s.campaign_run_id AS cr_id, sr.run_id AS run_id FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
         "WHERE s.campaign_run_id " + cr + " AND sr.run_id " + run +
         " UNION SELECT campaign_run_id, old_run_id FROM campaign_run_replacements WHERE campaign_run_id " + cr +
         " AND old_run_id " + run +
         " UNION SELECT campaign_run_id, new_run_id FROM campaign_run_replacements WHERE campaign_run_id " + cr +
         " AND new_run_id " + run;
}

// The campaign run's runs, as ?1 names it: a WITH clause.
std::string MyRunsSql() { return "WITH mine(run_id) AS (SELECT run_id FROM (" + HoldsSql("= ?1", "IS NOT NULL") + ")) "; }

// An adaptive campaign run `cr` that has not stopped: its rounds carry no stop reason and none of
// its sweeps is cancelled (a cancel stops its rounds at the next look).
constexpr char kLiveAdaptive[] =
    "json_valid(cr.definition) AND json_type(cr.definition, '$.adaptive') IS 'object' "
    "AND NOT EXISTS (SELECT 1 FROM campaign_rounds x WHERE x.campaign_run_id = cr.id AND x.stop_reason IS NOT NULL) "
    "AND NOT EXISTS (SELECT 1 FROM sweeps xs WHERE xs.campaign_run_id = cr.id AND xs.cancelled_at IS NOT NULL)";

// The closed leases of the campaign run's (?1) runs and beds not charged yet, as
// ClosedAttempt's columns: leases granted after the last per-ending look (rows from before
// migration 18), and for each its payer: the one its grant decided (migration 19 on), else the
// earlier rule's (below).
constexpr char kOldLook[] =
    ", old_look(at) AS (SELECT COALESCE(MAX(charged_at), -1e300) FROM campaign_run_charges "
    "WHERE campaign_run_id = ?1 AND lease_token IS NULL) ";
constexpr char kClosedLease[] =
    "(l.closed_at IS NOT NULL OR l.completed_at IS NOT NULL OR l.outcome IS NOT NULL) "
    "AND NOT EXISTS (SELECT 1 FROM campaign_run_charges c WHERE c.campaign_run_id = ?1 AND c.lease_token = l.token) "
    "AND l.granted_at > (SELECT at FROM old_look) ";
// The payer of a lease granted before migration 19, as the ledger decided it then, at the look:
// an earlier adaptive campaign run, live when the lease was granted, that holds a run meeting
// `run_condition` (rr: the run; l: the lease) in its sweeps now; else this one (?1).
std::string PayerOf(const std::string& run_condition) {
  return "CASE WHEN l.payer_decided THEN l.payer_campaign_run_id ELSE COALESCE((SELECT MIN(cr.id) FROM campaign_runs cr JOIN sweeps s ON s.campaign_run_id = cr.id "
         "JOIN sweep_runs sr ON sr.sweep_id = s.id JOIN runs rr ON rr.id = sr.run_id WHERE " +
         run_condition +
         " AND cr.id < ?1 AND cr.created_at <= l.granted_at AND json_valid(cr.definition) "
         "AND json_type(cr.definition, '$.adaptive') IS 'object' AND NOT EXISTS (SELECT 1 FROM campaign_rounds x "
         "WHERE x.campaign_run_id = cr.id AND x.stop_reason IS NOT NULL AND x.finished_at <= l.granted_at)), ?1) END, "
         "l.payer_decided";
}

}  // namespace

Result<std::vector<ClosedAttempt>> UnchargedAttempts(Transaction& t, int64_t campaign_run_id) {
  std::vector<ClosedAttempt> out;
  auto read = [&](Statement& st, const std::string& kind) -> Status {
    st.Bind(1, campaign_run_id);
    for (;;) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) return Status::Ok();
      ClosedAttempt a;
      a.kind = kind;
      a.lease_token = st.Text(0);
      a.id = st.Int(1);
      a.granted_at = st.Double(2);
      a.ended_at = st.Double(3);
      a.outcome = st.Text(4);
      a.sim_time_s = st.OptDouble(5);
      a.run_duration_s = st.OptDouble(6).value_or(0);
      Result<Point> p = StoredPoint(st.Text(7), st.Text(8), st.Double(9), st.Double(10), st.Double(11),
                                    st.Double(12), st.Double(13), st.OptText(14), st.OptDouble(15));
      if (!p.ok()) return Status(p.status().code(), kind + " " + std::to_string(a.id) + ": " + p.status().reason());
      a.point = *p;
      a.payer = st.OptInt(16);
      a.payer_decided = st.Int(17) != 0;
      out.push_back(std::move(a));
    }
  };
  // A run's attempts: what each reached when its lease closed (a lease closed before migration 18
  // recorded none: a done one is read from the run's result).
  Statement runs = t.Prepare(
      MyRunsSql() + kOldLook +
      "SELECT l.token, r.id, l.granted_at, COALESCE(l.closed_at, l.completed_at, l.granted_at), "
      "COALESCE(l.outcome, 'expired'), COALESCE(l.sim_time_s, CASE WHEN l.outcome = 'done' THEN res.sim_time_s END), "
      "r.run_duration_s, r.mode, r.axis, r.A, r.f, r.osc_omega, r.rot_omega, r.duration_s, r.materials, r.dt_s, " +
      PayerOf("rr.id = r.id") +
      " FROM runs r JOIN mine m ON m.run_id = r.id JOIN leases l ON l.kind = 'run' AND l.job_id = r.id "
      "LEFT JOIN results res ON res.run_id = r.id WHERE " +
      kClosedLease + "ORDER BY r.id, l.granted_at, l.token");
  SANDSWIM_RETURN_IF_ERROR(read(runs, "run"));
  // A bed's attempts, priced by the materials of one of its runs here (its grains follow them).
  Statement beds = t.Prepare(
      MyRunsSql() + kOldLook +
      "SELECT l.token, b.id, l.granted_at, COALESCE(l.closed_at, l.completed_at, l.granted_at), "
      "COALESCE(l.outcome, 'expired'), NULL, NULL, r.mode, r.axis, r.A, r.f, r.osc_omega, r.rot_omega, r.duration_s, "
      "r.materials, r.dt_s, " +
      PayerOf("rr.bed_id = b.id") +
      " FROM beds b JOIN runs r ON r.id = (SELECT MIN(r2.id) FROM runs r2 JOIN mine m ON m.run_id = r2.id "
      "WHERE r2.bed_id = b.id) JOIN leases l ON l.kind = 'bed' AND l.job_id = b.id WHERE " +
      kClosedLease + "ORDER BY b.id, l.granted_at, l.token");
  SANDSWIM_RETURN_IF_ERROR(read(beds, "bed"));
  return out;
}

Result<std::vector<ClosedAttempt>> UnchargedAttempts(Store& store, int64_t campaign_run_id) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return UnchargedAttempts(*t, campaign_run_id);
}

Result<double> AddCharges(Transaction& t, int64_t campaign_run_id, int round, double now,
                          const std::vector<Charge>& charges) {
  Statement st = t.Prepare(
      "INSERT INTO campaign_run_charges (campaign_run_id, kind, job_id, lease_token, ended_at, state, sim_time_s, "
      "priced_by, core_h, round, charged_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT DO NOTHING");
  double added = 0;
  for (const Charge& c : charges) {
    st.Reset();
    st.Bind(1, campaign_run_id).Bind(2, c.kind).Bind(3, c.id);
    if (c.lease_token.empty()) {
      st.BindNull(4);
    } else {
      st.Bind(4, c.lease_token);
    }
    st.Bind(5, c.ended_at).Bind(6, c.state).Bind(7, c.sim_time_s).Bind(8, c.priced_by).Bind(9, c.core_h);
    st.Bind(10, round).Bind(11, now);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    if (t.Changes() == 1) added += c.core_h;
  }
  return added;
}

Result<double> ChargedCoreHours(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare("SELECT COALESCE(SUM(core_h), 0) FROM campaign_run_charges WHERE campaign_run_id = ?");
  st.Bind(1, campaign_run_id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  return *row ? st.Double(0) : 0.0;
}

Result<double> ChargedCoreHours(Store& store, int64_t campaign_run_id) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return ChargedCoreHours(*t, campaign_run_id);
}

AdaptiveCost RoundRates(const RoundRow& round, AdaptiveCost now) {
  if (round.run_s_per_unit) now.run_rate.s_per_unit = *round.run_s_per_unit;
  if (round.bed_s_per_unit) now.bed_rate.s_per_unit = *round.bed_s_per_unit;
  return now;
}

Result<int64_t> BusyJobs(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare(MyRunsSql() +
                           "SELECT COUNT(*) FROM mine m JOIN runs r ON r.id = m.run_id JOIN beds b ON b.id = r.bed_id "
                           "WHERE r.state IN ('queued', 'running') OR b.state IN ('queued', 'running')");
  st.Bind(1, campaign_run_id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  return *row ? st.Int(0) : 0;
}

Result<int64_t> BusyJobs(Store& store, int64_t campaign_run_id) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return BusyJobs(*t, campaign_run_id);
}

Status DecideLeasePayer(Transaction& t, const std::string& token, api::JobKind kind, int64_t job_id) {
  // The earliest live adaptive campaign run that holds the leased run, or a run on the leased bed.
  const std::string runs = kind == api::JobKind::kBed ? "IN (SELECT id FROM runs WHERE bed_id = ?2)" : "= ?2";
  Statement st = t.Prepare("UPDATE leases SET payer_decided = 1, payer_campaign_run_id = (SELECT MIN(cr.id) FROM (" +
                           HoldsSql("IS NOT NULL", runs) + ") h JOIN campaign_runs cr ON cr.id = h.cr_id WHERE " +
                           kLiveAdaptive + ") WHERE token = ?1");
  st.Bind(1, token).Bind(2, job_id);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  if (t.Changes() != 1) return Status::Internal("the lease " + token + " to decide a payer for is not stored");
  return Status::Ok();
}

Result<std::map<std::string, SweepSlot>> CampaignRunSweeps(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare(
      "SELECT s.name, s.id, COALESCE((SELECT MAX(position) + 1 FROM sweep_runs sr WHERE sr.sweep_id = s.id), 0) "
      "FROM sweeps s WHERE s.campaign_run_id = ? ORDER BY s.id");
  st.Bind(1, campaign_run_id);
  std::map<std::string, SweepSlot> out;
  for (;;) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out[st.Text(0)] = SweepSlot{st.Int(1), st.Int(2)};
  }
  return out;
}

Result<int64_t> CancelledSweeps(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare("SELECT COUNT(*) FROM sweeps WHERE campaign_run_id = ? AND cancelled_at IS NOT NULL");
  st.Bind(1, campaign_run_id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  return *row ? st.Int(0) : 0;
}

Result<int64_t> CancelledSweeps(Store& store, int64_t campaign_run_id) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return CancelledSweeps(*t, campaign_run_id);
}

Result<int64_t> ReplaceInCampaignRunSweeps(Transaction& t, int64_t campaign_run_id, int round, int64_t old_run_id,
                                           const std::string& new_run_key, const std::string& sweep) {
  Statement find = t.Prepare("SELECT id FROM runs WHERE key = ?");
  find.Bind(1, new_run_key);
  Result<bool> row = find.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::Internal("the longer run " + new_run_key + " was not written before it replaced run " +
                                     std::to_string(old_run_id));
  const int64_t new_run_id = find.Int(0);
  if (new_run_id == old_run_id) return int64_t{0};
  Statement record = t.Prepare(
      "INSERT INTO campaign_run_replacements (campaign_run_id, round, sweep_id, position, old_run_id, new_run_id) "
      "SELECT ?1, ?2, sr.sweep_id, sr.position, ?3, ?4 FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
      "WHERE s.campaign_run_id = ?1 AND s.name = ?5 AND sr.run_id = ?3 ON CONFLICT DO NOTHING");
  record.Bind(1, campaign_run_id).Bind(2, round).Bind(3, old_run_id).Bind(4, new_run_id).Bind(5, sweep);
  SANDSWIM_RETURN_IF_ERROR(record.Run());
  Statement leave = t.Prepare(
      "DELETE FROM sweep_runs WHERE run_id = ? AND sweep_id IN (SELECT id FROM sweeps WHERE campaign_run_id = ? "
      "AND name = ?)");
  leave.Bind(1, old_run_id).Bind(2, campaign_run_id).Bind(3, sweep);
  SANDSWIM_RETURN_IF_ERROR(leave.Run());
  return t.Changes();
}

Result<int64_t> SettleReplacements(Transaction& t, int64_t campaign_run_id, double now) {
  struct Pending {
    int round;
    int64_t sweep_id, position, old_run_id, new_run_id;
    JobState state;
  };
  std::vector<Pending> pending;
  {
    Statement st = t.Prepare(
        "SELECT p.round, p.sweep_id, p.position, p.old_run_id, p.new_run_id, r.state FROM campaign_run_replacements p "
        "JOIN runs r ON r.id = p.new_run_id WHERE p.campaign_run_id = ? AND p.outcome IS NULL "
        "AND r.state IN ('done', 'failed', 'cancelled')");
    st.Bind(1, campaign_run_id);
    for (;;) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      Result<JobState> state = st.State(5);
      if (!state.ok()) return state.status();
      pending.push_back({static_cast<int>(st.Int(0)), st.Int(1), st.Int(2), st.Int(3), st.Int(4), *state});
    }
  }
  if (pending.empty()) return int64_t{0};
  Statement settle = t.Prepare(
      "UPDATE campaign_run_replacements SET outcome = ?, settled_at = ? WHERE campaign_run_id = ? AND round = ? "
      "AND sweep_id = ? AND old_run_id = ?");
  Statement back = t.Prepare("INSERT INTO sweep_runs (sweep_id, run_id, position) VALUES (?, ?, ?) ON CONFLICT DO NOTHING");
  Statement out = t.Prepare("DELETE FROM sweep_runs WHERE sweep_id = ? AND run_id = ?");
  int64_t restored = 0;
  std::vector<int64_t> sweeps;
  for (const Pending& p : pending) {
    const bool stands = p.state == JobState::kDone;
    if (!stands) {
      back.Reset();
      back.Bind(1, p.sweep_id).Bind(2, p.old_run_id).Bind(3, p.position);
      SANDSWIM_RETURN_IF_ERROR(back.Run());
      out.Reset();
      out.Bind(1, p.sweep_id).Bind(2, p.new_run_id);
      SANDSWIM_RETURN_IF_ERROR(out.Run());
      ++restored;
      sweeps.push_back(p.sweep_id);
      SANDSWIM_RETURN_IF_ERROR(t.Event(now, "campaign_run.replacement_restored",
                                       "campaign_run/" + std::to_string(campaign_run_id),
                                       {{"round", p.round}, {"sweep", p.sweep_id}, {"run", p.old_run_id},
                                        {"longer_run", p.new_run_id}, {"longer_run_state", p.state}}));
    }
    settle.Reset();
    settle.Bind(1, stands ? "replaced" : "restored").Bind(2, now).Bind(3, campaign_run_id).Bind(4, p.round);
    settle.Bind(5, p.sweep_id).Bind(6, p.old_run_id);
    SANDSWIM_RETURN_IF_ERROR(settle.Run());
  }
  if (!sweeps.empty()) SANDSWIM_RETURN_IF_ERROR(submissions::RecountSweeps(t, sweeps));
  return restored;
}

bool RunsInRounds(const CampaignRunInfo& campaign_run) {
  const json& d = campaign_run.definition;
  return d.is_object() && d.contains("adaptive") && d["adaptive"].is_object();
}

json AdaptiveSettingsJson(const CampaignRunInfo& campaign_run) {
  if (!RunsInRounds(campaign_run)) return nullptr;
  json settings = campaign_run.definition["adaptive"];
  if (!settings.contains("max_rounds")) settings["max_rounds"] = AdaptiveSettings().max_rounds;
  return settings;
}

Result<json> RoundsReply(Store& store, const CampaignRunInfo& campaign_run) {
  json reply{{"adaptive", AdaptiveSettingsJson(campaign_run)}, {"rounds", json::array()}};
  if (reply["adaptive"].is_null()) return reply;
  Result<std::vector<RoundRow>> rows = ListRounds(store, campaign_run.id);
  if (!rows.ok()) return rows.status();
  reply["rounds"] = RoundsToJson(*rows, reply["adaptive"].value("budget_core_h", 0.0));
  return reply;
}

}  // namespace sandswim::rounds
