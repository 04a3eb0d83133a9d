#include "core/api.h"

namespace sandswim::api {
namespace {

template <typename T>
void PutOptional(nlohmann::json& j, const char* name, const std::optional<T>& v) {
  if (v) j[name] = *v;
}

template <typename T>
void GetOptional(const nlohmann::json& j, const char* name, std::optional<T>& v) {
  auto it = j.find(name);
  if (it != j.end() && !it->is_null()) v = it->template get<T>();
  else v.reset();
}

}  // namespace

void to_json(nlohmann::json& j, const LeaseGrant& g) {
  j = nlohmann::json{{"token", g.token},       {"kind", g.kind},           {"id", g.id},
                     {"key", g.key},           {"deck", g.deck},           {"attempt", g.attempt},
                     {"ttl_s", g.ttl_s},       {"duration_s", g.duration_s}, {"steps", g.steps},
                     {"wall_budget_s", g.wall_budget_s}};
  PutOptional(j, "bed", g.bed);
}

void from_json(const nlohmann::json& j, LeaseGrant& g) {
  g.token = j.at("token").get<std::string>();
  g.kind = j.at("kind").get<JobKind>();
  g.id = j.at("id").get<int64_t>();
  g.key = j.value("key", "");
  g.deck = j.at("deck").get<std::string>();
  g.attempt = j.value("attempt", 1);
  g.ttl_s = j.value("ttl_s", 60.0);
  g.duration_s = j.value("duration_s", 0.0);
  g.steps = j.value("steps", int64_t{0});
  g.wall_budget_s = j.value("wall_budget_s", 0.0);
  GetOptional(j, "bed", g.bed);
}

void to_json(nlohmann::json& j, const Completion& c) {
  j = nlohmann::json{{"ok", c.ok}, {"execution", c.execution}, {"log_tail", c.log_tail}};
  PutOptional(j, "result", c.result);
  PutOptional(j, "bed_result", c.bed_result);
  PutOptional(j, "trajectory", c.trajectory);
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

}  // namespace sandswim::api
