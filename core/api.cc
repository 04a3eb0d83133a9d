#include "core/api.h"

#include <algorithm>

#include "core/result_fields.h"

namespace sandswim::api {
namespace {

template <typename T>
void PutOptional(nlohmann::json& j, const char* name, const std::optional<T>& v) {
  if (v) j[name] = *v;
}

template <typename T>
void GetOptional(const nlohmann::json& j, const char* name, std::optional<T>& v) {
  auto it = j.find(name);
  if (it != j.end() && !it->is_null())
    v = it->template get<T>();
  else
    v.reset();
}

// A report's fields are the result's that the run makes (core/result_fields.h), under their names.
bool InReport(const ResultField& f) {
  return f.origin == ResultOrigin::kAnalysis || f.origin == ResultOrigin::kRun;
}

}  // namespace

void to_json(nlohmann::json& j, const RunResult& r) {
  j = nlohmann::json::object();
  const StoredResult s{r, {}, {}, 0};
  for (const ResultField& f : ResultFields()) {
    if (!InReport(f)) continue;
    nlohmann::json v = f.get(s);
    if (!v.is_null()) j[f.name] = std::move(v);  // an absent optional field is left out
  }
}

void from_json(const nlohmann::json& j, RunResult& r) {
  StoredResult s;  // a key the report lacks keeps RunResult's default, or the field's `absent`
  for (const ResultField& f : ResultFields()) {
    if (!InReport(f)) continue;
    auto it = j.find(f.name);
    if (it != j.end()) f.set(s, *it);
    else if (!f.absent.is_null()) f.set(s, f.absent);
  }
  r = std::move(s.result);
}

void to_json(nlohmann::json& j, const BedResult& b) {
  j = nlohmann::json{
      {"grains", b.grains},     {"so_z", b.so_z},     {"grain_top", b.grain_top}, {"equilibrated", b.equilibrated},
      {"ke_ratio", b.ke_ratio}, {"sha256", b.sha256}, {"bytes", b.bytes}};
  PutOptional(j, "bed_height", b.bed_height);
  PutOptional(j, "so_depth", b.so_depth);
  PutOptional(j, "packing_fraction", b.packing_fraction);
  PutOptional(j, "shell_grains", b.shell_grains);
}

void from_json(const nlohmann::json& j, BedResult& b) {
  b.grains = j.value("grains", int64_t{0});
  b.so_z = j.value("so_z", 0.0);
  b.grain_top = j.value("grain_top", 0.0);
  b.equilibrated = j.value("equilibrated", false);
  b.ke_ratio = j.value("ke_ratio", 0.0);
  b.sha256 = j.value("sha256", "");
  b.bytes = j.value("bytes", int64_t{0});
  GetOptional(j, "bed_height", b.bed_height);
  GetOptional(j, "so_depth", b.so_depth);
  GetOptional(j, "packing_fraction", b.packing_fraction);
  GetOptional(j, "shell_grains", b.shell_grains);
}

void to_json(nlohmann::json& j, const LeaseGrant& g) {
  j = nlohmann::json{{"token", g.token}, {"kind", g.kind},
                     {"id", g.id},       {"key", g.key},
                     {"deck", g.deck},   {"attempt", g.attempt},
                     {"ttl_s", g.ttl_s}, {"duration_s", g.duration_s},
                     {"steps", g.steps}, {"wall_budget_s", g.wall_budget_s},
                     {"dt_s", g.dt_s},   {"f_hz", g.f_hz},
                     {"A_m", g.A_m}};
  if (!g.key_engine.empty()) j["key_engine"] = g.key_engine;
  PutOptional(j, "bed", g.bed);
  PutOptional(j, "z_floor_m", g.z_floor_m);
  PutOptional(j, "so_radius_m", g.so_radius_m);
  if (g.precision) j["precision"] = PrecisionToJson(*g.precision);
  if (!g.snapshots.empty()) j["snapshots"] = g.snapshots;
  if (g.queue_dry) j["queue_dry"] = true;
}

void from_json(const nlohmann::json& j, LeaseGrant& g) {
  g.token = j.at("token").get<std::string>();
  g.kind = j.at("kind").get<JobKind>();
  g.id = j.at("id").get<int64_t>();
  g.key = j.value("key", "");
  g.deck = j.at("deck").get<std::string>();
  g.key_engine = j.value("key_engine", "");
  g.attempt = j.value("attempt", 1);
  g.ttl_s = j.value("ttl_s", 60.0);
  g.duration_s = j.value("duration_s", 0.0);
  g.steps = j.value("steps", int64_t{0});
  g.wall_budget_s = j.value("wall_budget_s", 0.0);
  GetOptional(j, "bed", g.bed);
  g.dt_s = j.value("dt_s", 0.0);
  g.f_hz = j.value("f_hz", 0.0);
  g.A_m = j.value("A_m", 0.0);
  GetOptional(j, "z_floor_m", g.z_floor_m);
  GetOptional(j, "so_radius_m", g.so_radius_m);
  if (auto it = j.find("precision"); it != j.end() && !it->is_null()) {
    auto t = PrecisionFromJson(*it);
    if (!t.ok()) throw nlohmann::json::other_error::create(501, "precision: " + t.status().ToString(), &*it);
    g.precision = *t;
  }
  g.snapshots = j.value("snapshots", std::vector<double>{});
  g.queue_dry = j.value("queue_dry", false);
}

void to_json(nlohmann::json& j, const Completion& c) {
  j = nlohmann::json{{"ok", c.ok}, {"execution", c.execution}, {"log_tail", c.log_tail}};
  PutOptional(j, "result", c.result);
  PutOptional(j, "bed_result", c.bed_result);
  PutOptional(j, "trajectory", c.trajectory);
  if (!c.snapshots.empty()) j["snapshots"] = c.snapshots;
  PutOptional(j, "failure", c.failure);
  PutOptional(j, "next", c.next);
}

void from_json(const nlohmann::json& j, Completion& c) {
  c.ok = j.at("ok").get<bool>();
  c.execution = j.value("execution", Execution{});
  c.log_tail = j.value("log_tail", "");
  GetOptional(j, "result", c.result);
  GetOptional(j, "bed_result", c.bed_result);
  GetOptional(j, "trajectory", c.trajectory);
  c.snapshots = j.value("snapshots", std::vector<Snapshot>{});
  GetOptional(j, "failure", c.failure);
  GetOptional(j, "next", c.next);
}

std::string ToJsonText(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

void to_json(nlohmann::json& j, const CompletionReply& r) {
  j = nlohmann::json{{"state", r.state}};
  PutOptional(j, "next", r.next);
}

void from_json(const nlohmann::json& j, CompletionReply& r) {
  r.state = j.at("state").get<std::string>();
  GetOptional(j, "next", r.next);
}

int AttemptsFor(const std::string& failure_kind, int max_attempts) {
  static const char* const kRepeatByNature[] = {"deck_error", "not_equilibrated", "lost_atoms", "bad_output",
                                                "bad_lease"};
  for (const char* k : kRepeatByNature)
    if (failure_kind == k) return 1;
  if (failure_kind == "stalled") return std::min(2, max_attempts);
  return max_attempts;
}

namespace {

Status LimitName(const std::string& value, const std::string& field) {
  if (value.size() <= kMaxWorkerNameLength) return Status::Ok();
  return Status::InvalidArgument(field, "may be at most " + std::to_string(kMaxWorkerNameLength) + " bytes, got " +
                                            std::to_string(value.size()));
}

void CutText(std::string& text) {
  if (text.size() <= kMaxWorkerTextLength) return;
  const size_t was = text.size();
  size_t cut = kMaxWorkerTextLength;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0) == 0x80) --cut;  // not inside a character
  text.resize(cut);
  text += "\n[cut at " + std::to_string(cut) + " of " + std::to_string(was) + " bytes by the daemon]";
}

}  // namespace

Status LimitLengths(LeaseRequest& r) {
  SANDSWIM_RETURN_IF_ERROR(LimitName(r.worker, "worker"));
  SANDSWIM_RETURN_IF_ERROR(LimitName(r.host, "host"));
  return LimitName(r.slurm_job, "slurm_job");
}

Status LimitLengths(Completion& c) {
  SANDSWIM_RETURN_IF_ERROR(LimitName(c.execution.engine_version, "execution.engine_version"));
  SANDSWIM_RETURN_IF_ERROR(LimitName(c.execution.host, "execution.host"));
  SANDSWIM_RETURN_IF_ERROR(LimitName(c.execution.launcher, "execution.launcher"));
  if (c.next) {
    Status s = LimitLengths(*c.next);
    if (!s.ok()) return s.WithFieldPrefix("next");
  }
  if (c.failure) {
    SANDSWIM_RETURN_IF_ERROR(LimitName(c.failure->kind, "failure.kind"));
    CutText(c.failure->message);
  }
  CutText(c.log_tail);
  return Status::Ok();
}

Status LimitLengths(ReleaseRequest& r) {
  CutText(r.reason);
  return Status::Ok();
}

}  // namespace sandswim::api
