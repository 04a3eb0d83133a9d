// The results table: one row per run, the same columns in the REST API's JSON and CSV
// (GET /api/v1/sweeps/{id}/results, campaign runs' results) and in `sandswim results`, so that
// `sandswim results --format csv` is byte for byte the daemon's `?format=csv`.
//
// Thread safety: pure functions; the column list is a constant.
#ifndef SANDSWIM_CORE_RESULT_TABLE_H_
#define SANDSWIM_CORE_RESULT_TABLE_H_

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace sandswim {

// The columns of a result row, in order (a campaign run's rows add "sweeps" at the end).
const std::vector<std::string>& ResultColumns();

// One CSV cell: null is empty, an array is its items joined by ';', numbers in their shortest
// round-trip form, strings quoted (RFC 4180) when they hold a comma, a quote or a line break.
std::string CsvCell(const nlohmann::json& value);

// A header line of `columns`, then one line per row (a row missing a column gets an empty cell).
std::string RowsToCsv(const std::vector<nlohmann::json>& rows, const std::vector<std::string>& columns);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_RESULT_TABLE_H_
