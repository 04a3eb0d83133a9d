// Cron: five-field cron expressions (the schedule a campaign carries) and when they are next due.
//
// Syntax (Vixie cron's, numbers only): "minute hour day-of-month month day-of-week", fields
// separated by blanks. Each field is a comma-separated list of items; an item is "*", "N",
// "N-M", each optionally followed by "/STEP" ("*/15", "1-10/3"); "N/STEP" means "N-max/STEP".
// Ranges: minute 0-59, hour 0-23, day-of-month 1-31, month 1-12, day-of-week 0-7 (0 and 7 are
// Sunday). The day rule is cron's: when both day-of-month and day-of-week are restricted (their
// field does not start with "*"), a day matches if EITHER matches; otherwise both must match
// (an unrestricted field matches every day).
//
// Time zones: NextDue() works in wall-clock time of a zone: kLocal is the process's local zone
// (TZ, else /etc/localtime, through localtime_r/mktime), kUtc is UTC. The DST rule is one
// definition for every wall time W of a matching day:
//     due(W) = the earliest instant whose wall-clock reading is >= W.
// So an ordinary time fires once; a time that occurs twice when clocks go back fires at its
// FIRST occurrence only; a time that does not exist when clocks go forward (02:30 on the
// spring-forward night in Europe) fires at the instant the gap ends (03:00 summer time), and
// several missing times of one gap collapse into that one firing. No night is lost or doubled.
//
// Thread safety: pure functions (localtime_r/mktime read the process's zone; do not change TZ
// while another thread calls NextDue with kLocal).
#ifndef SANDSWIM_CORE_CRON_H_
#define SANDSWIM_CORE_CRON_H_

#include <bitset>
#include <optional>
#include <string>

#include "core/status.h"

namespace sandswim {

struct CronSchedule {
  std::string text;  // as given (trimmed)
  std::bitset<60> minutes;
  std::bitset<24> hours;
  std::bitset<32> days_of_month;  // bit 0 unused
  std::bitset<13> months;         // bit 0 unused
  std::bitset<7> days_of_week;    // 0 = Sunday (7 folded onto 0)
  bool dom_restricted = false;    // field does not start with '*'
  bool dow_restricted = false;
};

// Parses a five-field expression. Errors are kInvalidArgument naming `field` (default
// "schedule"), with the offending cron field in the reason ("hour: 24 is out of range 0-23").
Result<CronSchedule> ParseCron(const std::string& text, const std::string& field = "schedule");

enum class CronZone { kLocal, kUtc };

// The first due instant strictly after `after` (seconds since the epoch), on a whole minute of
// the zone's wall clock, under the DST rule above. kNotFound when nothing is due in the next
// eight years (e.g. "0 0 31 2 *").
Result<double> NextDue(const CronSchedule& schedule, double after, CronZone zone = CronZone::kLocal);

// The latest due instant in (after, until], or nothing when none is. Used to run only the most
// recent of several missed due times.
Result<std::optional<double>> LatestDueIn(const CronSchedule& schedule, double after, double until,
                                          CronZone zone = CronZone::kLocal);

// "2026-11-23 02:00" in the zone's wall clock (logs and reports).
std::string FormatWallMinute(double t, CronZone zone = CronZone::kLocal);

}  // namespace sandswim

#endif  // SANDSWIM_CORE_CRON_H_
