#include "server/store/campaigns.h"

namespace sandswim {

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
    entry.drift_tolerance_mps = row.drift_tolerance_mps;
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
  entry.drift_tolerance_mps = entry.campaign.drift_tolerance_mps;
  return entry;
}

}  // namespace sandswim
