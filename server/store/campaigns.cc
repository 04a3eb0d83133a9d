#include "server/store/campaigns.h"

#include "core/keys.h"

namespace sandswim {

using nlohmann::json;

Result<CatalogueEntry> FindCampaign(Store& store, const std::string& name, const std::string& field) {
  Result<std::optional<StoredCampaign>> stored = store.GetCampaign(name);
  if (!stored.ok()) return stored.status();
  CatalogueEntry entry;
  if (stored->has_value()) {
    const StoredCampaign& row = **stored;
    Result<Campaign> parsed = ParseCampaign(row.definition);
    if (!parsed.ok()) {
      return Status::Corruption("stored campaign '" + name + "' no longer parses: " + parsed.status().ToString());
    }
    entry.campaign = std::move(parsed).value();
    entry.definition = row.definition;
    entry.stored = true;
    entry.schedule = row.schedule;
    entry.version = row.version;
    return entry;
  }
  Result<Campaign> builtin = BuiltinCampaign(name);
  if (!builtin.ok()) {
    std::string names;
    for (const std::string& n : BuiltinCampaignNames()) names += (names.empty() ? "" : ", ") + n;
    return Status(StatusCode::kNotFound,
                  "no campaign named '" + name + "' (builtin: " + names + "; or one stored in the daemon)", field);
  }
  entry.campaign = std::move(builtin).value();
  Result<nlohmann::json> definition = BuiltinCampaignDefinition(name);
  if (!definition.ok()) return definition.status();
  entry.definition = std::move(definition).value();
  entry.schedule = entry.campaign.schedule;
  return entry;
}

std::string DefinitionSha256(const json& resolved) { return Sha256Hex(resolved.dump()); }

void to_json(json& j, const CampaignVersion& v) {
  j = {{"version", v.version},
       {"created_at", v.created_at},
       {"extends", v.extends.empty() ? json(nullptr) : json(v.extends)},
       {"extends_version", v.extends.empty() ? json(nullptr) : json(v.extends_version)},
       {"definition_sha256", v.definition_sha256}};
}

namespace {

constexpr const char* kVersionColumns = "name, version, definition, resolved, extends, extends_version, created_at";

json ParseOrNull(const std::string& text) {
  try {
    return json::parse(text);
  } catch (const json::exception&) {
    return json();
  }
}

CampaignVersion VersionFromRow(const Statement& st) {
  CampaignVersion v;
  v.name = st.Text(0);
  v.version = static_cast<int>(st.Int(1));
  v.definition = ParseOrNull(st.Text(2));
  v.resolved = ParseOrNull(st.Text(3));
  v.extends = st.Text(4);
  v.extends_version = static_cast<int>(st.OptInt(5).value_or(0));
  v.created_at = st.Double(6);
  v.definition_sha256 = DefinitionSha256(v.resolved);
  return v;
}

Result<std::optional<CampaignVersion>> ReadVersion(Transaction& t, const std::string& name, std::optional<int> version) {
  Statement st = t.Prepare(std::string("SELECT ") + kVersionColumns +
                           " FROM campaign_versions WHERE name = ?1 AND (?2 IS NULL OR version = ?2) "
                           "ORDER BY version DESC LIMIT 1");
  st.Bind(1, name).Bind(2, version);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<CampaignVersion>();
  return std::optional<CampaignVersion>(VersionFromRow(st));
}

}  // namespace

Result<PutVersionResult> PutCampaignVersion(Store& store, const NewCampaignVersion& v) {
  Result<Transaction> t = store.db().Begin();
  if (!t.ok()) return t.status();
  PutVersionResult out;
  std::optional<int> current;
  bool same_columns = false;  // the row's schedule (PutCampaign (campaigns.h) sets it apart)
  {
    Statement st = t->Prepare("SELECT version, schedule FROM campaigns WHERE name = ?");
    st.Bind(1, v.name);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (*row) {
      current = static_cast<int>(st.Int(0));
      same_columns = st.OptText(1) == v.schedule;
    }
  }
  out.created = !current.has_value();
  if (current && same_columns) {
    Result<std::optional<CampaignVersion>> now = ReadVersion(*t, v.name, *current);
    if (!now.ok()) return now.status();
    if (now->has_value() && (*now)->definition == v.definition && (*now)->resolved == v.resolved) {
      out.version = *current;
      out.unchanged = true;
      return out;  // nothing written: the transaction rolls back
    }
  }
  {
    // After the last version ever stored under this name, also when the campaign was deleted.
    Statement st = t->Prepare("SELECT COALESCE(MAX(version), 0) FROM campaign_versions WHERE name = ?");
    st.Bind(1, v.name);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    out.version = static_cast<int>(st.Int(0)) + 1;
  }
  {
    Statement st = t->Prepare(
        "INSERT INTO campaign_versions (name, version, definition, resolved, extends, extends_version, created_at) "
        "VALUES (?, ?, ?, ?, ?, ?, ?)");
    st.Bind(1, v.name).Bind(2, out.version).Bind(3, v.definition.dump()).Bind(4, v.resolved.dump());
    st.Bind(5, v.extends.empty() ? std::optional<std::string>() : std::optional<std::string>(v.extends));
    st.Bind(6, v.extends.empty() ? std::optional<int64_t>() : std::optional<int64_t>(v.extends_version));
    st.Bind(7, v.now);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  {
    // The tolerance column mirrors the resolved definition's field; nothing reads it (campaigns.h).
    auto tolerance = v.resolved.find("drift_tolerance_mps");
    const double tolerance_mps =
        tolerance != v.resolved.end() && tolerance->is_number() ? tolerance->get<double>() : 0.0;
    Statement st = t->Prepare(
        "INSERT INTO campaigns (name, definition, schedule, drift_tolerance_mps, updated_at, version) "
        "VALUES (?, ?, ?, ?, ?, ?) ON CONFLICT (name) DO UPDATE SET definition = excluded.definition,"
        " schedule = excluded.schedule, drift_tolerance_mps = excluded.drift_tolerance_mps,"
        " updated_at = excluded.updated_at, version = excluded.version");
    st.Bind(1, v.name).Bind(2, v.resolved.dump()).Bind(3, v.schedule);
    st.Bind(4, tolerance_mps).Bind(5, v.now).Bind(6, out.version);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  SANDSWIM_RETURN_IF_ERROR(
      t->Event(v.now, "campaign.saved", "campaign/" + v.name, {{"version", out.version}, {"created", out.created}}));
  SANDSWIM_RETURN_IF_ERROR(t->Commit());
  return out;
}

Status PutCampaign(Store& store, const StoredCampaign& c) {
  NewCampaignVersion v;
  v.name = c.name;
  v.definition = c.definition;
  v.resolved = c.definition;
  v.schedule = c.schedule;
  v.now = c.updated_at;
  return PutCampaignVersion(store, v).status();
}

Result<std::vector<CampaignVersion>> ListCampaignVersions(Store& store, const std::string& name) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  Statement st =
      t->Prepare(std::string("SELECT ") + kVersionColumns + " FROM campaign_versions WHERE name = ? ORDER BY version");
  st.Bind(1, name);
  std::vector<CampaignVersion> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out.push_back(VersionFromRow(st));
  }
  return out;
}

Result<std::optional<CampaignVersion>> GetCampaignVersion(Store& store, const std::string& name, int version) {
  Result<Transaction> t = store.db().BeginRead();
  if (!t.ok()) return t.status();
  return ReadVersion(*t, name, version);
}

Status DeleteCampaign(Store& store, const std::string& name, double now) {
  Result<Transaction> t = store.db().Begin();
  if (!t.ok()) return t.status();
  {
    Statement st = t->Prepare("SELECT 1 FROM campaigns WHERE name = ?");
    st.Bind(1, name);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) return Status(StatusCode::kNotFound, "no stored campaign named '" + name + "'", "name");
  }
  {
    // The newest such campaign run: runs are shared, so an older one may show runs a later
    // (forced) rerun requeued.
    Statement st = t->Prepare(
        "SELECT s.campaign_run_id, COUNT(DISTINCT r.id) FROM sweeps s "
        "JOIN campaign_runs cr ON cr.id = s.campaign_run_id "
        "JOIN sweep_runs sr ON sr.sweep_id = s.id JOIN runs r ON r.id = sr.run_id "
        "WHERE cr.campaign = ? AND r.state IN ('queued', 'running') "
        "GROUP BY s.campaign_run_id ORDER BY s.campaign_run_id DESC LIMIT 1");
    st.Bind(1, name);
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (*row) {
      return Status(StatusCode::kConflict,
                    "campaign '" + name + "' has campaign run " + std::to_string(st.Int(0)) + " with " +
                        std::to_string(st.Int(1)) +
                        " run(s) queued or running: cancel its sweeps or wait until they finish, then delete it",
                    "name");
    }
  }
  int64_t schedules = 0;
  {
    Statement st = t->Prepare("DELETE FROM campaign_schedules WHERE campaign = ?");
    st.Bind(1, name);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
    schedules = t->Changes();
  }
  {
    Statement st = t->Prepare("DELETE FROM campaigns WHERE name = ?");
    st.Bind(1, name);
    SANDSWIM_RETURN_IF_ERROR(st.Run());
  }
  SANDSWIM_RETURN_IF_ERROR(t->Event(now, "campaign.deleted", "campaign/" + name, {{"schedule_removed", schedules > 0}}));
  return t->Commit();
}

}  // namespace sandswim
