#include "server/store/schedule_table.h"

namespace sandswim::schedules {

Result<std::vector<ScheduleRow>> ListSchedules(Transaction& t) {
  Statement st = t.Prepare(
      "SELECT s.campaign, s.scale, s.cron, s.enabled, s.first_seen_at, "
      "(SELECT MAX(due_time) FROM campaign_runs cr WHERE cr.campaign = s.campaign AND cr.trigger = 'schedule'), "
      "s.source "
      "FROM campaign_schedules s ORDER BY s.campaign");
  std::vector<ScheduleRow> out;
  while (true) {
    Result<bool> row = st.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    ScheduleRow s;
    s.campaign = st.Text(0);
    s.scale = st.Text(1);
    s.cron = st.Text(2);
    s.enabled = st.Int(3) != 0;
    s.first_seen_at = st.Double(4);
    s.last_due = st.OptDouble(5);
    s.source = st.Text(6);
    out.push_back(std::move(s));
  }
  return out;
}

Result<std::vector<std::string>> EnabledFlagCampaigns(Transaction& t) {
  Statement all = t.Prepare("SELECT campaign FROM campaign_schedules WHERE enabled = 1 AND source = 'flag'");
  std::vector<std::string> out;
  while (true) {
    Result<bool> row = all.Step();
    if (!row.ok()) return row.status();
    if (!*row) break;
    out.push_back(all.Text(0));
  }
  return out;
}

Result<std::optional<double>> LastScheduledDue(Transaction& t, const std::string& campaign) {
  Statement st = t.Prepare("SELECT MAX(due_time) FROM campaign_runs WHERE campaign = ? AND trigger = 'schedule'");
  st.Bind(1, campaign);
  Result<bool> row = st.Step();
  if (!row.ok()) return row.status();
  return *row ? st.OptDouble(0) : std::optional<double>();
}

Status DisableSchedule(Transaction& t, const std::string& campaign, double now) {
  Statement st = t.Prepare("UPDATE campaign_schedules SET enabled = 0, updated_at = ? WHERE campaign = ?");
  st.Bind(1, now).Bind(2, campaign);
  return st.Run();
}

Status RegisterSchedule(Transaction& t, const std::string& campaign, const std::string& scale, const std::string& cron,
                        double now, const std::string& source) {
  Statement st = t.Prepare(
      "INSERT INTO campaign_schedules (campaign, scale, cron, enabled, first_seen_at, updated_at, source) "
      "VALUES (?, ?, ?, 1, ?, ?, ?) ON CONFLICT (campaign) DO UPDATE SET scale = excluded.scale, "
      "cron = excluded.cron, first_seen_at = CASE WHEN enabled = 1 THEN first_seen_at "
      "ELSE excluded.first_seen_at END, "
      "source = CASE WHEN enabled = 1 AND source = 'api' THEN 'api' ELSE excluded.source END, "
      "enabled = 1, updated_at = excluded.updated_at");
  st.Bind(1, campaign).Bind(2, scale).Bind(3, cron).Bind(4, now).Bind(5, now).Bind(6, source);
  return st.Run();
}

Result<bool> RemoveSchedule(Transaction& t, const std::string& campaign) {
  Statement st = t.Prepare("DELETE FROM campaign_schedules WHERE campaign = ?");
  st.Bind(1, campaign);
  SANDSWIM_RETURN_IF_ERROR(st.Run());
  return t.Changes() > 0;
}

}  // namespace sandswim::schedules
