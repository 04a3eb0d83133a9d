#include "core/precision.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "core/api.h"
#include "core/trajectory.h"
#include "tests/synthetic_trajectory.h"

namespace sandswim {
namespace {

using ::testing::HasSubstr;

api::RunResult Rates(double uz, double ci95, int blocks, const std::string& window_end = "run_end") {
  api::RunResult r;
  r.uz = uz;
  r.uz_ci95 = ci95;
  r.uz_stderr = ci95 / 4;
  r.uz_blocks = blocks;
  r.block_kind = "period";
  r.window_end = window_end;
  return r;
}

TEST(PrecisionTest, TargetIsMetByTheRelativeOrTheAbsoluteHalfWidth) {
  const PrecisionTarget t{0.1, 0.002, 3, 4};
  EXPECT_TRUE(TargetMet(Rates(0.10, 0.0099, 3), t));   // within 10 % of |U_z|
  EXPECT_FALSE(TargetMet(Rates(0.10, 0.0101, 3), t));  // neither
  EXPECT_TRUE(TargetMet(Rates(0.001, 0.0019, 3), t));  // near 0: the absolute half-width decides
  EXPECT_TRUE(TargetMet(Rates(-0.10, 0.0099, 3), t));  // sinking: |U_z|
  // Never before min_periods, nor without an interval.
  EXPECT_FALSE(TargetMet(Rates(0.10, 0.001, 2), t));
  api::RunResult no_interval = Rates(0.10, 0.001, 5);
  no_interval.uz_ci95.reset();
  EXPECT_FALSE(TargetMet(no_interval, t));
  api::RunResult no_rate = Rates(0.10, 0.001, 5);
  no_rate.uz.reset();
  EXPECT_FALSE(TargetMet(no_rate, t));
}

TEST(PrecisionTest, StopRuleEndsAtTheTargetOrWhenTheWindowHasClosed) {
  const PrecisionTarget t{0.1, 0.002, 3, 4};
  EXPECT_EQ(DecideStop(Rates(0.10, 0.05, 3), t), StopVerdict::kContinue);
  EXPECT_EQ(DecideStop(Rates(0.10, 0.005, 3), t), StopVerdict::kTargetMet);
  EXPECT_EQ(DecideStop(Rates(0.10, 0.05, 3, "surface"), t), StopVerdict::kWindowClosed);
  EXPECT_EQ(DecideStop(Rates(-0.10, 0.05, 1, "floor"), t), StopVerdict::kWindowClosed);
  // A met target wins over a closed window: the run ended for the better reason.
  EXPECT_EQ(DecideStop(Rates(0.10, 0.005, 4, "surface"), t), StopVerdict::kTargetMet);
}

TEST(PrecisionTest, RunDurationHoldsTheTransientAndMinPeriods) {
  const PrecisionTarget t{0.1, 0, 3, 2};
  EXPECT_DOUBLE_EQ(RunDuration(OscillatoryPoint(0.03, 3, 80, 5), t), 2.0);
  EXPECT_DOUBLE_EQ(RunDuration(OscillatoryPoint(0.03, 1, 80, 5), t), 4.0);  // 1 + 3 periods of 1 s
  EXPECT_DOUBLE_EQ(RunDuration(OscillatoryPoint(0.03, 1, 80, 3), t), 3.0);  // never beyond the asked
  EXPECT_DOUBLE_EQ(RunDuration(OscillatoryPoint(0.03, 3, 80, 5), std::nullopt), 5.0);
  Point rotation;
  rotation.mode = Mode::kRotation;
  rotation.omega = 80;
  rotation.duration_s = 4;
  EXPECT_DOUBLE_EQ(RunDuration(rotation, PrecisionTarget{0.1, 0, 10, 1}), 11 * WindowRule{}.undriven_block_s);
}

// The merged target must never be met where either one is not: a 0 threshold is the strictest.
TEST(PrecisionTest, TightestMeetsBothTargets) {
  const PrecisionTarget a{0.1, 0.002, 3, 2}, b{0.2, 0.001, 5, 4};
  auto t = Tightest(a, b);
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(*t, (PrecisionTarget{0.1, 0.001, 5, 4}));
  EXPECT_EQ(Tightest(a, b), Tightest(b, a));
  // {rel 0.1} with {rel 0.2, abs 0.001}: abs 0 stays (a small |U_z| must still meet 0.1 |U_z|).
  EXPECT_EQ(*Tightest(PrecisionTarget{0.1, 0, 3, 2}, b), (PrecisionTarget{0.1, 0, 5, 4}));
  // Relative only against absolute only: nothing states both, the point runs its whole duration.
  EXPECT_FALSE(Tightest(PrecisionTarget{0.2, 0, 3, 2}, PrecisionTarget{0, 0.005, 3, 2}).has_value());
}

TEST(PrecisionTest, JsonRoundTripsAndStoredTargetsAreChecked) {
  const PrecisionTarget t{0.1, 0.002, 4, 3.5};
  auto back = PrecisionFromJson(PrecisionToJson(t));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, t);
  auto none = StoredPrecision(std::nullopt);
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  auto stored = StoredPrecision(PrecisionToJson(t).dump());
  ASSERT_TRUE(stored.ok());
  EXPECT_EQ(**stored, t);
  EXPECT_EQ(StoredPrecision(std::string("{")).status().code(), StatusCode::kCorruption);
  EXPECT_EQ(StoredPrecision(std::string(R"({"uz_rel": 0.1})")).status().code(), StatusCode::kCorruption);
}

TEST(PrecisionTest, StopNotesSayWhyWithTheirFigures) {
  const PrecisionTarget t{0.1, 0.002, 3, 2};
  api::RunResult r = Rates(0.1, 0.008, 4);
  r.sim_time_s = 1.7;
  r.stop_reason = "target";
  EXPECT_THAT(DescribeStop(r, t), HasSubstr("precision target met at t = 1.7 s"));
  EXPECT_THAT(DescribeStop(r, t), HasSubstr("+-0.008 m/s <= the target's 0.01 m/s, 4 whole periods"));
  r.stop_reason = "duration";
  r.uz_ci95 = 0.03;
  EXPECT_THAT(DescribeStop(r, t), HasSubstr("ran to its maximum of 1.7 s without meeting the precision target"));
  EXPECT_THAT(DescribeStop(r, std::nullopt), HasSubstr("ran its whole duration"));
  r.stop_reason = "window";
  r.window_end = "floor";
  EXPECT_THAT(DescribeStop(r, t), HasSubstr("the steady window had closed"));
  EXPECT_THAT(DescribeStop(r, t), HasSubstr("floor"));
  r.stop_reason = "surface";
  EXPECT_THAT(DescribeStop(r, t), HasSubstr("reached the bed surface"));
}

// On a trajectory with a known drift, a run followed to a target ends once the interval is
// tight enough, and the rate it then reports holds the truth within that interval.
TEST(PrecisionTest, FollowingASyntheticRunEndsWhenTheIntervalIsTight) {
  testing::SyntheticSo so;
  so.drift = 0.05;
  so.f = 3;
  so.v_noise_sd = 0.02;
  so.duration = 10;
  const std::vector<SoSample> all = testing::MakeSyntheticSo(so, 7);
  const PrecisionTarget t{0.2, 0, 3, 10};
  RunInputs in;
  in.f = so.f;
  in.precision = t;
  std::optional<api::RunResult> ended;
  for (size_t n = 100; n <= all.size(); n += 50) {
    std::vector<SoSample> so_far(all.begin(), all.begin() + n);
    auto r = AnalyzeRun(so_far, in);
    ASSERT_TRUE(r.ok());
    if (DecideStop(*r, t) != StopVerdict::kContinue) {
      ended = *r;
      break;
    }
  }
  ASSERT_TRUE(ended.has_value()) << "the target was never met in 10 s";
  EXPECT_GE(ended->uz_blocks, 3);
  EXPECT_TRUE(ended->precision_met.value_or(false));
  EXPECT_LE(*ended->uz_ci95, 0.2 * std::fabs(*ended->uz));
  EXPECT_NEAR(*ended->uz, so.drift, 2 * *ended->uz_ci95);
}

}  // namespace
}  // namespace sandswim
