#include "core/campaign_definition.h"

#include <set>

#include "core/claims.h"
#include "core/text.h"

namespace sandswim {

using nlohmann::json;

namespace {

std::string List(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

// The base's array `key` ("sweeps", "claims") indexed by each element's `id_key`.
Result<std::vector<std::pair<std::string, json>>> Named(const json& base, const char* key, const char* id_key) {
  std::vector<std::pair<std::string, json>> out;
  auto it = base.find(key);
  if (it == base.end()) return out;
  if (!it->is_array()) return Status::Internal(std::string("the base's \"") + key + "\" is not an array");
  for (const json& e : *it) {
    if (!e.is_object() || !e.contains(id_key) || !e[id_key].is_string())
      return Status::Internal(std::string("an element of the base's \"") + key + "\" has no " + id_key);
    out.emplace_back(e[id_key].get<std::string>(), e);
  }
  return out;
}

// `written` (the definition's array) with every string replaced by the base's element of that name.
Result<json> Select(const json& written, const char* key, const char* what,
                    const std::string& base_name, const std::vector<std::pair<std::string, json>>& base) {
  if (!written.is_array())
    return Status::InvalidArgument(key, std::string("must be an array of ") + what + " (objects) or names of the " +
                                            base_name + " campaign's " + what + " (strings)");
  json out = json::array();
  std::set<std::string> taken;
  for (size_t i = 0; i < written.size(); ++i) {
    const std::string field = std::string(key) + "[" + std::to_string(i) + "]";
    const json& e = written[i];
    if (!e.is_string()) {
      out.push_back(e);
      continue;
    }
    const std::string name = e.get<std::string>();
    const json* found = nullptr;
    std::vector<std::string> names;
    for (const auto& [n, element] : base) {
      names.push_back(n);
      if (n == name) found = &element;
    }
    if (!found)
      return Status::InvalidArgument(field, "names no " + std::string(what).substr(0, std::string(what).size() - 1) +
                                                " of " + base_name + " (its " + what + ": " + List(names) + ")");
    if (!taken.insert(name).second) return Status::InvalidArgument(field, "takes \"" + name + "\" twice");
    out.push_back(*found);
  }
  return out;
}

}  // namespace

Status CheckCampaignName(const std::string& field, const std::string& name) {
  if (name.empty() || name.size() > kMaxCampaignNameLength)
    return Status::InvalidArgument(field, "must be 1 to " + std::to_string(kMaxCampaignNameLength) + " characters");
  for (char c : name) {
    bool ok =
        (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok) return Status::InvalidArgument(field, "may hold only A-Z a-z 0-9 . _ -");
  }
  return Status::Ok();
}

Result<ResolvedDefinition> ResolveCampaignDefinition(const json& definition, const CampaignLookup& lookup) {
  if (!definition.is_object()) return Status::InvalidArgument("", "must be a JSON object (a campaign definition)");
  ResolvedDefinition r;
  auto ext = definition.find("extends");
  if (ext == definition.end()) {
    r.resolved = definition;
    return r;
  }
  if (!ext->is_string()) return Status::InvalidArgument("extends", "must be the name of a campaign (a string)");
  r.extends = ext->get<std::string>();
  SANDSWIM_RETURN_IF_ERROR(CheckCampaignName("extends", r.extends));
  auto own_name = definition.find("name");
  if (own_name != definition.end() && own_name->is_string() && own_name->get<std::string>() == r.extends)
    return Status::InvalidArgument("extends", "names this campaign itself: a campaign extends another one");
  Result<BaseCampaign> base = lookup(r.extends);
  if (!base.ok()) {
    if (base.status().code() == StatusCode::kNotFound)
      return Status::InvalidArgument("extends", base.status().reason());
    return base.status();
  }
  r.extends_version = base->version;
  const json& b = base->resolved;
  if (!b.is_object()) return Status::Internal("campaign " + r.extends + " has no resolved definition");

  auto base_sweeps = Named(b, "sweeps", "name");
  if (!base_sweeps.ok()) return base_sweeps.status();
  auto base_claims = Named(b, "claims", "id");
  if (!base_claims.ok()) return base_claims.status();

  json out = b;
  for (const auto& [key, value] : definition.items()) {
    if (key == "extends") continue;
    if (key == "sweeps") {
      auto s = Select(value, "sweeps", "sweeps", r.extends, *base_sweeps);
      if (!s.ok()) return s.status();
      out["sweeps"] = std::move(*s);
    } else if (key == "claims") {
      auto c = Select(value, "claims", "claims", r.extends, *base_claims);
      if (!c.ok()) return c.status();
      out["claims"] = std::move(*c);
    } else {
      out[key] = value;
    }
  }
  // The base's claims, when the definition states none, are those it can still judge.
  if (!definition.contains("claims") && definition.contains("sweeps") && out.contains("claims") &&
      out["sweeps"].is_array()) {
    std::vector<std::string> kept;
    for (const json& s : out["sweeps"])
      if (s.is_object() && s.contains("name") && s["name"].is_string()) kept.push_back(s["name"].get<std::string>());
    json claims = json::array();
    for (const json& c : b["claims"]) {
      auto one = ParseClaims(json::array({c}), kept);
      if (one.ok()) {
        claims.push_back(c);
      } else {
        std::string why = one.status().reason();
        std::string field = one.status().field();  // "[0].rule.sweep"
        if (StartsWith(field, "[0]")) field = field.substr(3);
        if (StartsWith(field, ".")) field = field.substr(1);
        if (!field.empty()) why = field + ": " + why;
        r.notes.push_back("claim " + c.value("id", std::string("?")) + " of " + r.extends + " left out (" + why +
                          "): state it in \"claims\" to keep it");
      }
    }
    out["claims"] = std::move(claims);
  }
  r.resolved = std::move(out);
  return r;
}

}  // namespace sandswim
