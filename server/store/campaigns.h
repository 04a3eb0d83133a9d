// Campaign catalogue: what "the campaign NAME" means to the daemon, in one place. A campaign is
// the current version of the definition stored under NAME (a user's, PutCampaignVersion; or one
// recorded by PutCampaign) when there is one, else the built-in one compiled in
// (templates/campaigns/NAME.json, core/sweep.h BuiltinCampaign; version 0, never stored).
// Submission, the scheduler, the drift reports and the REST routes all look campaigns up here.
//
// Versions (table campaign_versions, schema/013_campaign_versions.sql): every change of a stored
// campaign is a new version 1, 2, ...; each keeps the definition as written and as resolved
// (core/campaign_definition.h: no "extends"), which is what runs. Deleting a campaign keeps its
// versions (its past campaign runs name them); storing it again goes on from the last version.
//
// The drift tolerance has one home, the definition's `drift_tolerance_mps`: a campaign run's drift
// report holds it to the tolerance of the definition that run recorded (server/analysis/
// drift_report.cc DriftToleranceOf). The column campaigns.drift_tolerance_mps (schema/001) is
// written from the resolved definition with each version, for whoever reads the file, and read by
// nothing here: there is no operator override of it (sandswimd has no such flag).
//
// Thread safety: free functions over a thread-safe Store; each write is one transaction.
#ifndef SANDSWIM_SERVER_STORE_CAMPAIGNS_H_
#define SANDSWIM_SERVER_STORE_CAMPAIGNS_H_

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "core/sweep.h"
#include "server/store/store.h"

namespace sandswim {

struct CatalogueEntry {
  Campaign campaign;                    // parsed (its sweeps at the campaign's own scale)
  nlohmann::json definition;            // as stored, or the built-in file's JSON
  bool stored = false;                  // false: the built-in one, not yet recorded in the store
  std::optional<std::string> schedule;  // the stored row's, else the definition's
  int version = 0;                      // the stored campaign's current version; 0: built-in
};

// The SHA-256 (hex) of a resolved definition's canonical dump (keys sorted, no spaces): what a
// campaign run records beside the definition it ran, and what drift compares.
std::string DefinitionSha256(const nlohmann::json& resolved);

// One stored version of a campaign.
struct CampaignVersion {
  std::string name;
  int version = 0;
  nlohmann::json definition;  // as written
  nlohmann::json resolved;    // as it runs
  std::string extends;        // "" when it extends none
  int extends_version = 0;
  double created_at = 0;
  std::string definition_sha256;  // DefinitionSha256(resolved)
};
// {"version","created_at","extends"(string|null),"extends_version"(int|null),"definition_sha256"}
void to_json(nlohmann::json& j, const CampaignVersion& v);

// A version to store. REQUIRES: `resolved` parses (ParseCampaign) and names `name`; `schedule`
// is the resolved definition's.
struct NewCampaignVersion {
  std::string name;
  nlohmann::json definition;
  nlohmann::json resolved;
  std::string extends;
  int extends_version = 0;
  std::optional<std::string> schedule;
  double now = 0;
};
struct PutVersionResult {
  int version = 0;
  bool created = false;    // the campaign was not stored before
  bool unchanged = false;  // as written and as resolved equal to the current version: no new one
};
// One transaction: a new version (the last one + 1) made current, unless the definition as
// written and as resolved equal the current version's (then nothing changes: `unchanged`).
Result<PutVersionResult> PutCampaignVersion(Store& store, const NewCampaignVersion& v);

// Stores `c.definition` as the next version of the campaign, as written and as resolved alike,
// with `c`'s schedule column (tests and benchmarks; the REST API checks and
// resolves a definition first: server/jobs/campaign_edits.h SaveCampaign).
Status PutCampaign(Store& store, const StoredCampaign& c);

// Every version of NAME, oldest first (also after the campaign was deleted); empty: none.
Result<std::vector<CampaignVersion>> ListCampaignVersions(Store& store, const std::string& name);
// Version `version` of NAME; nullopt when there is none.
Result<std::optional<CampaignVersion>> GetCampaignVersion(Store& store, const std::string& name, int version);

// Removes the stored campaign NAME and its schedule in one transaction; its versions and its
// campaign runs stay. kNotFound (field "name") when none is stored; kConflict (field "name") while
// a run of one of its campaign runs is queued or running, naming that campaign run, and then
// nothing changes.
Status DeleteCampaign(Store& store, const std::string& name, double now);

// kNotFound (field `field`) naming the built-in campaigns when there is no campaign NAME;
// kCorruption when a stored definition no longer parses.
Result<CatalogueEntry> FindCampaign(Store& store, const std::string& name, const std::string& field = "campaign");

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_CAMPAIGNS_H_
