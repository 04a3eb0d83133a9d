// Campaign edits: a user's campaign checked and stored as a new version, or deleted (the
// REST API's PUT and DELETE /api/v1/campaigns/{name}). The versions themselves, and what
// "the campaign NAME" means, are the store's (server/store/campaigns.h); this is the checking in
// front of them, so that nothing is stored that would be refused later:
//   1. the name (core/campaign_definition.h CheckCampaignName), not a built-in campaign's
//      (built-in campaigns are read-only: kConflict, saying how to make one's own copy);
//   2. "extends" resolved against the base's current version (ResolveCampaignDefinition);
//   3. the resolved definition parsed (core/sweep.h ParseCampaign: sweeps, claims and their rule
//      kinds and parameters);
//   4. its plan at each scale (core/sweep.h PlanSubmission): over the submission cap at the
//      campaign's own scale, or over the daemon's queue cap, is refused now, not at the first
//      nightly run.
// Refusals name the definition's own field ("sweeps[2].axes[0].values", "claims[0].rule",
// "extends", "name"): kFailedPrecondition (HTTP 422) for a definition that does not hold,
// kConflict for a built-in name. Nothing is stored on a refusal.
//
// Thread safety: free functions over a thread-safe Store.
#ifndef SANDSWIM_SERVER_JOBS_CAMPAIGN_EDITS_H_
#define SANDSWIM_SERVER_JOBS_CAMPAIGN_EDITS_H_

#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "core/sweep.h"
#include "server/jobs/submission.h"
#include "server/store/campaigns.h"
#include "server/store/store.h"

namespace sandswim {

// True for a campaign compiled into the binaries (core/sweep.h BuiltinCampaignNames).
bool IsBuiltinCampaign(const std::string& name);

// A definition that holds: resolved, parsed and planned.
struct CheckedCampaign {
  nlohmann::json definition;  // as written
  nlohmann::json resolved;    // its "name" is the campaign's
  std::string extends;
  int extends_version = 0;
  std::vector<std::string> notes;  // from resolving (claims of the base left out, and why)
  Campaign campaign;
  // Runs a submission of it makes at each scale (smoke, mini, paper); null at a scale where it
  // would be past the cap (refused at PUT only at its own scale).
  nlohmann::json planned_runs;
};

// Steps 1-4 above for `definition` stored as `name`. `engine_version` enters the plans' keys.
Result<CheckedCampaign> CheckCampaign(Store& store, const std::string& name, const nlohmann::json& definition,
                                      const std::string& engine_version,
                                      size_t max_runs = kMaxRunsPerSubmission,
                                      int64_t max_queued_runs = kMaxQueuedRuns);

// {"smoke": n|null, "mini": n|null, "paper": n|null}: the runs a submission of `campaign` makes at
// each scale (null where it is past `max_runs` or the scale cannot take its points).
nlohmann::json PlannedRunsAtEachScale(const Campaign& campaign, const std::string& engine_version,
                                      size_t max_runs = kMaxRunsPerSubmission);

struct SavedCampaign {
  std::string name;
  int version = 0;
  bool created = false;
  bool unchanged = false;
  std::vector<std::string> notes;
  nlohmann::json planned_runs;
};
// {"name","version","created","unchanged","notes":[...],"planned_runs":{...}}
void to_json(nlohmann::json& j, const SavedCampaign& s);

// CheckCampaign, then the store's new version (or "unchanged"), in one transaction.
Result<SavedCampaign> SaveCampaign(Store& store, const std::string& name, const nlohmann::json& definition,
                                   const std::string& engine_version, double now,
                                   int64_t max_queued_runs = kMaxQueuedRuns);

// The notes PUT answered when it stored `v` (what resolving its "extends" left out, and why), made
// again by the same code: `v`'s definition as written, resolved against the version of its base it
// was resolved against then (a built-in base: its file). None are stored; GET shows these. A
// version whose resolving no longer works (a built-in base's file changed since) gets one note that
// says so.
Result<std::vector<std::string>> NotesOf(Store& store, const CampaignVersion& v);

// Deletes the stored campaign `name` with its schedule (server/store/campaigns.h DeleteCampaign);
// kConflict for a built-in one.
Status RemoveCampaign(Store& store, const std::string& name, double now);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_JOBS_CAMPAIGN_EDITS_H_
