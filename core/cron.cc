#include "core/cron.h"

#include <time.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <sstream>
#include <tuple>
#include <vector>

namespace sandswim {
namespace {

struct FieldSpec {
  const char* name;
  int lo, hi;
};
constexpr FieldSpec kFields[5] = {
    {"minute", 0, 59}, {"hour", 0, 23}, {"day-of-month", 1, 31}, {"month", 1, 12}, {"day-of-week", 0, 7}};

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : s) {
    if (c == sep) {
      out.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(cur);
  return out;
}

// A small non-negative decimal; false for anything else (signs, blanks, overflow).
bool ParseNumber(const std::string& s, int* v) {
  if (s.empty() || s.size() > 4) return false;
  int n = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    n = n * 10 + (c - '0');
  }
  *v = n;
  return true;
}

// Sets the bits one cron field names (indexes lo..hi of FieldSpec).
Status ParseField(const std::string& text, const FieldSpec& spec, const std::string& field, const std::string& whole,
                  std::vector<bool>* bits) {
  auto bad = [&](const std::string& why) {
    return Status::InvalidArgument(field, std::string(spec.name) + ": " + why + " in \"" + whole +
                                              "\" (fields: minute hour day-of-month month day-of-week)");
  };
  bits->assign(spec.hi + 1, false);
  for (const std::string& item : Split(text, ',')) {
    if (item.empty()) return bad("empty list item in \"" + text + "\"");
    std::vector<std::string> parts = Split(item, '/');
    if (parts.size() > 2) return bad("more than one '/' in \"" + item + "\"");
    int step = 1;
    if (parts.size() == 2 && (!ParseNumber(parts[1], &step) || step < 1)) {
      return bad("step \"" + parts[1] + "\" must be a positive integer");
    }
    int lo = spec.lo, hi = spec.hi;
    const std::string& base = parts[0];
    if (base != "*") {
      std::vector<std::string> range = Split(base, '-');
      if (range.size() > 2) return bad("\"" + base + "\" is not N or N-M");
      if (!ParseNumber(range[0], &lo)) return bad("\"" + range[0] + "\" is not a number");
      if (range.size() == 2) {
        if (!ParseNumber(range[1], &hi)) return bad("\"" + range[1] + "\" is not a number");
      } else if (parts.size() == 1) {
        hi = lo;  // "N" alone; "N/STEP" runs to the field's maximum
      }
      for (int v : {lo, hi}) {
        if (v < spec.lo || v > spec.hi) {
          return bad(std::to_string(v) + " is out of range " + std::to_string(spec.lo) + "-" + std::to_string(spec.hi));
        }
      }
      if (lo > hi) return bad("range " + base + " runs backwards");
    }
    for (int v = lo; v <= hi; v += step) (*bits)[v] = true;
  }
  return Status::Ok();
}

// ---- Civil dates (proleptic Gregorian), after H. Hinnant's days_from_civil ----------------------

int64_t DaysFromCivil(int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<int64_t>(doe) - 719468;
}

void CivilFromDays(int64_t z, int* y, int* m, int* d) {
  z += 719468;
  const int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const unsigned doe = static_cast<unsigned>(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  *d = static_cast<int>(doy - (153 * mp + 2) / 5 + 1);
  *m = static_cast<int>(mp < 10 ? mp + 3 : mp - 9);
  *y = static_cast<int>(static_cast<int64_t>(yoe) + era * 400 + (*m <= 2));
}

// ---- Wall clock --------------------------------------------------------------------------------

struct Wall {
  int y, mo, d, h, mi;
  auto tie() const { return std::tie(y, mo, d, h, mi); }
  bool operator<(const Wall& o) const { return tie() < o.tie(); }
  bool operator==(const Wall& o) const { return tie() == o.tie(); }
};

Wall ToWall(int64_t t, CronZone zone) {
  time_t tt = static_cast<time_t>(t);
  struct tm tm {};
  if (zone == CronZone::kUtc) {
    gmtime_r(&tt, &tm);
  } else {
    localtime_r(&tt, &tm);
  }
  return {tm.tm_year + 1900, tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min};
}

int64_t FromWall(const Wall& w, int isdst, CronZone zone) {
  struct tm tm {};
  tm.tm_year = w.y - 1900;
  tm.tm_mon = w.mo - 1;
  tm.tm_mday = w.d;
  tm.tm_hour = w.h;
  tm.tm_min = w.mi;
  tm.tm_isdst = isdst;
  return zone == CronZone::kUtc ? static_cast<int64_t>(timegm(&tm)) : static_cast<int64_t>(mktime(&tm));
}

// The earliest instant whose wall-clock reading is >= w (the header's DST rule).
int64_t Due(const Wall& w, CronZone zone) {
  if (zone == CronZone::kUtc) return FromWall(w, 0, zone);
  int64_t best = INT64_MAX, lowest = INT64_MAX;
  for (int isdst : {0, 1, -1}) {
    int64_t t = FromWall(w, isdst, zone);
    if (t == -1) continue;
    lowest = std::min(lowest, t);
    if (ToWall(t, zone) == w) best = std::min(best, t);
  }
  if (best != INT64_MAX) return best;  // exists (its first occurrence when it occurs twice)
  // Skipped by a forward jump: walk from before the gap to where the wall clock passes w.
  int64_t t = lowest == INT64_MAX ? FromWall(w, 0, zone) : lowest;
  t -= 3 * 3600;
  t -= ((t % 60) + 60) % 60;
  for (int i = 0; i < 48 * 60; ++i, t += 60) {
    if (!(ToWall(t, zone) < w)) return t;
  }
  return t;
}

bool DayMatches(const CronSchedule& s, int y, int mo, int d, int64_t days) {
  if (!s.months[mo]) return false;
  int dow = static_cast<int>(((days + 4) % 7 + 7) % 7);  // 1970-01-01 was a Thursday
  bool dom = s.days_of_month[d];
  bool dw = s.days_of_week[dow];
  (void)y;
  if (s.dom_restricted && s.dow_restricted) return dom || dw;
  return dom && dw;
}

}  // namespace

Result<CronSchedule> ParseCron(const std::string& text, const std::string& field) {
  std::vector<std::string> fields;
  {
    std::istringstream in(text);
    std::string f;
    while (in >> f) fields.push_back(f);
  }
  if (fields.size() != 5 || text.size() > 200) {
    return Status::InvalidArgument(field, "\"" + text +
                                              "\" must have five fields: minute hour day-of-month "
                                              "month day-of-week, e.g. \"0 2 * * *\"");
  }
  CronSchedule s;
  for (size_t i = 0; i < 5; ++i) s.text += (i ? " " : "") + fields[i];
  std::vector<bool> bits;
  for (size_t i = 0; i < 5; ++i) {
    SANDSWIM_RETURN_IF_ERROR(ParseField(fields[i], kFields[i], field, s.text, &bits));
    for (size_t v = 0; v < bits.size(); ++v) {
      if (!bits[v]) continue;
      switch (i) {
        case 0:
          s.minutes.set(v);
          break;
        case 1:
          s.hours.set(v);
          break;
        case 2:
          s.days_of_month.set(v);
          break;
        case 3:
          s.months.set(v);
          break;
        case 4:
          s.days_of_week.set(v % 7);
          break;
      }
    }
  }
  s.dom_restricted = fields[2][0] != '*';
  s.dow_restricted = fields[4][0] != '*';
  return s;
}

Result<double> NextDue(const CronSchedule& s, double after, CronZone zone) {
  const int64_t after_s = static_cast<int64_t>(std::floor(after));
  const Wall start = ToWall(after_s, zone);
  const int64_t first_day = DaysFromCivil(start.y, start.mo, start.d);
  for (int64_t k = 0; k <= 8 * 366; ++k) {
    int y, mo, d;
    CivilFromDays(first_day + k, &y, &mo, &d);
    if (!DayMatches(s, y, mo, d, first_day + k)) continue;
    for (int h = 0; h < 24; ++h) {
      if (!s.hours[h]) continue;
      for (int mi = 0; mi < 60; ++mi) {
        if (!s.minutes[mi]) continue;
        Wall w{y, mo, d, h, mi};
        if (!(start < w)) continue;  // due(w) <= after whenever w <= wall(after)
        int64_t t = Due(w, zone);
        if (static_cast<double>(t) > after) return static_cast<double>(t);
      }
    }
  }
  return Status::NotFound("schedule \"" + s.text + "\" is never due in the next eight years");
}

Result<std::optional<double>> LatestDueIn(const CronSchedule& s, double after, double until, CronZone zone) {
  if (!(until > after)) return std::optional<double>();
  // Look back over growing windows so that a long outage costs no more than the last few matches.
  for (double window : {86400.0, 8 * 86400.0, 64 * 86400.0, 512 * 86400.0, 4096 * 86400.0}) {
    const double lo = std::max(after, until - window);
    std::optional<double> latest;
    double t = lo;
    while (true) {
      Result<double> next = NextDue(s, t, zone);
      if (!next.ok() || *next > until) break;
      latest = *next;
      t = *next;
    }
    if (latest || lo == after) return latest;
  }
  return std::optional<double>();
}

std::string FormatWallMinute(double t, CronZone zone) {
  Wall w = ToWall(static_cast<int64_t>(std::floor(t)), zone);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02d %02d:%02d", w.y, w.mo, w.d, w.h, w.mi);
  return buf;
}

}  // namespace sandswim
