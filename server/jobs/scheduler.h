// Scheduler: reruns campaigns on their cron schedule (core/cron.h), in the daemon's local time
// zone, through Submit() with trigger "schedule" and due_time = the due minute.
//
// Which campaigns: those registered (Register(), from sandswimd's `--schedule NAME[:SCALE]`),
// recorded in table campaign_schedules (schema/002_nightly.sql) with the scale and the cron
// expression of the campaign (a stored campaign's `schedule` column, else the builtin
// campaign's "schedule"). One schedule per campaign: campaign_runs is unique per
// (campaign, due_time).
//
// When: Tick() looks, for every enabled registration, for the LATEST due time in
// (anchor, now], where anchor = the campaign's last scheduled due time in campaign_runs, or,
// when it has none, the time the daemon first registered it (first_seen_at, kept across
// restarts). At most one rerun per campaign per Tick:
//   - on time: the due minute arrives and the next Tick (every --scheduler-tick s) submits it;
//   - Tick many times in one minute, or restart at the due minute: the anchor is the due time
//     already recorded, so nothing more is submitted (and if two daemons raced, Submit answers
//     the second with the first's campaign run: UNIQUE(campaign, due_time) -> replayed);
//   - daemon down over several due times: at start-up only the latest missed one runs (one
//     catch-up night, not a burst of stale ones); the earlier ones are skipped, and logged.
// A rerun reuses every done run whose content key is unchanged (Submit's rule; no force).
//
// Registration: Register() upserts the given campaigns (first_seen_at is kept for an enabled
// row, reset to now for a new or re-enabled one, so re-enabling after a pause does not run a
// stale night) and, with `exclusive`, disables every other row a flag registered. Put() is the
// REST API's (PUT /api/v1/campaigns/{name}/schedule): a cron of the user's, for a built-in or a
// stored campaign, kept across restarts whatever the flags until Remove() or the campaign's
// deletion (server/store/campaigns.h DeleteCampaign) removes it.
//
// Thread safety: Tick() and Register() may be called from any thread; they serialise on the
// Store. REQUIRES: store and clock outlive the scheduler.
#ifndef SANDSWIM_SERVER_SCHEDULER_H_
#define SANDSWIM_SERVER_SCHEDULER_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/cron.h"
#include "core/status.h"
#include "platform/clock.h"
#include "server/store/store.h"

namespace sandswim {

// "NAME" or "NAME:SCALE" as --schedule takes it.
struct ScheduleRequest {
  std::string campaign;
  std::optional<std::string> scale;  // default: the campaign's
};
// InvalidArgument naming `field` for an empty name, a name outside [A-Za-z0-9._-], or an
// unknown scale.
Result<ScheduleRequest> ParseScheduleFlag(const std::string& text, const std::string& field = "--schedule");

struct ScheduledCampaign {
  std::string campaign;
  std::string scale;
  std::string cron;
  bool enabled = true;
  double first_seen_at = 0;
  std::optional<double> last_due;  // latest scheduled campaign run's due time
  std::optional<double> next_due;  // after max(last_due, first_seen_at, now)
  std::string source;              // "flag" | "api"
};
void to_json(nlohmann::json& j, const ScheduledCampaign& s);

// One rerun a Tick submitted.
struct ScheduledRerun {
  std::string campaign;
  std::string scale;
  double due_time = 0;
  int skipped = 0;  // earlier due times missed while down and not run
  int64_t campaign_run_id = 0;
  bool replayed = false;  // Submit answered with an existing campaign run
  int64_t runs = 0, runs_reused = 0, runs_new = 0, runs_requeued = 0, runs_shared = 0;
};

// What one Tick did: reruns submitted, and registrations that failed (a campaign removed or a
// submission refused); those are retried at the next Tick.
struct TickResult {
  std::vector<ScheduledRerun> submitted;
  std::vector<std::pair<std::string, Status>> errors;  // campaign, why
};

class Scheduler {
 public:
  Scheduler(Store* store, Clock* clock, std::string engine_version, CronZone zone = CronZone::kLocal);

  // Registers campaigns (see the header comment). Errors name `field`: an unknown campaign
  // (kNotFound), a campaign without a schedule or with a bad one, a bad scale, the same
  // campaign twice. Nothing is written unless every request is valid.
  Status Register(const std::vector<ScheduleRequest>& requests, bool exclusive = true,
                  const std::string& field = "--schedule");

  Result<std::vector<ScheduledCampaign>> List();
  // The enabled schedule of `campaign`; nullopt: none.
  Result<std::optional<ScheduledCampaign>> Find(const std::string& campaign);

  // Schedules `campaign` (kNotFound, field "name", when there is no such campaign) by `cron`
  // (kFailedPrecondition naming "cron" when it does not parse) at `scale` (default: the
  // campaign's; kFailedPrecondition naming "scale" when unknown), as the API's (see above).
  Result<ScheduledCampaign> Put(const std::string& campaign, const std::string& cron,
                                const std::optional<std::string>& scale);
  // Removes the schedule of `campaign`; kNotFound (field "schedule") when it has none.
  Status Remove(const std::string& campaign);

  // Submits every due rerun (see the header comment).
  Result<TickResult> Tick();

  CronZone zone() const { return zone_; }

 private:
  Store* store_;
  Clock* clock_;
  std::string engine_version_;
  CronZone zone_;
};

// One line per submitted rerun for the log:
//   "paper-58@smoke night 2026-11-23 02:00: submitted campaign run 7 (58 runs: 56 reused, 2 to run)"
std::string DescribeRerun(const ScheduledRerun& r, CronZone zone);

// The local zone as a user would name it: $TZ if set, else the target of /etc/localtime
// ("Europe/Berlin"), else the abbreviation; with the UTC offset at `now`:
// "Europe/Berlin (CET, UTC+01:00)".
std::string LocalTimeZoneDescription(double now);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_SCHEDULER_H_
