#include "server/jobs/campaign_edits.h"

#include <algorithm>

#include "core/adaptive.h"
#include "core/campaign_definition.h"
#include "core/scale.h"
#include "server/store/campaigns.h"
#include "server/store/rounds.h"

namespace sandswim {

using nlohmann::json;

namespace {

constexpr const char* kScales[] = {"smoke", "mini", "paper"};

// A definition that does not hold is 422 whatever the core calls it; the field stays.
Status Unprocessable(const Status& s) {
  if (s.code() != StatusCode::kInvalidArgument) return s;
  return Status(StatusCode::kFailedPrecondition, s.reason(), s.field());
}

Status BuiltinIsReadOnly(const std::string& name) {
  return Status(StatusCode::kConflict,
                "campaign '" + name + "' is built in and read-only: make your own copy, e.g. PUT /api/v1/campaigns/mine " +
                    "with {\"name\": \"mine\", \"extends\": \"" + name + "\"}, and change what you need in it",
                "name");
}

// The runs a submission of `campaign` makes at `scale` (Submit's plan), or its refusal.
Result<int64_t> PlannedRuns(const Campaign& campaign, const std::string& scale, const std::string& engine_version,
                            size_t max_runs) {
  std::vector<SweepSpec> sweeps = campaign.sweeps;
  for (SweepSpec& s : sweeps) s.scale = scale;
  PlanOptions options;
  options.max_runs = max_runs;
  options.keep_decks = false;
  options.threads = 2;
  Result<std::vector<ScalePlan>> planned = PlanSubmission(sweeps, engine_version, options, /*campaign=*/true);
  if (!planned.ok()) return planned.status();
  int64_t runs = 0;
  for (const ScalePlan& g : *planned) runs += static_cast<int64_t>(g.plan.runs.size());
  return runs;
}

}  // namespace

bool IsBuiltinCampaign(const std::string& name) {
  const std::vector<std::string> names = BuiltinCampaignNames();
  return std::find(names.begin(), names.end(), name) != names.end();
}

Result<CheckedCampaign> CheckCampaign(Store& store, const std::string& name, const json& definition,
                                      const std::string& engine_version, size_t max_runs, int64_t max_queued_runs) {
  SANDSWIM_RETURN_IF_ERROR(Unprocessable(CheckCampaignName("name", name)));
  if (IsBuiltinCampaign(name)) return BuiltinIsReadOnly(name);
  if (!definition.is_object()) {
    return Status(StatusCode::kFailedPrecondition, "must be a JSON object (a campaign definition)", "");
  }
  if (auto it = definition.find("name"); it != definition.end() && (!it->is_string() || *it != name)) {
    return Status(StatusCode::kFailedPrecondition,
                  "is " + it->dump() + " but the campaign is stored as \"" + name + "\": leave it out or make them equal",
                  "name");
  }
  CampaignLookup lookup = [&store](const std::string& base) -> Result<BaseCampaign> {
    Result<CatalogueEntry> found = FindCampaign(store, base, "extends");
    if (!found.ok()) return found.status();
    return BaseCampaign{found->definition, found->version};
  };
  Result<ResolvedDefinition> resolved = ResolveCampaignDefinition(definition, lookup);
  if (!resolved.ok()) return Unprocessable(resolved.status());
  CheckedCampaign out;
  out.definition = definition;
  out.resolved = std::move(resolved->resolved);
  out.resolved["name"] = name;
  out.extends = resolved->extends;
  out.extends_version = resolved->extends_version;
  out.notes = std::move(resolved->notes);
  Result<Campaign> parsed = ParseCampaign(out.resolved);
  if (!parsed.ok()) return Unprocessable(parsed.status());
  out.campaign = std::move(parsed).value();

  // Its own scale's plan decides: past the submission cap or the daemon's queue, refused now.
  Result<int64_t> own = PlannedRuns(out.campaign, out.campaign.scale, engine_version, max_runs);
  if (!own.ok()) {
    const Status& s = own.status();
    return Status(StatusCode::kFailedPrecondition, "at its scale " + out.campaign.scale + ": " + s.reason(),
                  s.field().empty() ? "sweeps" : s.field());
  }
  if (*own > max_queued_runs) {
    return Status(StatusCode::kFailedPrecondition,
                  "plans " + std::to_string(*own) + " runs at its scale " + out.campaign.scale +
                      ", more than the daemon's queue holds (" + std::to_string(max_queued_runs) +
                      ", sandswimd --max-queued-runs): fewer points, beds or sweeps",
                  "sweeps");
  }
  out.planned_runs = PlannedRunsAtEachScale(out.campaign, engine_version, max_runs);
  return out;
}

json PlannedRunsAtEachScale(const Campaign& campaign, const std::string& engine_version, size_t max_runs) {
  json out = json::object();
  for (const char* scale : kScales) {
    Result<int64_t> runs = PlannedRuns(campaign, scale, engine_version, max_runs);
    out[scale] = runs.ok() ? json(*runs) : json(nullptr);
  }
  return out;
}

void to_json(json& j, const SavedCampaign& s) {
  j = {{"name", s.name},          {"version", s.version}, {"created", s.created},
       {"unchanged", s.unchanged}, {"notes", s.notes},     {"planned_runs", s.planned_runs}};
}

Result<SavedCampaign> SaveCampaign(Store& store, const std::string& name, const json& definition,
                                   const std::string& engine_version, double now, int64_t max_queued_runs) {
  Result<CheckedCampaign> checked =
      CheckCampaign(store, name, definition, engine_version, kMaxRunsPerSubmission, max_queued_runs);
  if (!checked.ok()) return checked.status();
  // An adaptive campaign's budget must pay for its first round at the cost model's rates now.
  if (checked->campaign.adaptive) {
    Result<AdaptiveCost> cost = rounds::AdaptiveCostNow(store, checked->campaign.scale, now);
    if (!cost.ok()) return cost.status();
    SANDSWIM_RETURN_IF_ERROR(Unprocessable(CheckAdaptiveBudget(checked->campaign, checked->campaign.scale, *cost)));
  }
  NewCampaignVersion v;
  v.name = name;
  v.definition = checked->definition;
  v.resolved = checked->resolved;
  v.extends = checked->extends;
  v.extends_version = checked->extends_version;
  v.schedule = checked->campaign.schedule;
  v.now = now;
  Result<PutVersionResult> put = PutCampaignVersion(store, v);
  if (!put.ok()) return put.status();
  SavedCampaign out;
  out.name = name;
  out.version = put->version;
  out.created = put->created;
  out.unchanged = put->unchanged;
  out.notes = std::move(checked->notes);
  out.planned_runs = std::move(checked->planned_runs);
  return out;
}

Result<std::vector<std::string>> NotesOf(Store& store, const CampaignVersion& v) {
  if (v.extends.empty()) return std::vector<std::string>();
  CampaignLookup then = [&store, &v](const std::string& base) -> Result<BaseCampaign> {
    if (v.extends_version == 0) {
      Result<json> builtin = BuiltinCampaignDefinition(base);
      if (!builtin.ok()) return builtin.status();
      return BaseCampaign{*builtin, 0};
    }
    Result<std::optional<CampaignVersion>> found = GetCampaignVersion(store, base, v.extends_version);
    if (!found.ok()) return found.status();
    if (!found->has_value()) {
      return Status::NotFound("campaign '" + base + "' has no version " + std::to_string(v.extends_version));
    }
    return BaseCampaign{(*found)->resolved, v.extends_version};
  };
  Result<ResolvedDefinition> resolved = ResolveCampaignDefinition(v.definition, then);
  if (!resolved.ok()) {
    const StatusCode code = resolved.status().code();
    if (code != StatusCode::kInvalidArgument && code != StatusCode::kNotFound) return resolved.status();
    return std::vector<std::string>{"the notes of version " + std::to_string(v.version) +
                                    " cannot be made again: its base " + v.extends + " no longer resolves it (" +
                                    resolved.status().ToString() + ")"};
  }
  return std::move(resolved->notes);
}

Status RemoveCampaign(Store& store, const std::string& name, double now) {
  if (IsBuiltinCampaign(name)) {
    return Status(StatusCode::kConflict, "campaign '" + name + "' is built in and read-only: it cannot be deleted",
                  "name");
  }
  return DeleteCampaign(store, name, now);
}

}  // namespace sandswim
