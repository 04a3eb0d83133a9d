// Campaign definitions as users write them: a name a campaign may be stored under, and a
// definition that starts from another campaign ("extends") and overrides some of its fields.
//
// A stored campaign keeps two JSON documents per version: the definition as written and the
// definition resolved here (no "extends"), which is what ParseCampaign() reads, what a campaign run
// records and what its claims, report and drift read. Resolving happens once, when a version is
// stored: a later edit of the base makes no new version of the campaigns derived from it (each
// says which version of the base it was made from).
//
// Overrides: every key but "extends" replaces the base's, with two that select as well:
//   "sweeps": [ "baseline", "Omega-sweep", {a new sweep} ]  a string takes the base's sweep of that
//             name, an object is a sweep of this campaign's own; absent: the base's sweeps.
//   "claims": [ "F1", {a new claim} ]                       likewise by claim id; absent: the base's
//             claims whose rules name only sweeps this campaign keeps (each one left out is listed
//             in `notes`, with why).
// Everything else (scale, precision, replicates, schedule, ...) is taken whole from the base unless
// the definition sets it.
//
// Thread safety: pure functions.
#ifndef SANDSWIM_CORE_CAMPAIGN_DEFINITION_H_
#define SANDSWIM_CORE_CAMPAIGN_DEFINITION_H_

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"

namespace sandswim {

inline constexpr size_t kMaxCampaignNameLength = 64;

// `name` as a stored campaign's name: 1 to 64 of A-Z a-z 0-9 . _ - (InvalidArgument on `field`).
Status CheckCampaignName(const std::string& field, const std::string& name);

// The resolved definition of the campaign NAME and the version it is at (0 for a built-in one);
// NotFound when there is none.
struct BaseCampaign {
  nlohmann::json resolved;
  int version = 0;
};
using CampaignLookup = std::function<Result<BaseCampaign>(const std::string& name)>;

struct ResolvedDefinition {
  nlohmann::json resolved;         // no "extends"; not yet validated: ParseCampaign() does that
  std::string extends;             // the base's name, "" when the definition has none
  int extends_version = 0;         // the base's version it was resolved against
  std::vector<std::string> notes;  // what was left out, and why ("claim F4 left out: ...")
};

// `definition` resolved against its base, if it names one. Field paths of refusals are the
// definition's ("sweeps[2]", "extends"); a resolved sweep or claim keeps its index, so what
// ParseCampaign() later names in the resolved definition is the same place in the one written.
Result<ResolvedDefinition> ResolveCampaignDefinition(const nlohmann::json& definition, const CampaignLookup& lookup);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_CAMPAIGN_DEFINITION_H_
