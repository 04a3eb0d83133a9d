// Schedule table: the rows of campaign schedules (table campaign_schedules) and the scheduled
// campaign runs they made (campaign_runs with trigger 'schedule'), read and written inside a
// caller's Transaction. The scheduler (server/jobs/scheduler.h) decides what is due; every SQL
// statement it needs lives here, named after what it does.
//
// Nothing here commits or logs events: the caller's transaction does, so a registration and its
// audit event stay one atomic change.
//
// Thread safety: free functions over a Transaction, which holds the database's lock.
#ifndef SANDSWIM_SERVER_STORE_SCHEDULE_TABLE_H_
#define SANDSWIM_SERVER_STORE_SCHEDULE_TABLE_H_

#include <optional>
#include <string>
#include <vector>

#include "core/status.h"
#include "server/store/database.h"

namespace sandswim::schedules {

// One registered schedule, with the due time of the last campaign run it made.
struct ScheduleRow {
  std::string campaign;
  std::string scale;
  std::string cron;
  bool enabled = false;
  double first_seen_at = 0;
  std::optional<double> last_due;  // of its newest scheduled campaign run; none yet: nullopt
  std::string source;              // "flag" (sandswimd --schedule) | "api" (PUT .../schedule)
};

// Every schedule, by campaign name.
Result<std::vector<ScheduleRow>> ListSchedules(Transaction& t);
// The campaigns whose schedule is enabled and was registered by a flag (sandswimd --schedule),
// not through the API: the ones a start without their flag disables.
Result<std::vector<std::string>> EnabledFlagCampaigns(Transaction& t);
// The due time of the newest campaign run the schedule of `campaign` made (nullopt: none).
Result<std::optional<double>> LastScheduledDue(Transaction& t, const std::string& campaign);
Status DisableSchedule(Transaction& t, const std::string& campaign, double now);
// Registers (or re-enables, or changes) the schedule of `campaign`: a new or re-enabled
// registration starts now; an enabled one keeps its first_seen_at. `source` "flag" or "api"; a
// flag does not take over an enabled schedule the API registered (it stays the API's).
Status RegisterSchedule(Transaction& t, const std::string& campaign, const std::string& scale, const std::string& cron,
                        double now, const std::string& source = "flag");
// Removes the schedule of `campaign` (its past scheduled campaign runs stay); false: it had none.
Result<bool> RemoveSchedule(Transaction& t, const std::string& campaign);

}  // namespace sandswim::schedules

#endif  // SANDSWIM_SERVER_STORE_SCHEDULE_TABLE_H_
