// The results table's SQL, made from the one description of a run's result (core/result_fields.h):
// the SELECT list, the read of a row's result, the INSERT of a result and the re-analysis's
// UPDATE. A field added to the description is selected, read, inserted and (when the analysis
// makes it) rewritten without an edit here; its column comes from a migration (schema/).
//
// Thread safety: free functions; statements belong to the caller's Transaction.
#ifndef SANDSWIM_SERVER_STORE_RESULT_COLUMNS_H_
#define SANDSWIM_SERVER_STORE_RESULT_COLUMNS_H_

#include <cstdint>
#include <optional>
#include <string>

#include "core/result_fields.h"
#include "core/status.h"
#include "server/store/database.h"

namespace sandswim {

// "res.uz, res.uz_stderr, ..., res.created_at": every field's column in ResultFields() order,
// each of the results table aliased "res". ResultFields().size() columns.
const std::string& ResultSelectList();

// The result whose columns a statement selected with ResultSelectList() from column `first` on;
// nullopt when the row has no result (a LEFT JOIN's NULLs: the key is NOT NULL in every result).
std::optional<StoredResult> ReadResult(const Statement& st, int first);

// Inserts (or, for a forced rerun, replaces) the result of run `run_id`.
Status InsertResult(Transaction& t, int64_t run_id, const StoredResult& result);

// Rewrites what the analysis makes (ResultOrigin::kAnalysis) of run `run_id`'s result; the run's
// own figures, how it ran and the stored key and time stay.
Status UpdateAnalysedFields(Statement& prepared, int64_t run_id, const api::RunResult& result);
// The statement UpdateAnalysedFields binds and runs (prepare once per transaction).
std::string UpdateAnalysedFieldsSql();

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_RESULT_COLUMNS_H_
