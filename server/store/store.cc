#include "server/store/store.h"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <string_view>
#include <tuple>
#include <utility>

#include "core/deck.h"
#include "core/job_state.h"
#include "core/scale.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "server/store/result_columns.h"

namespace sandswim {
namespace {

// How many columns a list names (its commas, plus one).
constexpr int ColumnCount(std::string_view list) {
  int n = 1;
  for (char ch : list) n += ch == ',';
  return n;
}

// Columns of a run summary, shared by ListRuns, GetRun and the live board; the run's result
// follows them (RunColumns, ReadResult at kRunColumnCount).
constexpr std::string_view kRunColumns =
    "r.id, r.key, r.state, r.mode, r.A, r.f, r.osc_omega, r.rot_omega, r.axis, r.duration_s, "
    "r.run_duration_s, r.steps, r.bed_id, r.attempts, r.worker, r.sim_time_s, r.so_z, r.step, "
    "r.heartbeat_at, r.created_at, r.started_at, r.finished_at, r.last_error_kind, r.last_error, "
    "r.precision, r.snapshots, r.materials, r.dt_s";
constexpr int kRunColumnCount = ColumnCount(kRunColumns);
constexpr int kRunMaterialsColumn = kRunColumnCount - 2;  // and r.dt_s after it

// kRunColumns, then the run's result (a query joins `results res`), then what a query adds.
const std::string& RunColumns() {
  static const std::string kColumns = std::string(kRunColumns) + ", " + ResultSelectList();
  return kColumns;
}
int RunColumnsCount() { return kRunColumnCount + static_cast<int>(ResultFields().size()); }

// The snapshots table's rows of one run, by idx (schema/010_snapshots.sql).
Result<std::vector<api::Snapshot>> SnapshotsIn(Transaction& t, int64_t run_id) {
  Statement st =
      t.Prepare("SELECT idx, fraction, t_s, step, grains, bytes, sha256 FROM snapshots WHERE run_id = ? ORDER BY idx");
  st.Bind(1, run_id);
  std::vector<api::Snapshot> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out.push_back(api::Snapshot{static_cast<int>(st.Int(0)), st.Double(1), st.Double(2), st.Int(3), st.Int(4),
                                st.Int(5), st.Text(6)});
  }
  return out;
}

// Columns c..c+6: mode, A, f, osc_omega, rot_omega, axis, duration_s, and columns `materials` and
// `materials` + 1: the run's materials and its step, r.dt_s (core/point.h StoredPoint).
Result<Point> PointFromRow(const Statement& st, int c, int materials) {
  return StoredPoint(st.Text(c), st.Text(c + 5), st.Double(c + 1), st.Double(c + 2), st.Double(c + 3), st.Double(c + 4),
                     st.Double(c + 6), st.OptText(materials), st.OptDouble(materials + 1));
}

// A row of RunColumns().
Result<RunSummary> RunSummaryFromRow(const Statement& st) {
  RunSummary r;
  r.id = st.Int(0);
  r.key = st.Text(1);
  Result<JobState> state = st.State(2);
  if (!state.ok()) return state.status();
  r.state = *state;
  Result<Point> point = PointFromRow(st, 3, kRunMaterialsColumn);
  if (!point.ok()) return Status(point.status().code(), "run " + std::to_string(r.id) + ": " + point.status().reason());
  r.point = *point;
  r.run_duration_s = st.Double(10);
  r.steps = st.Int(11);
  r.bed_id = st.Int(12);
  r.attempts = static_cast<int>(st.Int(13));
  r.worker = st.Text(14);
  r.progress.sim_time_s = st.OptDouble(15).value_or(0);
  r.progress.so_z = st.OptDouble(16).value_or(0);
  r.progress.step = st.OptInt(17).value_or(0);
  r.progress.heartbeat_at = st.OptDouble(18);
  r.created_at = st.Double(19);
  r.started_at = st.OptDouble(20);
  r.finished_at = st.OptDouble(21);
  if (!st.IsNull(22)) r.last_error = api::Failure{st.Text(22), st.Text(23)};
  Result<std::optional<PrecisionTarget>> precision = StoredPrecision(st.OptText(24));
  if (!precision.ok())
    return Status(precision.status().code(), "run " + std::to_string(r.id) + ": " + precision.status().reason());
  r.precision = *precision;
  Result<SnapshotFractions> snapshots = StoredSnapshotFractions(st.OptText(25));
  if (!snapshots.ok())
    return Status(snapshots.status().code(), "run " + std::to_string(r.id) + ": " + snapshots.status().reason());
  r.snapshots = *snapshots;
  if (std::optional<StoredResult> res = ReadResult(st, kRunColumnCount)) {
    r.uz = res->result.uz;
    r.uz_text = DescribeUz(res->result);
  }
  return r;
}

// Adds the count in column 1 to the count of the state in column 0 (a state column: a text that
// is no job state is Corruption, not a count lost).
Status AddState(RunCounts& c, const Statement& st) {
  Result<JobState> s = st.State(0);
  if (!s.ok()) return s.status();
  c[*s] += st.Int(1);
  return Status::Ok();
}

template <typename T>
void PutOpt(nlohmann::json& j, const char* name, const std::optional<T>& v) {
  if (v) j[name] = *v;
}

nlohmann::json ParseJsonOr(const std::string& text, nlohmann::json fallback) {
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  return j.is_discarded() ? fallback : j;
}

Result<RunCounts> CountsWhere(Transaction& t, const std::string& sql, int64_t id) {
  Statement st = t.Prepare(sql);
  st.Bind(1, id);
  RunCounts c;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    SANDSWIM_RETURN_IF_ERROR(AddState(c, st));
  }
  return c;
}

// One row of sweep_counts (schema/003_perf.sql: kept by triggers in every transaction that
// changes a run's state or a sweep's membership), not a count over 10^5 membership rows.
Result<RunCounts> SweepCounts(Transaction& t, int64_t sweep_id) {
  Statement st = t.Prepare("SELECT queued, running, done, failed, cancelled FROM sweep_counts WHERE sweep_id = ?");
  st.Bind(1, sweep_id);
  RunCounts c;
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (*row) c = RunCounts{st.Int(0), st.Int(1), st.Int(2), st.Int(3), st.Int(4)};
  return c;
}

SweepInfo SweepFromRow(const Statement& st) {
  SweepInfo s;
  s.id = st.Int(0);
  s.name = st.Text(1);
  s.scale = st.Text(2);
  s.spec = ParseJsonOr(st.Text(3), nlohmann::json::object());
  s.campaign_run_id = st.OptInt(4);
  s.force = st.Int(5) != 0;
  s.created_at = st.Double(6);
  s.cancelled_at = st.OptDouble(7);
  return s;
}

constexpr const char* kSweepColumns = "id, name, scale, spec, campaign_run_id, force, created_at, cancelled_at";

}  // namespace

// ---- JSON ---------------------------------------------------------------------------------------

int64_t& RunCounts::operator[](JobState s) {
  switch (s) {
    case JobState::kQueued:
      return queued;
    case JobState::kRunning:
      return running;
    case JobState::kDone:
      return done;
    case JobState::kFailed:
      return failed;
    case JobState::kCancelled:
      return cancelled;
  }
  return queued;  // not reached: every JobState is a case
}

void to_json(nlohmann::json& j, const RunCounts& c) {
  j = nlohmann::json::object();
  for (JobState s : kJobStates) j[ToString(s)] = c[s];
}

void to_json(nlohmann::json& j, const SweepInfo& s) {
  j = nlohmann::json{{"id", s.id},
                     {"name", s.name},
                     {"scale", s.scale},
                     {"spec", s.spec},
                     {"force", s.force},
                     {"created_at", s.created_at},
                     {"cancelled", s.cancelled_at.has_value()},
                     {"counts", s.counts},
                     {"runs", s.counts.total()}};
  PutOpt(j, "campaign_run_id", s.campaign_run_id);
  PutOpt(j, "cancelled_at", s.cancelled_at);
}

void to_json(nlohmann::json& j, const SweepPage& p) {
  j = nlohmann::json{{"sweeps", p.sweeps}, {"next_cursor", nullptr}};
  if (p.next_cursor) j["next_cursor"] = *p.next_cursor;
}

void to_json(nlohmann::json& j, const Progress& p) {
  j = nlohmann::json{{"sim_time_s", p.sim_time_s}, {"so_z", p.so_z}, {"step", p.step}};
  PutOpt(j, "heartbeat_at", p.heartbeat_at);
}

void to_json(nlohmann::json& j, const RunSummary& r) {
  j = nlohmann::json{{"id", r.id},
                     {"key", r.key},
                     {"state", r.state},
                     {"point", PointToJson(r.point)},
                     {"run_duration_s", r.run_duration_s},
                     {"steps", r.steps},
                     {"bed_id", r.bed_id},
                     {"precision", r.precision ? PrecisionToJson(*r.precision) : nlohmann::json(nullptr)},
                     {"snapshots", r.snapshots},
                     {"attempts", r.attempts},
                     {"worker", r.worker},
                     {"progress", r.progress},
                     {"created_at", r.created_at}};
  PutOpt(j, "started_at", r.started_at);
  PutOpt(j, "finished_at", r.finished_at);
  PutOpt(j, "uz", r.uz);
  if (!r.uz_text.empty()) j["uz_text"] = r.uz_text;
  PutOpt(j, "last_error", r.last_error);
}

void to_json(nlohmann::json& j, const RunPage& p) {
  j = nlohmann::json{{"runs", p.runs}, {"next_cursor", nullptr}};
  if (p.next_cursor) j["next_cursor"] = *p.next_cursor;
}

void to_json(nlohmann::json& j, const RunDetail& r) {
  j = r.summary;
  j["deck"] = r.deck;
  j["bed_key"] = r.bed_key;
  j["bed_state"] = r.bed_state;
  j["sweeps"] = r.sweep_ids;
  PutOpt(j, "result", r.result);
  PutOpt(j, "trajectory", r.trajectory);
  j["log_tail"] = r.log_tail;
  j["snapshots_taken"] = nlohmann::json::array();
  for (const api::Snapshot& snap : r.snapshots) {
    nlohmann::json sj = snap;
    const std::string base = "/api/v1/runs/" + std::to_string(r.summary.id) + "/snapshots/" + std::to_string(snap.idx);
    sj["links"] = {{"vtk", base + ".vtk"},
                   {"dump", base + ".dump"},
                   {"slice_svg", base + "/slice.svg"},
                   {"slice_png", base + "/slice.png"}};
    j["snapshots_taken"].push_back(std::move(sj));
  }
}


void to_json(nlohmann::json& j, const CampaignRunInfo& c) {
  j = nlohmann::json{{"id", c.id},           {"campaign", c.campaign},     {"scale", c.scale},
                     {"trigger", c.trigger}, {"created_at", c.created_at}, {"sweeps", c.sweep_ids},
                     {"counts", c.counts}};
  PutOpt(j, "due_time", c.due_time);
  j["campaign_version"] = c.campaign_version ? nlohmann::json(*c.campaign_version) : nlohmann::json(nullptr);
  j["definition_sha256"] = c.definition_sha256.empty() ? nlohmann::json(nullptr) : nlohmann::json(c.definition_sha256);
}

void to_json(nlohmann::json& j, const StoredCampaign& c) {
  j = nlohmann::json{{"name", c.name},
                     {"definition", c.definition},
                     {"updated_at", c.updated_at}};
  PutOpt(j, "schedule", c.schedule);
}

void to_json(nlohmann::json& j, const Metrics& m) {
  j = nlohmann::json{{"runs", m.runs},
                     {"beds", m.beds},
                     {"sweeps", m.sweeps},
                     {"leases_granted", m.leases_granted},
                     {"completions", m.completions},
                     {"expirations", m.expirations},
                     {"pilots_gone", m.pilots_gone},
                     {"duplicates", m.duplicates}};
}

// ---- Store --------------------------------------------------------------------------------------

Result<std::unique_ptr<Store>> Store::Open(const std::string& path) {
  Result<std::unique_ptr<Database>> db = Database::Open(path);
  if (!db.ok()) return db.status();
  return std::unique_ptr<Store>(new Store(std::move(db).value()));
}

namespace {

// An old result as ReanalyzeOldResults reads it.
struct OldResult {
  int64_t run_id = 0;
  double f = 0;
  std::string scale, bed_result, trajectory, stop_reason;
  double sim_time_s = 0, z0 = 0;
  int64_t steps = 0, grains = 0;
  bool vibrates = false;
  int analysis = 1;
  std::optional<std::string> precision;  // the run's precision target (JSON), if it had one
  std::optional<std::string> materials;  // the run's materials (runs.materials), NULL: Table 1's
  std::optional<double> dt_s;            // the run's step (runs.dt_s), NULL: its materials' TimeStep
};

// The result analysis `kAnalysisVersion` makes of `o`'s stored trajectory, or why there is none.
Result<api::RunResult> Reanalyse(const OldResult& o) {
  nlohmann::json tj = ParseJsonOr(o.trajectory, nullptr);
  if (!tj.is_object()) return Status::FailedPrecondition("trajectory", "no stored trajectory");
  try {
    api::Trajectory tr = tj.get<api::Trajectory>();
    std::vector<SoSample> samples;
    Result<Materials> materials = StoredMaterials(o.materials);
    if (!materials.ok()) return materials.status();
    const double dt = o.dt_s.value_or(TimeStep(*materials));
    for (size_t i = 0; i < tr.t.size() && i < tr.x.size() && i < tr.y.size() && i < tr.z.size(); ++i) {
      samples.push_back({std::llround(tr.t[i] / dt), tr.t[i], tr.x[i], tr.y[i], tr.z[i]});
    }
    BedBounds bounds;
    bounds.so_radius = materials->d_so / 2;  // the run's SO, as its deck's r_so
    if (const Scale* scale = FindScale(o.scale)) bounds.floor = BoxFor(*scale, *materials).z_floor;
    nlohmann::json bed = ParseJsonOr(o.bed_result, nullptr);
    if (bed.is_object() && bed.contains("grain_top")) bounds.surface = bed["grain_top"].get<double>();
    DriveStartMarker start{o.grains, o.z0, bounds.surface.value_or(0)};
    DriveStopMarker stop{o.stop_reason, o.steps, o.sim_time_s, samples.empty() ? 0 : samples.back().z};
    // As the worker analyses a run (core/trajectory.h AnalyzeRun) -- except a run that the rule of
    // analysis 2 ended once its interval looked narrow enough: the blocks after a pilot were part
    // of that decision too, so no interval of it is honest (optional stopping). Its rate stays,
    // without an error.
    Result<std::optional<PrecisionTarget>> precision = StoredPrecision(o.precision);
    if (!precision.ok()) return precision.status();
    const bool old_stop = o.analysis == 2 && o.stop_reason == "target";
    RunInputs in;
    in.f = o.vibrates ? o.f : 0.0;
    in.bounds = bounds;
    if (bounds.surface) in.start = start;
    in.stop = stop;
    if (!old_stop) in.precision = *precision;
    auto r = AnalyzeRun(samples, in);
    if (!r.ok()) return r.status();
    if (old_stop) {
      r->uz_stderr.reset();
      r->uz_ci95.reset();
      r->uz_stderr_note =
          "ended by the precision rule of analysis 2 once its interval looked narrow enough, which made that "
          "interval too narrow (optional stopping): none is given; submit the sweep again with --force for one";
      r->precision_met = false;
      r->stop_note = "stopped for its precision target at t = " + Num(o.sim_time_s, 3) +
                     " s under the rule of analysis 2 (optional stopping): no interval";
    }
    r->grains = o.grains;  // as the engine reported it
    r->analysed_from = "trajectory";
    return r;
  } catch (const nlohmann::json::exception& e) {
    return Status::Corruption("the stored trajectory cannot be read: " + std::string(e.what()));
  }
}

}  // namespace

// Results of an analysis below this are re-analysed at start-up (their numbers or intervals were
// wrong: analysis 1's error, analysis 2's optional stopping). Analysis 4 (a transient in physical
// time, the trend test, x's amplitude at f) changed no number of analysis 3 that was wrong: a
// result of analysis 3 keeps its numbers and its analysis; `sandswim submit --force` runs it anew
// for analysis 4's.
constexpr int kReanalysedBelow = 3;

Result<Store::Reanalysis> Store::ReanalyzeOldResults() {
  // Pages of kPage rows by run id, each written in one transaction: memory and the write lock
  // are bounded however many results an old database holds.
  constexpr int kPage = 200;
  Reanalysis out;
  int64_t after = 0;
  while (true) {
    std::vector<OldResult> page;
    {
      Result<Transaction> t = db_->BeginRead();
      if (!t.ok()) return t.status();
      Statement st = t->Prepare(
          "SELECT res.run_id, r.f, r.mode, b.scale, COALESCE(b.result, ''), COALESCE(tr.data, ''), "
          "res.stop_reason, res.sim_time_s, res.steps, res.grains, res.z0, res.analysis, r.precision, "
          "r.materials, r.dt_s FROM results res "
          "JOIN runs r ON r.id = res.run_id JOIN beds b ON b.id = r.bed_id "
          "LEFT JOIN trajectories tr ON tr.run_id = res.run_id "
          "WHERE res.analysis < ? AND res.analysed_from != 'unreadable' AND res.run_id > ? "
          "ORDER BY res.run_id LIMIT ?");
      st.Bind(1, kReanalysedBelow).Bind(2, after).Bind(3, kPage);
      while (true) {
        Result<bool> row = st.Step();
        if (!row.ok()) return row.status();
        if (!*row) break;
        OldResult o;
        o.run_id = st.Int(0);
        o.f = st.Double(1);
        auto mode = ParseMode(st.Text(2));
        o.vibrates = mode && Point{*mode}.has_vibration();
        o.scale = st.Text(3);
        o.bed_result = st.Text(4);
        o.trajectory = st.Text(5);
        o.stop_reason = st.Text(6);
        o.sim_time_s = st.Double(7);
        o.steps = st.Int(8);
        o.grains = st.Int(9);
        o.z0 = st.Double(10);
        o.analysis = static_cast<int>(st.Int(11));
        o.precision = st.OptText(12);
        o.materials = st.OptText(13);
        o.dt_s = st.OptDouble(14);
        page.push_back(std::move(o));
      }
    }
    if (page.empty()) return out;
    after = page.back().run_id;
    Reanalysis counts;
    Status s = db_->Write([&](Transaction& t) {
      counts = {};
      Statement fresh = t.Prepare(UpdateAnalysedFieldsSql());
      Statement kept = t.Prepare(
          "UPDATE results SET analysed_from = 'unreadable', conclusive = 0, inconclusive_reason = ? "
          "WHERE run_id = ?");
      Statement same = t.Prepare("UPDATE results SET analysis = ? WHERE run_id = ?");
      for (const OldResult& o : page) {
        if (o.analysis >= 2 && o.stop_reason != "target") {
          // Analysis 3 changed only the runs ended by their precision target: this one's numbers
          // are this analysis's already, from its full dump (a trajectory is downsampled).
          same.Reset();
          same.Bind(1, kReanalysedBelow).Bind(2, o.run_id);
          SANDSWIM_RETURN_IF_ERROR(same.Run());
          ++counts.unchanged;
          continue;
        }
        Result<api::RunResult> r = Reanalyse(o);
        if (!r.ok()) {
          kept.Reset();
          kept.Bind(1,
                    (o.analysis == 1 ? std::string("made by the old estimator (analysis 1: a line and a sinusoid "
                                                   "fitted over one period, with a standard error ~10x too small)")
                                     : "ended by its precision target under analysis " + std::to_string(o.analysis) +
                                           ", whose interval was too narrow (the one its stop was chosen on)") +
                        "; it cannot be re-analysed: " + r.status().reason());
          kept.Bind(2, o.run_id);
          SANDSWIM_RETURN_IF_ERROR(kept.Run());
          ++counts.kept_old;
          continue;
        }
        SANDSWIM_RETURN_IF_ERROR(UpdateAnalysedFields(fresh, o.run_id, *r));
        ++counts.reanalysed;
      }
      return Status::Ok();
    });
    if (!s.ok()) return s;
    out.reanalysed += counts.reanalysed;
    out.kept_old += counts.kept_old;
    out.unchanged += counts.unchanged;
  }
}

Result<SweepPage> Store::ListSweeps(int64_t after_id, int limit) {
  limit = std::clamp(limit, 1, 1000);
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  SweepPage page;
  {
    Statement st = t->Prepare(std::string("SELECT ") + kSweepColumns + " FROM sweeps WHERE id > ? ORDER BY id LIMIT ?");
    st.Bind(1, after_id).Bind(2, limit + 1);
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      if (static_cast<int>(page.sweeps.size()) == limit) {
        page.next_cursor = page.sweeps.back().id;
        break;
      }
      page.sweeps.push_back(SweepFromRow(st));
    }
  }
  for (SweepInfo& s : page.sweeps) {
    Result<RunCounts> c = SweepCounts(*t, s.id);
    if (!c.ok()) return c.status();
    s.counts = *c;
  }
  return page;
}

Result<SweepInfo> Store::GetSweep(int64_t id) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  SweepInfo s;
  {
    Statement st = t->Prepare(std::string("SELECT ") + kSweepColumns + " FROM sweeps WHERE id = ?");
    st.Bind(1, id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) return Status::NotFound("no sweep " + std::to_string(id));
    s = SweepFromRow(st);
  }
  Result<RunCounts> c = SweepCounts(*t, id);
  if (!c.ok()) return c.status();
  s.counts = *c;
  return s;
}

Result<RunPage> Store::ListRuns(const RunFilter& f) {
  int limit = std::clamp(f.limit, 1, 1000);
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  std::string sql = "SELECT " + RunColumns() + " FROM ";
  sql += f.sweep_id ? "sweep_runs sr JOIN runs r ON r.id = sr.run_id " : "runs r ";
  sql += "LEFT JOIN results res ON res.run_id = r.id WHERE r.id > ?1";
  if (f.sweep_id) sql += " AND sr.sweep_id = ?2";
  if (f.state) sql += " AND r.state = ?3";
  sql += " ORDER BY r.id LIMIT ?4";
  RunPage page;
  Statement st = t->Prepare(sql);
  st.Bind(1, f.after_id).Bind(4, limit + 1);
  if (f.sweep_id) st.Bind(2, *f.sweep_id);
  if (f.state) st.Bind(3, JobStateName(*f.state));
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    if (static_cast<int>(page.runs.size()) == limit) {
      page.next_cursor = page.runs.back().id;
      break;
    }
    Result<RunSummary> run = RunSummaryFromRow(st);
    if (!run.ok()) return run.status();
    page.runs.push_back(std::move(run).value());
  }
  return page;
}

Result<RunDetail> Store::GetRun(int64_t id, Deck deck) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  RunDetail d;
  {
    Statement st = t->Prepare(
        "SELECT " + RunColumns() + ", d.deck, b.key, b.state, tr.data, lg.log_tail, b.scale FROM runs r " + "JOIN beds b ON b.id = r.bed_id " +
        "LEFT JOIN run_decks d ON d.run_id = r.id " + "LEFT JOIN results res ON res.run_id = r.id " +
        "LEFT JOIN trajectories tr ON tr.run_id = r.id " + "LEFT JOIN run_logs lg ON lg.run_id = r.id WHERE r.id = ?");
    st.Bind(1, id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) return Status::NotFound("no run " + std::to_string(id));
    Result<RunSummary> summary = RunSummaryFromRow(st);
    if (!summary.ok()) return summary.status();
    d.summary = std::move(summary).value();
    const int c = RunColumnsCount();
    if (deck == Deck::kLeftOut) {
      // d.deck stays "".
    } else if (!st.IsNull(c)) {
      d.deck = st.Text(c);
    } else {
      // Not stored since migration 3: the deck is a pure function of the point and the scale
      // (the lease queue renders the same bytes and checks them against the run's key).
      const Scale* scale = FindScale(st.Text(c + 5));
      if (scale == nullptr) return Status::Corruption("run " + std::to_string(id) + "'s bed has an unknown scale");
      try {
        d.deck = RenderDriveDeck(d.summary.point, *scale, d.summary.precision, d.summary.snapshots);
      } catch (const std::exception& e) {
        return Status::Internal("run " + std::to_string(id) + "'s deck does not render: " + e.what());
      }
    }
    d.bed_key = st.Text(c + 1);
    Result<JobState> bed_state = st.State(c + 2);
    if (!bed_state.ok()) return bed_state.status();
    d.bed_state = *bed_state;
    d.result = ReadResult(st, kRunColumnCount);
    if (!st.IsNull(c + 3)) {
      nlohmann::json tj = ParseJsonOr(st.Text(c + 3), nullptr);
      if (tj.is_object()) {
        try {
          d.trajectory = tj.get<api::Trajectory>();
        } catch (const nlohmann::json::exception&) {
          return Status::Corruption("trajectory of run " + std::to_string(id) + " does not parse");
        }
      }
    }
    d.log_tail = st.Text(c + 4);
  }
  Statement st = t->Prepare("SELECT sweep_id FROM sweep_runs WHERE run_id = ? ORDER BY sweep_id");
  st.Bind(1, id);
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    d.sweep_ids.push_back(st.Int(0));
  }
  Result<std::vector<api::Snapshot>> snapshots = SnapshotsIn(*t, id);
  if (!snapshots.ok()) return snapshots.status();
  d.snapshots = std::move(snapshots).value();
  return d;
}

Result<std::map<int64_t, api::Trajectory>> Store::SweepTrajectories(int64_t sweep_id) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  // Done runs only: a trajectory is what a run reported at completion, and the analysis draws done
  // runs; one left by a run that is not done (requeued, failed, running again) is not read, so it
  // cannot fail the sweep's analysis.
  Statement st = t->Prepare(
      "SELECT tr.run_id, tr.data FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id "
      "JOIN trajectories tr ON tr.run_id = sr.run_id WHERE sr.sweep_id = ? AND r.state = ?");
  st.Bind(1, sweep_id).Bind(2, JobStateName(JobState::kDone));
  std::map<int64_t, api::Trajectory> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    const int64_t run_id = st.Int(0);
    // As GetRun reads it: a stored value that is not an object is no trajectory.
    nlohmann::json tj = ParseJsonOr(st.Text(1), nullptr);
    if (!tj.is_object()) continue;
    try {
      out[run_id] = tj.get<api::Trajectory>();
    } catch (const nlohmann::json::exception&) {
      return Status::Corruption("trajectory of run " + std::to_string(run_id) + " does not parse");
    }
  }
  return out;
}

namespace {

constexpr const char* kBedColumns =
    "b.id, b.key, b.scale, b.replicate, b.seed_pour1, b.seed_pour2, b.state, b.attempts, b.result, "
    "b.last_error_kind, b.last_error, b.created_at, b.finished_at, "
    "(SELECT count(*) FROM runs r WHERE r.bed_id = b.id), b.ranks";

Result<BedView> BedFromRow(const Statement& st) {
  BedView b;
  b.id = st.Int(0);
  b.key = st.Text(1);
  b.scale = st.Text(2);
  b.replicate = static_cast<int>(st.Int(3));
  if (!st.IsNull(4)) b.seed_pour1 = st.Int(4);
  if (!st.IsNull(5)) b.seed_pour2 = st.Int(5);
  Result<JobState> state = st.State(6);
  if (!state.ok()) return state.status();
  b.state = *state;
  b.attempts = static_cast<int>(st.Int(7));
  if (!st.IsNull(8)) {
    nlohmann::json j = nlohmann::json::parse(st.Text(8), nullptr, /*allow_exceptions=*/false);
    if (j.is_discarded() || !j.is_object())
      return Status::Corruption("bed " + std::to_string(b.id) + ": its stored result is not a JSON object");
    try {
      b.result = j.get<api::BedResult>();
    } catch (const nlohmann::json::exception& e) {
      return Status::Corruption("bed " + std::to_string(b.id) + ": its stored result does not read: " + e.what());
    }
  }
  if (!st.IsNull(9)) b.last_error = api::Failure{st.Text(9), st.Text(10)};
  b.created_at = st.Double(11);
  b.finished_at = st.OptDouble(12);
  b.runs = st.Int(13);
  if (!st.IsNull(14)) b.ranks = static_cast<int>(st.Int(14));
  return b;
}

}  // namespace

void to_json(nlohmann::json& j, const BedView& b) {
  j = nlohmann::json{{"id", b.id},       {"key", b.key},           {"scale", b.scale}, {"replicate", b.replicate},
                     {"state", b.state}, {"attempts", b.attempts}, {"runs", b.runs},   {"created_at", b.created_at}};
  if (b.seed_pour1 && b.seed_pour2) j["seeds"] = {{"pour1", *b.seed_pour1}, {"pour2", *b.seed_pour2}};
  if (b.result) j["result"] = *b.result;
  if (b.ranks) j["ranks"] = *b.ranks;
  if (b.last_error) j["last_error"] = {{"kind", b.last_error->kind}, {"message", b.last_error->message}};
  if (b.finished_at) j["finished_at"] = *b.finished_at;
}

Result<BedView> Store::GetBed(int64_t id) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(std::string("SELECT ") + kBedColumns + " FROM beds b WHERE b.id = ?");
  st.Bind(1, id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::NotFound("no bed " + std::to_string(id));
  return BedFromRow(st);
}

Result<std::vector<BedView>> Store::ListBeds() {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(std::string("SELECT ") + kBedColumns + " FROM beds b ORDER BY b.id");
  std::vector<BedView> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    Result<BedView> b = BedFromRow(st);
    if (!b.ok()) return b.status();
    out.push_back(std::move(b).value());
  }
  return out;
}

namespace {

// The columns of a result row (ResultRowFromRow): the run's, then its result, then whatever a
// query adds after them (from kResultRowColumnCount() on).
constexpr std::string_view kResultRowRunColumns =
    "r.id, r.key, r.state, r.mode, r.A, r.f, r.osc_omega, r.rot_omega, r.axis, r.duration_s, "
    "r.run_duration_s, r.bed_id, b.replicate, r.materials, r.dt_s";
constexpr int kResultRowRunColumnCount = ColumnCount(kResultRowRunColumns);
const std::string& ResultRowColumns() {
  static const std::string kColumns = std::string(kResultRowRunColumns) + ", " + ResultSelectList();
  return kColumns;
}
const int kResultRowColumnCount = kResultRowRunColumnCount + static_cast<int>(ResultFields().size());

Result<ResultRow> ResultRowFromRow(const Statement& st) {
  ResultRow r;
  r.run_id = st.Int(0);
  r.key = st.Text(1);
  Result<JobState> state = st.State(2);
  if (!state.ok()) return state.status();
  r.state = *state;
  Result<Point> point = PointFromRow(st, 3, 13);
  if (!point.ok())
    return Status(point.status().code(), "run " + std::to_string(r.run_id) + ": " + point.status().reason());
  r.point = *point;
  r.run_duration_s = st.Double(10);
  r.bed_id = st.Int(11);
  r.replicate = static_cast<int>(st.Int(12));
  r.result = ReadResult(st, kResultRowRunColumnCount);
  return r;
}

Status MustExist(Transaction& t, const char* table, const char* what, int64_t id) {
  Statement st = t.Prepare(std::string("SELECT 1 FROM ") + table + " WHERE id = ?");
  st.Bind(1, id);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return Status::NotFound(std::string("no ") + what + " " + std::to_string(id));
  return Status::Ok();
}

}  // namespace

Result<std::vector<ResultRow>> Store::SweepResults(int64_t sweep_id) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  if (Status s = MustExist(*t, "sweeps", "sweep", sweep_id); !s.ok()) return s;
  Statement st = t->Prepare("SELECT " + ResultRowColumns() +
                            " FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id JOIN beds b ON b.id = r.bed_id "
                            "LEFT JOIN results res ON res.run_id = r.id WHERE sr.sweep_id = ? ORDER BY sr.position");
  st.Bind(1, sweep_id);
  std::vector<ResultRow> rows;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    Result<ResultRow> r = ResultRowFromRow(st);
    if (!r.ok()) return r.status();
    rows.push_back(std::move(r).value());
  }
  return rows;
}

Result<ResultPage> Store::ResultsPage(ResultsOf of, int64_t id, const ResultCursor& after, int limit) {
  limit = std::clamp(limit, 1, kMaxResultsPage);
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  const bool campaign = of == ResultsOf::kCampaignRun;
  if (Status s = campaign ? MustExist(*t, "campaign_runs", "campaign run", id) : MustExist(*t, "sweeps", "sweep", id);
      !s.ok())
    return s;
  std::map<int64_t, std::string> sweep_names;  // a campaign run's sweeps
  if (campaign) {
    Statement st = t->Prepare("SELECT id, name FROM sweeps WHERE campaign_run_id = ?");
    st.Bind(1, id);
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      sweep_names[st.Int(0)] = st.Text(1);
    }
  }
  // Both walk (sweep, position) in order on sweep_runs_by_position. A campaign run's run that an
  // earlier sweep of the same campaign run holds too is left where it first appeared.
  const std::string joins =
      " JOIN runs r ON r.id = sr.run_id JOIN beds b ON b.id = r.bed_id LEFT JOIN results res ON res.run_id = r.id ";
  const std::string sql =
      campaign ? "SELECT " + ResultRowColumns() +
                     ", sr.sweep_id, sr.position, (SELECT group_concat(sr2.sweep_id) FROM sweep_runs sr2 JOIN sweeps "
                     "s2 ON s2.id = sr2.sweep_id WHERE sr2.run_id = r.id AND s2.campaign_run_id = ?1)"
                     " FROM sweeps s JOIN sweep_runs sr ON sr.sweep_id = s.id" +
                     joins +
                     "WHERE s.campaign_run_id = ?1 AND (sr.sweep_id > ?2 OR (sr.sweep_id = ?2 AND sr.position > ?3)) "
                     "AND NOT EXISTS (SELECT 1 FROM sweep_runs sr3 JOIN sweeps s3 ON s3.id = sr3.sweep_id "
                     "WHERE sr3.run_id = r.id AND s3.campaign_run_id = ?1 AND s3.id < s.id) "
                     "ORDER BY sr.sweep_id, sr.position LIMIT ?4"
               : "SELECT " + ResultRowColumns() + ", sr.sweep_id, sr.position FROM sweep_runs sr" + joins +
                     "WHERE sr.sweep_id = ?1 AND sr.position > ?3 ORDER BY sr.position LIMIT ?4";
  Statement st = t->Prepare(sql);
  st.Bind(1, id).Bind(2, after.sweep_id).Bind(3, after.position).Bind(4, limit + 1);
  ResultPage page;
  ResultCursor last = after;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    if (static_cast<int>(page.rows.size()) == limit) {
      page.next = last;
      break;
    }
    Result<ResultRow> r = ResultRowFromRow(st);
    if (!r.ok()) return r.status();
    last = ResultCursor{st.Int(kResultRowColumnCount), st.Int(kResultRowColumnCount + 1)};
    if (campaign) {
      std::vector<int64_t> ids;  // "12,14": group_concat's order is not defined
      const std::string list = st.Text(kResultRowColumnCount + 2);
      for (size_t at = 0; at < list.size();) {
        size_t end = list.find(',', at);
        if (end == std::string::npos) end = list.size();
        ids.push_back(std::strtoll(list.c_str() + at, nullptr, 10));
        at = end + 1;
      }
      std::sort(ids.begin(), ids.end());
      for (int64_t sweep : ids) r->sweeps.push_back(sweep_names[sweep]);
    }
    page.rows.push_back(std::move(r).value());
  }
  return page;
}

Result<std::vector<ResultRow>> Store::ResultsOfDrives(ResultsOf of, int64_t id, const std::vector<Point>& points) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  const bool campaign = of == ResultsOf::kCampaignRun;
  if (Status s = campaign ? MustExist(*t, "campaign_runs", "campaign run", id) : MustExist(*t, "sweeps", "sweep", id);
      !s.ok())
    return s;
  std::set<DriveId> drives;
  std::set<std::tuple<double, double, double, double>> numbers;  // a first sieve on the run's own columns
  for (const Point& p : points) {
    drives.insert(DriveIdOf(p));
    numbers.emplace(p.A, p.f, p.Omega, p.omega);
  }
  std::vector<int64_t> candidates;  // in the set's order, each once
  {
    Statement st = t->Prepare(
        campaign ? "SELECT r.id, r.A, r.f, r.osc_omega, r.rot_omega FROM sweeps s JOIN sweep_runs sr ON sr.sweep_id = "
                   "s.id JOIN runs r ON r.id = sr.run_id WHERE s.campaign_run_id = ? ORDER BY sr.sweep_id, sr.position"
                 : "SELECT r.id, r.A, r.f, r.osc_omega, r.rot_omega FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id "
                   "WHERE sr.sweep_id = ? ORDER BY sr.position");
    st.Bind(1, id);
    std::set<int64_t> seen;
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      if (numbers.count({st.Double(1), st.Double(2), st.Double(3), st.Double(4)}) == 0) continue;
      if (seen.insert(st.Int(0)).second) candidates.push_back(st.Int(0));
    }
  }
  std::map<int64_t, ResultRow> found;
  constexpr size_t kChunk = 500;  // ids bound per statement
  for (size_t from = 0; from < candidates.size(); from += kChunk) {
    const size_t to = std::min(candidates.size(), from + kChunk);
    std::string marks;
    for (size_t i = from; i < to; ++i) marks += i == from ? "?" : ",?";
    Statement st = t->Prepare("SELECT " + ResultRowColumns() +
                              " FROM runs r JOIN beds b ON b.id = r.bed_id LEFT JOIN results res ON res.run_id = r.id "
                              "WHERE r.id IN (" + marks + ")");
    for (size_t i = from; i < to; ++i) st.Bind(static_cast<int>(i - from + 1), candidates[i]);
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      Result<ResultRow> r = ResultRowFromRow(st);
      if (!r.ok()) return r.status();
      if (drives.count(DriveIdOf(r->point)) > 0) found.emplace(r->run_id, std::move(r).value());
    }
  }
  std::vector<ResultRow> rows;
  rows.reserve(found.size());
  for (int64_t run : candidates) {
    auto it = found.find(run);
    if (it != found.end()) rows.push_back(std::move(it->second));
  }
  return rows;
}

namespace {

Result<std::vector<CampaignRunInfo>> ReadCampaignRuns(Transaction& t, Statement& st) {
  std::vector<CampaignRunInfo> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    CampaignRunInfo c;
    c.id = st.Int(0);
    c.campaign = st.Text(1);
    c.scale = st.Text(2);
    c.trigger = st.Text(3);
    c.due_time = st.OptDouble(4);
    c.created_at = st.Double(5);
    if (std::optional<int64_t> v = st.OptInt(6)) c.campaign_version = static_cast<int>(*v);
    if (std::optional<std::string> d = st.OptText(7)) c.definition = ParseJsonOr(*d, nlohmann::json());
    c.definition_sha256 = st.Text(8);
    out.push_back(std::move(c));
  }
  for (CampaignRunInfo& c : out) {
    Statement s = t.Prepare("SELECT id FROM sweeps WHERE campaign_run_id = ? ORDER BY id");
    s.Bind(1, c.id);
    while (true) {
      Result<bool> row = s.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      c.sweep_ids.push_back(s.Int(0));
    }
    Result<RunCounts> counts =
        CountsWhere(t,
                    "SELECT state, COUNT(*) FROM runs WHERE id IN (SELECT sr.run_id FROM sweep_runs sr "
                    "JOIN sweeps s ON s.id = sr.sweep_id WHERE s.campaign_run_id = ?) GROUP BY state",
                    c.id);
    if (!counts.ok()) return counts.status();
    c.counts = *counts;
  }
  return out;
}

constexpr const char* kCampaignRunColumns =
    "id, campaign, scale, trigger, due_time, created_at, campaign_version, definition, definition_sha256";

}  // namespace

Result<CampaignRunInfo> Store::GetCampaignRun(int64_t id) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(std::string("SELECT ") + kCampaignRunColumns + " FROM campaign_runs WHERE id = ?");
  st.Bind(1, id);
  Result<std::vector<CampaignRunInfo>> rows = ReadCampaignRuns(*t, st);
  if (!rows.ok()) return rows.status();
  if (rows->empty()) return Status::NotFound("no campaign run " + std::to_string(id));
  return std::move(rows->front());
}

Result<std::vector<CampaignRunInfo>> Store::ListCampaignRuns(const std::string& campaign, int limit) {
  limit = std::clamp(limit, 1, 1000);
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(std::string("SELECT ") + kCampaignRunColumns +
                            " FROM campaign_runs WHERE (?1 = '' OR campaign = ?1) "
                            "ORDER BY id DESC LIMIT ?2");
  st.Bind(1, campaign).Bind(2, limit);
  return ReadCampaignRuns(*t, st);
}

namespace {
// campaigns.drift_tolerance_mps is not read: the tolerance is the definition's (server/store/campaigns.h).
constexpr const char* kCampaignColumns = "name, definition, schedule, updated_at, version";
StoredCampaign CampaignFromRow(const Statement& st) {
  StoredCampaign c;
  c.name = st.Text(0);
  c.definition = ParseJsonOr(st.Text(1), nlohmann::json::object());
  c.schedule = st.OptText(2);
  c.updated_at = st.Double(3);
  c.version = static_cast<int>(st.Int(4));
  return c;
}
}  // namespace

Result<std::optional<StoredCampaign>> Store::GetCampaign(const std::string& name) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(std::string("SELECT ") + kCampaignColumns + " FROM campaigns WHERE name = ?");
  st.Bind(1, name);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<StoredCampaign>();
  return std::optional<StoredCampaign>(CampaignFromRow(st));
}

Result<std::vector<StoredCampaign>> Store::ListCampaigns() {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Statement st = t->Prepare(std::string("SELECT ") + kCampaignColumns + " FROM campaigns ORDER BY name");
  std::vector<StoredCampaign> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out.push_back(CampaignFromRow(st));
  }
  return out;
}

Result<Metrics> Store::GetMetrics() {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  Metrics m;
  for (const char* table : {"runs", "beds"}) {
    Statement st = t->Prepare(std::string("SELECT state, COUNT(*) FROM ") + table + " GROUP BY state");
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      SANDSWIM_RETURN_IF_ERROR(AddState(std::string(table) == "runs" ? m.runs : m.beds, st));
    }
  }
  {
    Statement st = t->Prepare("SELECT COUNT(*) FROM sweeps");
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    m.sweeps = st.Int(0);
  }
  Statement st = t->Prepare("SELECT name, value FROM counters");
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    std::string name = st.Text(0);
    if (name == "leases_granted")
      m.leases_granted = st.Int(1);
    else if (name == "completions")
      m.completions = st.Int(1);
    else if (name == "expirations")
      m.expirations = st.Int(1);
    else if (name == "pilots_gone")
      m.pilots_gone = st.Int(1);
    else if (name == "duplicates")
      m.duplicates = st.Int(1);
  }
  return m;
}

Result<LiveBoard> Store::ReadLiveBoard(int sweeps, int campaign_runs, int running) {
  Result<Transaction> t = db_->BeginRead();
  if (!t.ok()) return t.status();
  LiveBoard board;
  auto earliest_start = [&](const char* sql, int64_t id) -> Result<std::optional<double>> {
    Statement st = t->Prepare(sql);
    st.Bind(1, id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    return *row ? st.OptDouble(0) : std::nullopt;
  };
  {
    Statement st = t->Prepare(std::string("SELECT ") + kSweepColumns + " FROM sweeps ORDER BY id DESC LIMIT ?");
    st.Bind(1, sweeps);
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      board.sweeps.push_back(SweepFromRow(st));
      board.sweeps.back().spec = nullptr;  // the feed shows progress; the spec is GET /sweeps/{id}'s
    }
  }
  for (SweepInfo& s : board.sweeps) {
    Result<RunCounts> c = SweepCounts(*t, s.id);
    if (!c.ok()) return c.status();
    s.counts = *c;
    if (s.counts.queued + s.counts.running == 0) continue;
    auto started = earliest_start(
        "SELECT MIN(r.started_at) FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id WHERE sr.sweep_id = ?", s.id);
    if (!started.ok()) return started.status();
    if (*started) board.sweep_started_at[s.id] = **started;
  }
  {
    Statement st = t->Prepare(std::string("SELECT ") + kCampaignRunColumns + " FROM campaign_runs ORDER BY id DESC LIMIT ?");
    st.Bind(1, campaign_runs);
    Result<std::vector<CampaignRunInfo>> rows = ReadCampaignRuns(*t, st);
    if (!rows.ok()) return rows.status();
    board.campaign_runs = std::move(rows).value();
  }
  for (const CampaignRunInfo& c : board.campaign_runs) {
    if (c.counts.queued + c.counts.running == 0) continue;
    auto started = earliest_start(
        "SELECT MIN(r.started_at) FROM runs r WHERE r.id IN (SELECT sr.run_id FROM sweep_runs sr "
        "JOIN sweeps s ON s.id = sr.sweep_id WHERE s.campaign_run_id = ?)",
        c.id);
    if (!started.ok()) return started.status();
    if (*started) board.campaign_run_started_at[c.id] = **started;
  }
  {
    Statement st = t->Prepare("SELECT " + RunColumns() +
                              " FROM runs r LEFT JOIN results res ON res.run_id = r.id WHERE r.state = 'running' "
                              "ORDER BY r.id LIMIT ?");
    st.Bind(1, running);
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      Result<RunSummary> run = RunSummaryFromRow(st);
      if (!run.ok()) return run.status();
      board.running.push_back(std::move(run).value());
    }
  }
  if (!board.running.empty()) {
    // A run is in one sweep, or in several of a campaign run: the board says which, so a page or
    // `sandswim watch` shows a sweep's runs in flight without asking for them.
    Statement st = t->Prepare(
        "SELECT sr.run_id, sr.sweep_id FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id WHERE r.state = 'running' "
        "AND r.id <= ? ORDER BY sr.run_id, sr.sweep_id");
    st.Bind(1, board.running.back().id);
    while (true) {
      Result<bool> row = st.Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      board.running_sweeps[st.Int(0)].push_back(st.Int(1));
    }
  }
  Statement st = t->Prepare("SELECT state, COUNT(*) FROM runs GROUP BY state");
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    SANDSWIM_RETURN_IF_ERROR(AddState(board.runs, st));
  }
  return board;
}

}  // namespace sandswim
