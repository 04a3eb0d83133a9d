#include "server/store/drift_table.h"

namespace sandswim::drift_table {
namespace {

constexpr const char* kReportColumns =
    "d.campaign_run_id, d.report, COALESCE(cr.definition_sha256, ''), cr.campaign_version "
    "FROM drift_reports d JOIN campaign_runs cr ON cr.id = d.campaign_run_id ";

Result<std::optional<StoredReport>> ReadOne(Statement& st) {
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  if (!*row) return std::optional<StoredReport>();
  StoredReport r;
  r.campaign_run_id = st.Int(0);
  r.report = st.Text(1);
  r.definition_sha256 = st.Text(2);
  if (std::optional<int64_t> v = st.OptInt(3)) r.campaign_version = static_cast<int>(*v);
  return std::optional<StoredReport>(std::move(r));
}

}  // namespace

Result<std::vector<int64_t>> FinishedWithoutReport(Transaction& t) {
  Statement st = t.Prepare(
      "SELECT cr.id FROM campaign_runs cr "
      "WHERE NOT EXISTS (SELECT 1 FROM drift_reports d WHERE d.campaign_run_id = cr.id) "
      "  AND NOT EXISTS (SELECT 1 FROM sweeps s JOIN sweep_runs sr ON sr.sweep_id = s.id "
      "                  JOIN runs r ON r.id = sr.run_id "
      "                  WHERE s.campaign_run_id = cr.id AND r.state IN ('queued', 'running')) "
      // An adaptive campaign run (schema/015) is finished when its rounds have stopped, not when a round's runs are.
      "  AND NOT (COALESCE(json_valid(cr.definition), 0) AND json_type(cr.definition, '$.adaptive') IS 'object' "
      "           AND NOT EXISTS (SELECT 1 FROM campaign_rounds rd WHERE rd.campaign_run_id = cr.id "
      "                           AND rd.stop_reason IS NOT NULL)) "
      "ORDER BY cr.id");
  std::vector<int64_t> ids;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    ids.push_back(st.Int(0));
  }
  return ids;
}

Result<std::optional<StoredReport>> ReportOf(Transaction& t, int64_t campaign_run_id) {
  Statement st = t.Prepare(std::string("SELECT ") + kReportColumns + "WHERE d.campaign_run_id = ?");
  st.Bind(1, campaign_run_id);
  return ReadOne(st);
}

Result<std::optional<StoredReport>> Latest(Transaction& t, const std::string& campaign, const std::string& scale) {
  Statement st = t.Prepare(std::string("SELECT ") + kReportColumns +
                           "WHERE d.campaign = ?1 AND (?2 = '' OR d.scale = ?2) ORDER BY d.campaign_run_id DESC LIMIT 1");
  st.Bind(1, campaign).Bind(2, scale);
  return ReadOne(st);
}

Result<std::optional<StoredReport>> Previous(Transaction& t, const std::string& campaign, const std::string& scale,
                                             int64_t before_id, const std::optional<std::string>& definition_sha256) {
  Statement st = t.Prepare(std::string("SELECT ") + kReportColumns +
                           "WHERE d.campaign = ?1 AND d.scale = ?2 AND d.campaign_run_id < ?3 "
                           "AND (?4 IS NULL OR cr.definition_sha256 = ?4) "
                           "ORDER BY d.campaign_run_id DESC LIMIT 1");
  st.Bind(1, campaign).Bind(2, scale).Bind(3, before_id).Bind(4, definition_sha256);
  return ReadOne(st);
}

Result<bool> Insert(Transaction& t, const NewReport& r) {
  Statement st = t.Prepare(
      "INSERT INTO drift_reports (campaign_run_id, campaign, scale, previous_campaign_run_id, "
      "tolerance_mps, points, reused, ran, missing, drifted, report, created_at) "
      "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?) ON CONFLICT (campaign_run_id) DO NOTHING");
  st.Bind(1, r.campaign_run_id).Bind(2, r.campaign).Bind(3, r.scale);
  st.Bind(4, r.previous_campaign_run_id).Bind(5, r.tolerance_mps);
  st.Bind(6, r.points).Bind(7, r.reused).Bind(8, r.ran);
  st.Bind(9, r.missing).Bind(10, r.drifted);
  st.Bind(11, r.report).Bind(12, r.created_at);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  return t.Changes() > 0;
}

}  // namespace sandswim::drift_table
