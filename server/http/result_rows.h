// Result rows as the API sends them: a run's result row as a JSON object and a CSV line
// (core/result_table.h: the two share their columns), the per-point aggregates over replicate
// beds, and the results of a sweep or a campaign run, paged (JSON) or streamed (CSV). Used by the
// routes of sweeps and of campaign runs.
//
// Thread safety: free functions; they read a thread-safe Store.
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

// Rows of a results page when the request names no `limit` (at most kMaxResultsPage, store.h).
inline constexpr int kDefaultResultsPage = 1000;

// What a page's "aggregates" are, as its "aggregates_of" says.
inline constexpr const char* kAggregatesOf =
    "the points whose runs are on this page, each over all of its runs in the set (a point on two pages is on "
    "both, the same)";

// A run's result row (core/result_table.h's columns; a campaign run's row adds "sweeps").
nlohmann::json ResultRowJson(const ResultRow& row, ResultsOf of = ResultsOf::kSweep);

// The answer of GET /api/v1/sweeps/{id}/results (ResultsOf::kSweep) and of
// /api/v1/campaign-runs/{id}/results (kCampaignRun), {id} the path's:
//  - JSON: a page of at most `?limit=` rows (kDefaultResultsPage; 1..kMaxResultsPage) after
//    `?cursor=` (the previous page's next_cursor): {"id", "results": [rows], "next_cursor": text
//    or null, "next": the next page's path (absent on the last page), "aggregates",
//    "aggregates_of"}, and a `Link: <path>; rel="next"` header. "aggregates": the per-point
//    aggregates over replicate beds (core/aggregate.h) of the points whose runs are on this page,
//    each over all of that point's runs in the set (never partial), with its point's fields; a
//    point whose runs two pages share is on both, the same. "aggregates_of" says so (kAggregatesOf).
//    A page costs its own rows and its points' other runs, never the whole set (the first page
//    once aggregated every point of the set: 100,000 runs read for a page of 1,000).
//  - `?format=csv` (or Accept: text/csv): every row, one a line under one header line, streamed
//    a page at a time from the read connections: a daemon holds one page per reader, however
//    large the set. A read that fails after the first page closes the connection before the
//    stream's end (a client sees the transfer cut, never a short file that looks whole).
void SendResults(Call& c, ResultsOf of);

}  // namespace routes
}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_RESULT_ROWS_H_
