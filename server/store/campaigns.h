// Campaign catalogue: what "the campaign NAME" means to the daemon, in one place. A campaign is
// the definition stored with Store::PutCampaign (a user's, or a built-in one recorded when it was
// first submitted) when there is one, else the built-in one compiled in
// (templates/campaigns/NAME.json, core/sweep.h BuiltinCampaign). Submission, the scheduler, the
// drift reports and the REST routes all look campaigns up here.
//
// Thread safety: a free function over a thread-safe Store.
#ifndef SANDSWIM_SERVER_STORE_CAMPAIGNS_H_
#define SANDSWIM_SERVER_STORE_CAMPAIGNS_H_

#include <optional>
#include <string>

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
  double drift_tolerance_mps = 0;       // the stored row's, else the definition's
};

// kNotFound (field `field`) naming the built-in campaigns when there is no campaign NAME;
// kCorruption when a stored definition no longer parses.
Result<CatalogueEntry> FindCampaign(Store& store, const std::string& name, const std::string& field = "campaign");

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_CAMPAIGNS_H_
