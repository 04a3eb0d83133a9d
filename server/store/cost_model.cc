#include "server/store/cost_model.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <map>

#include "core/job_state.h"
#include "core/point.h"
#include "core/precision.h"
#include "server/store/job_table.h"

namespace sandswim {
namespace {

using json = nlohmann::json;

// Runs and beds of a scope: the SQL that selects the scope's run ids.
std::string ScopeRuns(EtaScope scope) {
  return scope == EtaScope::kSweep ? "SELECT run_id FROM sweep_runs WHERE sweep_id = ?1"
                                   : "SELECT sr.run_id FROM sweep_runs sr JOIN sweeps s ON s.id = sr.sweep_id "
                                     "WHERE s.campaign_run_id = ?1";
}

Status StepAll(Statement& st, const std::function<void(const Statement&)>& row) {
  while (true) {
    Result<bool> r = st.Step();
    if (!r.ok()) return r.status();
    if (!*r) return Status::Ok();
    row(st);
  }
}

// The earliest step a queued or running run's precision target can end it at (core/cost.h
// WorkLeft::min_steps), from ReadEta's row (columns 9-18); 0 without a target or when the row no
// longer parses (the run then counts to its deck's end).
int64_t EarliestTargetStep(const Statement& r, int64_t steps) {
  Result<std::optional<PrecisionTarget>> target = StoredPrecision(r.OptText(9));
  if (!target.ok() || !*target) return 0;
  Result<Point> point = StoredPoint(r.Text(10), r.Text(11), r.Double(12), r.Double(13), r.Double(14), r.Double(15),
                                    r.Double(16), r.OptText(18), r.OptDouble(19));
  const double run_s = r.Double(17);
  if (!point.ok() || !(run_s > 0)) return 0;
  const double earliest = EarliestTargetStopS(*point, **target);
  return std::clamp<int64_t>(static_cast<int64_t>(std::ceil(static_cast<double>(steps) * earliest / run_s)), 1, steps);
}

std::string Plural(int n, const char* what) { return std::to_string(n) + " " + what + (n == 1 ? "" : "s"); }

}  // namespace

namespace {

// The live running runs' stretches for core/cost.h CurrentShare, from their progress marks of
// this attempt: the last kShareWindowS before their newest heartbeat, the window before that, and
// their attempt so far.
Result<Share> ReadShare(Transaction& t, double now, const EngineRate& model) {
  struct Running {
    int64_t id, step;
    double heartbeat_at, started_at, particles;
  };
  std::vector<Running> running;
  {
    Statement st = t.Prepare(
        "SELECT r.id, r.step, r.heartbeat_at, r.started_at, b.grains + 1.0 FROM runs r JOIN beds b ON b.id = r.bed_id "
        "WHERE r.state = 'running' AND r.step > 0 AND b.grains > 0 AND r.heartbeat_at >= ?1 AND r.started_at IS NOT "
        "NULL");
    st.Bind(1, now - kLiveEngineS);
    Status s = StepAll(st, [&](const Statement& r) {
      running.push_back({r.Int(0), r.Int(1), r.Double(2), r.Double(3), r.Double(4)});
    });
    if (!s.ok()) return s;
  }
  std::vector<RateSample> recent, before, so_far;
  for (const Running& run : running) {
    so_far.push_back({static_cast<double>(run.step) * run.particles, run.heartbeat_at - run.started_at});
    std::vector<std::pair<double, int64_t>> marks;  // (at, step), oldest first
    Statement st = t.Prepare(
        "SELECT at, step FROM run_progress WHERE run_id = ?1 AND at >= ?2 AND at <= ?3 AND at >= ?4 ORDER BY at");
    st.Bind(1, run.id).Bind(2, run.started_at).Bind(3, run.heartbeat_at);
    st.Bind(4, run.heartbeat_at - 2 * kShareWindowS - jobs::kProgressMarkS);
    Status s = StepAll(st, [&](const Statement& r) { marks.emplace_back(r.Double(0), r.Int(1)); });
    if (!s.ok()) return s;
    // The oldest mark at or after `from`.
    auto first_after = [&](double from) {
      return std::find_if(marks.begin(), marks.end(), [&](const auto& m) { return m.first >= from; });
    };
    auto a = first_after(run.heartbeat_at - kShareWindowS);
    if (a == marks.end()) continue;
    recent.push_back({static_cast<double>(run.step - a->second) * run.particles, run.heartbeat_at - a->first});
    auto b = first_after(a->first - kShareWindowS);
    if (b != a) before.push_back({static_cast<double>(a->second - b->second) * run.particles, a->first - b->first});
  }
  return CurrentShare(recent, before, so_far, model, kShareWindowS);
}

// `hosts`: also every done run's rate per host and rank count (GET /api/v1/cost-model), a read
// of every result; the ETA does not use them.
Result<CostModelView> ReadIn(Transaction& t, double now, bool hosts) {
  CostModelView v;
  if (hosts) {
    // Every done run's result, per host and rank count.
    std::map<std::pair<std::string, int>, std::vector<RateSample>> by_host;
    Statement st = t.Prepare("SELECT host, ranks, steps * (grains + 1.0), wall_s FROM results WHERE wall_s > 0");
    Status s = StepAll(st, [&](const Statement& r) {
      by_host[{r.Text(0), static_cast<int>(r.Int(1))}].push_back({r.Double(2), r.Double(3)});
    });
    if (!s.ok()) return s;
    for (const auto& [key, samples] : by_host) {
      v.hosts.push_back({key.first, key.second,
                         FitRate(samples, DefaultRate(),
                                 Plural(static_cast<int>(samples.size()), "done run") + " on " + key.first + ", " +
                                     Plural(key.second, "rank"))});
    }
  }
  Result<EngineRate> run_rate = PooledRunRate(t);
  if (!run_rate.ok()) return run_rate.status();
  v.run_rate = *run_rate;
  Result<std::vector<RankRate>> bed_rates = BedRatesByRanks(t);
  if (!bed_rates.ok()) return bed_rates.status();
  v.bed_rates = std::move(bed_rates).value();
  v.bed_rate = BedRateOnRanks(v.bed_rates, 1);
  {
    // Running jobs, and of them those whose last heartbeat (or grant) is fresh: the engines.
    const std::string live = "MAX(COALESCE(heartbeat_at, 0), COALESCE(started_at, 0)) >= ?1";
    Statement st = t.Prepare("SELECT (SELECT COUNT(*) FROM runs WHERE state = 'running') + (SELECT COUNT(*) FROM beds "
                             "WHERE state = 'running'), (SELECT COUNT(*) FROM runs WHERE state = 'running' AND " +
                             live + ") + (SELECT COUNT(*) FROM beds WHERE state = 'running' AND " + live + ")");
    st.Bind(1, now - kLiveEngineS);
    Result<bool> r = st.Step();
    if (!r.ok()) return r.status();
    v.engines_in_flight = static_cast<int>(st.Int(1));
    v.silent_jobs = static_cast<int>(st.Int(0) - st.Int(1));
  }
  Result<Share> share = ReadShare(t, now, v.run_rate);
  if (!share.ok()) return share.status();
  v.share = *share;
  return v;
}

}  // namespace

Result<EngineRate> PooledRunRate(Transaction& t) {
  std::vector<RateSample> pooled;
  int done = 0, running = 0;
  {
    // The newest results by run id (the primary key: no sort of the whole table).
    Statement st = t.Prepare(
        "SELECT steps * (grains + 1.0), wall_s FROM results WHERE wall_s > 0 ORDER BY run_id DESC LIMIT ?1");
    st.Bind(1, kRateWindow);
    Status s = StepAll(st, [&](const Statement& r) {
      pooled.push_back({r.Double(0), r.Double(1)});
      ++done;
    });
    if (!s.ok()) return s;
  }
  {
    // Running runs: the step of their last heartbeat over the time it took them (their bed's grains
    // + the SO).
    Statement st = t.Prepare(
        "SELECT r.step * (b.grains + 1.0), r.heartbeat_at - r.started_at FROM runs r JOIN beds b ON b.id = r.bed_id "
        "WHERE r.state = 'running' AND r.step > 0 AND b.grains > 0 AND r.heartbeat_at - r.started_at >= ?1");
    st.Bind(1, kMinProgressSampleS);
    Status s = StepAll(st, [&](const Statement& r) {
      pooled.push_back({r.Double(0), r.Double(1)});
      ++running;
    });
    if (!s.ok()) return s;
  }
  std::string basis = "measured: ";
  if (done) basis += Plural(done, "done run");
  if (done && running) basis += " and ";
  if (running) basis += Plural(running, "running run");
  return FitRate(pooled, DefaultRate(), basis);
}

Result<std::vector<RankRate>> BedRatesByRanks(Transaction& t) {
  struct Beds {
    std::vector<RateSample> samples;
    int unknown = 0;  // of them, beds prepared before their ranks were recorded
  };
  std::map<int, Beds> by_ranks;
  // Newest first; each rank count keeps its newest kRateWindow (beds are few: no window in SQL).
  Statement st = t.Prepare(
      "SELECT COALESCE(ranks, 1), ranks IS NULL, grains, finished_at - started_at FROM beds WHERE state = 'done' "
      "AND grains > 0 AND finished_at > started_at ORDER BY finished_at DESC");
  Status s = StepAll(st, [&](const Statement& r) {
    Beds& beds = by_ranks[std::max(1, static_cast<int>(r.Int(0)))];
    if (beds.samples.size() >= static_cast<size_t>(kRateWindow)) return;
    beds.samples.push_back({r.Double(2), r.Double(3)});
    if (r.Int(1) != 0) ++beds.unknown;
  });
  if (!s.ok()) return s;
  std::vector<RankRate> out;
  for (const auto& [ranks, beds] : by_ranks) {
    std::string basis =
        "measured: " + Plural(static_cast<int>(beds.samples.size()), "done bed") + " on " + Plural(ranks, "rank");
    if (beds.unknown > 0) {
      basis += " (" + std::to_string(beds.unknown) + " of them prepared before ranks were recorded, counted as 1)";
    }
    out.push_back({ranks, FitRate(beds.samples, DefaultBedRate(), basis)});
  }
  return out;
}

Result<EngineRate> BedRate(Transaction& t, int ranks) {
  Result<std::vector<RankRate>> rates = BedRatesByRanks(t);
  if (!rates.ok()) return rates.status();
  return BedRateOnRanks(*rates, ranks);
}

Result<double> WallBudget(Transaction& t, bool bed, int64_t bed_id, int64_t steps) {
  double grains = 0;
  std::string scale_name;
  {
    Statement st = t.Prepare("SELECT grains, scale FROM beds WHERE id = ?1");
    st.Bind(1, bed_id);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (*row) {
      grains = st.OptInt(0).value_or(0);
      scale_name = st.Text(1);
    }
  }
  if (!(grains > 0)) {
    const Scale* scale = FindScale(scale_name);
    grains = EstimatedGrains(scale ? *scale : *FindScale("smoke"));
  }
  Result<EngineRate> rate = bed ? BedRate(t) : PooledRunRate(t);
  if (!rate.ok()) return rate.status();
  const double predicted = bed ? grains * rate->s_per_unit : static_cast<double>(steps) * (grains + 1) * rate->s_per_unit;
  return kWallBudgetMultiple * predicted + kWallBudgetMarginS;
}

void to_json(json& j, const EngineRate& r) {
  j = {{"s_per_unit", r.s_per_unit}, {"rel_error", r.rel_error}, {"samples", r.samples}, {"basis", r.basis}};
}

void to_json(json& j, const CostModelView& v) {
  json hosts = json::array();
  for (const HostRate& h : v.hosts) {
    json r = h.rate;
    r["host"] = h.host;
    r["ranks"] = h.ranks;
    hosts.push_back(std::move(r));
  }
  json beds = json::array();
  for (const RankRate& b : v.bed_rates) {
    json r = b.rate;
    r["ranks"] = b.ranks;
    beds.push_back(std::move(r));
  }
  json share = {{"measured", v.share.measured},
                {"factor", v.share.factor},
                {"scale", v.share.scale},
                {"rel_error", v.share.rel_error},
                {"engines", v.share.engines},
                {"window_s", v.share.window_s}};
  if (v.share.factor_before) share["factor_before"] = *v.share.factor_before;
  j = {{"run_rate", v.run_rate},
       {"bed_rate", v.bed_rate},
       {"bed_rates", beds},
       {"hosts", hosts},
       {"engines_in_flight", v.engines_in_flight},
       {"engines_silent", v.silent_jobs},
       {"share", share}};
}

Result<CostModelView> ReadCostModel(Store& store, double now) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return ReadIn(*t, now, /*hosts=*/true);
}

Result<std::optional<Eta>> ReadEta(Store& store, EtaScope scope, int64_t id, double now, int min_slots) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  Result<CostModelView> model = ReadIn(*t, now, /*hosts=*/false);
  if (!model.ok()) return model.status();
  const Scale* smoke = FindScale("smoke");
  std::vector<WorkLeft> left;
  std::map<int64_t, WorkLeft> beds;  // the beds its unfinished runs wait for
  {
    Statement st = t->Prepare(
        "SELECT r.state, r.steps, COALESCE(r.step, 0), COALESCE(r.heartbeat_at - r.started_at, 0), b.id, b.state, "
        "b.grains, b.scale, COALESCE(?2 - b.started_at, 0), r.precision, r.mode, r.axis, r.A, r.f, r.osc_omega, "
        "r.rot_omega, r.duration_s, r.run_duration_s, r.materials, r.dt_s FROM runs r JOIN beds b ON b.id = r.bed_id "
        "WHERE r.id IN (" + ScopeRuns(scope) + ") AND r.state IN ('queued', 'running')");
    st.Bind(1, id).Bind(2, now);
    Status unparsed = Status::Ok();  // a state text that is no JobState: Corruption, as every store read
    Status s = StepAll(st, [&](const Statement& r) {
      Result<JobState> run_state = r.State(0);
      Result<JobState> bed_state = r.State(5);
      if (!run_state.ok() || !bed_state.ok()) {
        if (unparsed.ok()) unparsed = run_state.ok() ? bed_state.status() : run_state.status();
        return;
      }
      const Scale* scale = FindScale(r.Text(7));
      const double grains = r.OptInt(6) && *r.OptInt(6) > 0 ? static_cast<double>(*r.OptInt(6))
                                                              : EstimatedGrains(scale ? *scale : *smoke);
      WorkLeft w;
      w.running = *run_state == JobState::kRunning;
      w.particles = grains + 1;
      w.steps = r.Int(1);
      w.steps_done = r.Int(2);
      w.elapsed_s = r.Double(3);
      w.min_steps = EarliestTargetStep(r, w.steps);
      left.push_back(w);
      if (*bed_state == JobState::kQueued || *bed_state == JobState::kRunning) {
        WorkLeft b;
        b.kind = WorkLeft::Kind::kBed;
        b.running = *bed_state == JobState::kRunning;
        b.particles = grains;
        b.elapsed_s = b.running ? r.Double(8) : 0;
        beds[r.Int(4)] = b;
      }
    });
    if (!s.ok()) return s;
    if (!unparsed.ok()) return unparsed;
  }
  for (const auto& [bed_id, b] : beds) left.push_back(b);
  if (left.empty()) return std::optional<Eta>();
  // The share of their steps the scope's done runs used (a precision target or a boundary ends
  // runs early), as the expectation for the rest.
  std::vector<double> fractions;
  {
    Statement st = t->Prepare("SELECT CAST(res.steps AS REAL) / r.steps FROM runs r JOIN results res ON res.run_id = r.id "
                              "WHERE r.id IN (" + ScopeRuns(scope) + ") AND r.state = 'done' AND r.steps > 0");
    st.Bind(1, id);
    Status s = StepAll(st, [&](const Statement& r) { fractions.push_back(std::clamp(r.Double(0), 0.0, 1.0)); });
    if (!s.ok()) return s;
  }
  StepShare share;
  if (!fractions.empty()) {
    double mean = 0;
    for (double f : fractions) mean += f;
    mean /= static_cast<double>(fractions.size());
    double ss = 0;
    for (double f : fractions) ss += (f - mean) * (f - mean);
    share.done = static_cast<int>(fractions.size());
    share.mean = mean;
    // One done run says nothing of the scatter: half its share, as a guess.
    share.sd = fractions.size() > 1 ? std::sqrt(ss / static_cast<double>(fractions.size() - 1)) : 0.5 * mean;
  }
  const int slots = std::max({model->engines_in_flight, min_slots, 1});
  // Beds on this machine are assumed to get the share its runs get now (no bed's share is measured:
  // beds do not heartbeat their progress), and the basis says so.
  EngineRate bed_rate = model->bed_rate;
  if (model->share.measured) {
    bed_rate.s_per_unit *= model->share.scale;
    bed_rate.rel_error = std::hypot(bed_rate.rel_error, model->share.rel_error);
    bed_rate.basis += ", assumed the runs' share now (a bed's is not measured)";
  }
  std::optional<Eta> eta = EstimateEta(left, AtShare(model->run_rate, model->share), bed_rate, share, slots);
  if (eta) {
    eta->basis += "; " + Plural(slots, "engine");
    if (model->silent_jobs > 0) {
      eta->basis += " (" + Plural(model->silent_jobs, "running job") + " without a heartbeat for " +
                    std::to_string(static_cast<int>(kLiveEngineS)) + " s not counted)";
    }
  }
  return eta;
}

json EtaJson(const std::optional<Eta>& eta) {
  if (!eta) return nullptr;
  return {{"s", eta->seconds},
          {"rel_error", eta->rel_error},
          // rel_error is a half-range on a log scale (the share's |ln factor| / 2): the band is s / e^r
          // to s * e^r, never below 0 and as wide on either side in ratio.
          {"low_s", eta->seconds / std::exp(eta->rel_error)},
          {"high_s", eta->seconds * std::exp(eta->rel_error)},
          {"basis", eta->basis}};
}

}  // namespace sandswim
