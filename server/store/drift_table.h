// Drift table: the stored drift reports (table drift_reports, schema/002_nightly.sql) and the
// campaign runs they are made for, read and written inside a caller's Transaction. The drift
// report itself (its JSON, its comparison) is server/analysis/drift_report.h's; every SQL
// statement it needs lives here, named after what it does.
//
// Thread safety: free functions over a Transaction, which holds the database's lock.
#ifndef SANDSWIM_SERVER_STORE_DRIFT_TABLE_H_
#define SANDSWIM_SERVER_STORE_DRIFT_TABLE_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/status.h"
#include "server/store/database.h"

namespace sandswim::drift_table {

// The campaign runs without a report whose runs are all terminal, oldest first.
Result<std::vector<int64_t>> FinishedWithoutReport(Transaction& t);

// A stored report (its JSON) and what its campaign run ran (schema/013_campaign_versions.sql:
// "" / nullopt for a campaign run made before definitions were recorded).
struct StoredReport {
  int64_t campaign_run_id = 0;
  std::string report;  // JSON DriftReport
  std::string definition_sha256;
  std::optional<int> campaign_version;
};

// The report of one campaign run; nullopt: none yet.
Result<std::optional<StoredReport>> ReportOf(Transaction& t, int64_t campaign_run_id);
// The latest report of `campaign` at `scale` ("" for any scale); nullopt: none.
Result<std::optional<StoredReport>> Latest(Transaction& t, const std::string& campaign, const std::string& scale);
// The latest report of `campaign` at `scale` of a campaign run before `before_id`; with
// `definition_sha256`, only one whose campaign run ran that definition.
Result<std::optional<StoredReport>> Previous(Transaction& t, const std::string& campaign, const std::string& scale,
                                             int64_t before_id,
                                             const std::optional<std::string>& definition_sha256 = std::nullopt);

struct NewReport {
  int64_t campaign_run_id = 0;
  std::string campaign, scale;
  std::optional<int64_t> previous_campaign_run_id;
  double tolerance_mps = 0;
  int64_t points = 0, reused = 0, ran = 0, missing = 0, drifted = 0;
  std::string report;  // JSON
  double created_at = 0;
};
// Stores `r` unless its campaign run has one already; true when it was stored.
Result<bool> Insert(Transaction& t, const NewReport& r);

}  // namespace sandswim::drift_table

#endif  // SANDSWIM_SERVER_STORE_DRIFT_TABLE_H_
