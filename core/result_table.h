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

#include "core/materials.h"

namespace sandswim {

// The columns of a result row, in order: the run's and its point's, "Uz_text", then the row keys
// of the stored result's fields (core/result_fields.h; a campaign run's rows add "sweeps" at the
// end). A row's
// JSON object carries these, and its point's materials where they are not Table 1's (its point's
// JSON, core/sweep.h PointToJson: a Table 1 row is what it always was).
const std::vector<std::string>& ResultColumns();

// The CSV's columns: ResultColumns(), then all ten materials of core/materials.h, each named with
// its unit (MaterialCsvColumn: "so_density_kg_m3", "so_diameter_m", "grain_friction"). All ten, not
// those that differ from Table 1: the header is streamed before the rows are read, a CSV's columns
// do not change with its sweep (CSVs of several sweeps stack), and a cell is the value the run
// had (Table 1's where its point set none), never an empty cell that reads as "unknown". At the
// end, so that the columns before them keep their places.
const std::vector<std::string>& ResultCsvColumns();
// "<name>_<unit>" with the unit's '/' as '_' and without '^' (kg/m^3: "kg_m3"); the name alone
// for a dimensionless one.
std::string MaterialCsvColumn(const MaterialField& field);
// A row's JSON object with its materials under their CSV columns (Table 1's where it has none).
nlohmann::json ResultCsvRow(const nlohmann::json& row);

// One CSV cell: null is empty, an array is its items joined by ';', numbers in their shortest
// round-trip form, strings quoted (RFC 4180) when they hold a comma, a quote or a line break.
std::string CsvCell(const nlohmann::json& value);

// A header line of `columns`, then one line per row (a row missing a column gets an empty cell).
std::string RowsToCsv(const std::vector<nlohmann::json>& rows, const std::vector<std::string>& columns);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_RESULT_TABLE_H_
