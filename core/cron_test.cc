#include "core/cron.h"

#include <stdlib.h>
#include <time.h>

#include <string>

#include <gtest/gtest.h>

namespace sandswim {
namespace {

double Utc(int y, int mo, int d, int h, int mi, int s = 0) {
  struct tm tm {};
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  tm.tm_sec = s;
  return static_cast<double>(timegm(&tm));
}

CronSchedule Cron(const std::string& text) {
  auto c = ParseCron(text);
  EXPECT_TRUE(c.ok()) << c.status().ToString();
  return c.ok() ? *c : CronSchedule{};
}

double Next(const std::string& text, double after, CronZone zone = CronZone::kUtc) {
  auto t = NextDue(Cron(text), after, zone);
  EXPECT_TRUE(t.ok()) << t.status().ToString();
  return t.ok() ? *t : 0;
}

TEST(ParseCronTest, FieldsListsRangesSteps) {
  CronSchedule c = Cron("*/15 9-17 * * 1-5");
  EXPECT_EQ(c.minutes.count(), 4u);
  EXPECT_TRUE(c.minutes[0] && c.minutes[15] && c.minutes[30] && c.minutes[45]);
  EXPECT_EQ(c.hours.count(), 9u);
  EXPECT_TRUE(c.hours[9] && c.hours[17] && !c.hours[18]);
  EXPECT_EQ(c.days_of_month.count(), 31u);
  EXPECT_EQ(c.months.count(), 12u);
  EXPECT_EQ(c.days_of_week.count(), 5u);
  EXPECT_FALSE(c.dom_restricted);
  EXPECT_TRUE(c.dow_restricted);

  CronSchedule d = Cron("  5/20 0,12  1-10/3 2 7 ");
  EXPECT_EQ(d.text, "5/20 0,12 1-10/3 2 7");
  EXPECT_TRUE(d.minutes[5] && d.minutes[25] && d.minutes[45]);
  EXPECT_EQ(d.minutes.count(), 3u);
  EXPECT_EQ(d.hours.count(), 2u);
  EXPECT_TRUE(d.days_of_month[1] && d.days_of_month[4] && d.days_of_month[7] && d.days_of_month[10]);
  EXPECT_EQ(d.days_of_month.count(), 4u);
  EXPECT_TRUE(d.months[2]);
  EXPECT_TRUE(d.days_of_week[0]);  // 7 is Sunday
  EXPECT_EQ(d.days_of_week.count(), 1u);
}

TEST(ParseCronTest, RefusesBadExpressionsNamingTheField) {
  for (const char* bad :
       {"", "0 2 * *", "0 2 * * * *", "60 2 * * *", "0 24 * * *", "0 2 0 * *", "0 2 * 13 *", "0 2 * * 8", "*/0 * * * *",
        "5-2 * * * *", "a * * * *", "1- * * * *", "1,,2 * * * *", "-1 * * * *", "1/2/3 * * * *", "JAN * * * *"}) {
    auto c = ParseCron(bad, "campaign.schedule");
    ASSERT_FALSE(c.ok()) << bad;
    EXPECT_EQ(c.status().code(), StatusCode::kInvalidArgument) << bad;
    EXPECT_EQ(c.status().field(), "campaign.schedule") << bad;
  }
  auto c = ParseCron("0 24 * * *");
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.status().reason().find("hour: 24 is out of range 0-23"), std::string::npos) << c.status().reason();
}

TEST(NextDueTest, NightlyIsStrictlyAfter) {
  const std::string nightly = "0 2 * * *";
  EXPECT_EQ(Next(nightly, Utc(2026, 11, 22, 12, 0)), Utc(2026, 11, 23, 2, 0));
  EXPECT_EQ(Next(nightly, Utc(2026, 11, 23, 1, 59, 59) + 0.5), Utc(2026, 11, 23, 2, 0));
  EXPECT_EQ(Next(nightly, Utc(2026, 11, 23, 2, 0)), Utc(2026, 11, 24, 2, 0));  // strictly after
  EXPECT_EQ(Next(nightly, Utc(2026, 11, 23, 2, 0) + 0.25), Utc(2026, 11, 24, 2, 0));
  // Month and year roll over.
  EXPECT_EQ(Next(nightly, Utc(2026, 12, 31, 3, 0)), Utc(2027, 1, 1, 2, 0));
  EXPECT_EQ(Next("*/15 * * * *", Utc(2026, 11, 22, 12, 7)), Utc(2026, 11, 22, 12, 15));
}

TEST(NextDueTest, DayOfMonthOrDayOfWeekWhenBothRestricted) {
  // 2026-11-13 is a Friday; 2026-11-20 a Friday; 2026-12-13 a Sunday.
  const std::string friday_or_13th = "0 0 13 * 5";
  EXPECT_EQ(Next(friday_or_13th, Utc(2026, 11, 12, 0, 0)), Utc(2026, 11, 13, 0, 0));
  EXPECT_EQ(Next(friday_or_13th, Utc(2026, 11, 13, 0, 0)), Utc(2026, 11, 20, 0, 0));
  EXPECT_EQ(Next(friday_or_13th, Utc(2026, 12, 12, 0, 0)), Utc(2026, 12, 13, 0, 0));  // Sunday the 13th
  // Only one restricted: both must hold (every day-of-month, Mondays only).
  EXPECT_EQ(Next("0 0 * * 1", Utc(2026, 11, 22, 0, 0)), Utc(2026, 11, 23, 0, 0));
  // "*/2" starts with '*': unrestricted for the either rule, so odd days AND Mondays
  // (2026-11-23 is an odd Monday, 11-30 an even one, 12-07 the next odd one).
  EXPECT_EQ(Next("0 0 */2 * 1", Utc(2026, 11, 22, 0, 0)), Utc(2026, 11, 23, 0, 0));
  EXPECT_EQ(Next("0 0 */2 * 1", Utc(2026, 11, 23, 0, 0)), Utc(2026, 12, 7, 0, 0));
}

TEST(NextDueTest, LeapDayAndNever) {
  EXPECT_EQ(Next("0 0 29 2 *", Utc(2026, 11, 22, 0, 0)), Utc(2028, 2, 29, 0, 0));
  auto never = NextDue(Cron("0 0 31 2 *"), Utc(2026, 1, 1, 0, 0), CronZone::kUtc);
  ASSERT_FALSE(never.ok());
  EXPECT_EQ(never.status().code(), StatusCode::kNotFound);
}

TEST(LatestDueInTest, OnlyTheLatestMissedDueTime) {
  CronSchedule nightly = Cron("0 2 * * *");
  auto latest = LatestDueIn(nightly, Utc(2026, 11, 20, 2, 0), Utc(2026, 11, 23, 12, 0), CronZone::kUtc);
  ASSERT_TRUE(latest.ok());
  ASSERT_TRUE(latest->has_value());
  EXPECT_EQ(**latest, Utc(2026, 11, 23, 2, 0));
  // The bound is inclusive at `until`, exclusive at `after`.
  latest = LatestDueIn(nightly, Utc(2026, 11, 22, 2, 0), Utc(2026, 11, 23, 2, 0), CronZone::kUtc);
  ASSERT_TRUE(latest.ok() && latest->has_value());
  EXPECT_EQ(**latest, Utc(2026, 11, 23, 2, 0));
  latest = LatestDueIn(nightly, Utc(2026, 11, 23, 2, 0), Utc(2026, 11, 23, 23, 0), CronZone::kUtc);
  ASSERT_TRUE(latest.ok());
  EXPECT_FALSE(latest->has_value());
  // A long outage: one year of nights, still just the last one.
  latest = LatestDueIn(nightly, Utc(2025, 11, 1, 0, 0), Utc(2026, 11, 23, 1, 0), CronZone::kUtc);
  ASSERT_TRUE(latest.ok() && latest->has_value());
  EXPECT_EQ(**latest, Utc(2026, 11, 22, 2, 0));
}

// Runs a test body with TZ set to a POSIX rule (no tzdata needed): central Europe, summer time
// from the last Sunday of March 02:00 to the last Sunday of October 03:00.
class BerlinTime : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* old = getenv("TZ");
    if (old) saved_ = old;
    had_ = old != nullptr;
    setenv("TZ", "CET-1CEST,M3.5.0,M10.5.0/3", 1);
    tzset();
  }
  void TearDown() override {
    if (had_) {
      setenv("TZ", saved_.c_str(), 1);
    } else {
      unsetenv("TZ");
    }
    tzset();
  }
  std::string saved_;
  bool had_ = false;
};

TEST_F(BerlinTime, NightlyInLocalTime) {
  // 02:00 CET is 01:00 UTC in winter.
  EXPECT_EQ(Next("0 2 * * *", Utc(2026, 11, 22, 12, 0), CronZone::kLocal), Utc(2026, 11, 23, 1, 0));
  EXPECT_EQ(FormatWallMinute(Utc(2026, 11, 23, 1, 0), CronZone::kLocal), "2026-11-23 02:00");
}

TEST_F(BerlinTime, SpringForwardGapFiresWhenTheGapEnds) {
  // 2026-03-29: 02:00 CET (01:00 UTC) becomes 03:00 CEST. 02:00 and 02:30 do not exist.
  EXPECT_EQ(Next("0 2 * * *", Utc(2026, 3, 28, 12, 0), CronZone::kLocal), Utc(2026, 3, 29, 1, 0));
  EXPECT_EQ(Next("30 2 * * *", Utc(2026, 3, 28, 12, 0), CronZone::kLocal), Utc(2026, 3, 29, 1, 0));
  // Several missing minutes of one gap collapse into one firing; the next is 03:00 CEST.
  EXPECT_EQ(Next("*/20 2-3 * * *", Utc(2026, 3, 29, 1, 0), CronZone::kLocal), Utc(2026, 3, 29, 1, 20));
  // The night after is normal again: 02:30 CEST = 00:30 UTC.
  EXPECT_EQ(Next("30 2 * * *", Utc(2026, 3, 29, 1, 0), CronZone::kLocal), Utc(2026, 3, 30, 0, 30));
}

TEST_F(BerlinTime, FallBackFiresAtTheFirstOccurrenceOnly) {
  // 2026-10-25: 03:00 CEST (01:00 UTC) becomes 02:00 CET; 02:30 happens at 00:30 and 01:30 UTC.
  EXPECT_EQ(Next("30 2 * * *", Utc(2026, 10, 24, 12, 0), CronZone::kLocal), Utc(2026, 10, 25, 0, 30));
  EXPECT_EQ(Next("30 2 * * *", Utc(2026, 10, 25, 0, 30), CronZone::kLocal), Utc(2026, 10, 26, 1, 30));
  // From inside the repeated hour (02:10 CET, the second time round) nothing repeats either.
  EXPECT_EQ(Next("30 2 * * *", Utc(2026, 10, 25, 1, 10), CronZone::kLocal), Utc(2026, 10, 26, 1, 30));
}

}  // namespace
}  // namespace sandswim
