// Result rows as the API sends them: a run's result row as a JSON object and a CSV line
// (core/result_table.h: the two share their columns), the per-point aggregates over replicate
// beds, and a campaign run's distinct runs. Used by the routes of sweeps and of campaign runs.
//
// Thread safety: free functions; CampaignRunRows reads a thread-safe Store.
#ifndef SANDSWIM_SERVER_HTTP_RESULT_ROWS_H_
#define SANDSWIM_SERVER_HTTP_RESULT_ROWS_H_

#include <cstdint>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/status.h"
#include "server/http/call.h"
#include "server/store/store.h"

namespace sandswim {
namespace routes {

nlohmann::json ResultRowJson(const ResultRow& row);
// The per-point aggregates over replicate beds (core/aggregate.h) of these runs, each with its
// point's fields.
nlohmann::json AggregatesJson(const std::vector<ResultRow>& rows);
// `?format=csv`: the runs, one a line (core/result_table.h); JSON: {"id", "results", "aggregates"}.
void SendRows(Call& c, int64_t id, const std::vector<nlohmann::json>& rows, const std::vector<ResultRow>& distinct,
              bool with_sweeps);
// A campaign run's distinct runs, each naming the sweeps it belongs to (`distinct`: the same runs,
// as read).
Result<std::vector<nlohmann::json>> CampaignRunRows(Store& store, const CampaignRunInfo& info,
                                                    std::vector<ResultRow>* distinct = nullptr);

}  // namespace routes
}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_RESULT_ROWS_H_
