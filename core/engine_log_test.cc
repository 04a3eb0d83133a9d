#include "core/engine_log.h"

#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "tests/fixture_file.h"

namespace sandswim {
namespace {

using testing::Fixture;  // tests/fixture_file.h

ExitFacts Exit(int code, int sig = 0, bool timed_out = false, bool cancelled = false) {
  ExitFacts e;
  e.exit_code = code;
  e.signal = sig;
  e.timed_out = timed_out;
  e.cancelled = cancelled;
  return e;
}

ExitFacts NotStarted() {
  ExitFacts e;
  e.started = false;
  e.start_error = "'liggghts' not found on PATH";
  return e;
}

constexpr char kVersionLine[] =
    "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)\n";

TEST(EngineLogTest, RealDriveLog) {
  EngineLog log = ParseEngineLog(Fixture("drive_omega_minus80.log"));
  EXPECT_EQ(log.version, "LIGGGHTS-PUBLIC 3.8.0");
  EXPECT_EQ(log.version_line, std::string(kVersionLine).substr(0, sizeof(kVersionLine) - 2));
  ASSERT_TRUE(log.drive_start.has_value());
  EXPECT_EQ(log.drive_start->grains, 5024);
  EXPECT_DOUBLE_EQ(log.drive_start->so_z, -0.0112944231246753);
  EXPECT_DOUBLE_EQ(log.drive_start->surface, 0.219183512199015);
  ASSERT_TRUE(log.drive_stop.has_value());
  EXPECT_EQ(log.drive_stop->reason, "duration");
  EXPECT_EQ(log.drive_stop->step, 30000);
  EXPECT_DOUBLE_EQ(log.drive_stop->t, 0.3);
  EXPECT_DOUBLE_EQ(log.drive_stop->z, 0.026681491424663);
  EXPECT_EQ(log.last_thermo_step, 30000);
  EXPECT_TRUE(log.error_line.empty());
  EXPECT_FALSE(log.lost_atoms);
  EXPECT_TRUE(log.bad_marker.empty()) << log.bad_marker;
  EXPECT_EQ(ClassifyExit(api::JobKind::kRun, ExitFacts{}, log, 30000), std::nullopt);
}

TEST(EngineLogTest, RealBedLog) {
  EngineLog log = ParseEngineLog(Fixture("bed.log"));
  ASSERT_TRUE(log.bed_grains.has_value());
  EXPECT_EQ(log.bed_grains->grains, 5024);
  EXPECT_DOUBLE_EQ(log.bed_grains->grain_top, 0.219183512199015);
  EXPECT_EQ(log.bed_grains->step, 123001);
  ASSERT_TRUE(log.bed_equilibrium.has_value());
  EXPECT_TRUE(log.bed_equilibrium->equilibrated);
  EXPECT_DOUBLE_EQ(log.bed_equilibrium->ke_peak, 37.677812517013);
  EXPECT_EQ(log.last_thermo_step, 123001);
  EXPECT_EQ(ClassifyExit(api::JobKind::kBed, ExitFacts{}, log, 0), std::nullopt);
}

TEST(EngineLogTest, RealDeckErrorLog) {
  EngineLog log = ParseEngineLog(Fixture("deck_error.log"));
  EXPECT_EQ(log.error_line, "ERROR: Unknown command: foo_command 1 2 (./src/input.cpp:259)");
  EXPECT_EQ(log.error_line_number, 5);
  ExitFacts exit;
  exit.exit_code = 1;
  auto failure = ClassifyExit(api::JobKind::kRun, exit, log, 100);
  ASSERT_TRUE(failure.has_value());
  EXPECT_EQ(failure->kind, "deck_error");
  EXPECT_EQ(failure->message, log.error_line);
}

TEST(EngineLogTest, EchoedPrintCommandsAndTornLinesAreNotMarkers) {
  std::string text = std::string(kVersionLine) +
                     "print \"SANDSWIM drive stop duration step ${st} t ${t} z ${so_z}\"\n"
                     "SANDSWIM drive stop duration step 300";  // still being written
  EngineLog log = ParseEngineLog(text);
  EXPECT_FALSE(log.drive_stop.has_value());
  EXPECT_TRUE(log.bad_marker.empty());
}

TEST(EngineLogTest, MalformedMarkerIsReported) {
  EngineLog log = ParseEngineLog(std::string(kVersionLine) + "SANDSWIM drive stop sideways step 3 t 0 z 0\n");
  EXPECT_EQ(log.bad_marker, "SANDSWIM drive stop sideways step 3 t 0 z 0");
  auto failure = ClassifyExit(api::JobKind::kRun, ExitFacts{}, log, 3);
  ASSERT_TRUE(failure.has_value());
  EXPECT_EQ(failure->kind, "bad_output");
}

TEST(EngineLogTest, LastLines) {
  EXPECT_EQ(LastLines("a\nb\nc\n", 2), "b\nc\n");
  EXPECT_EQ(LastLines("a\nb\nc", 2), "b\nc");
  EXPECT_EQ(LastLines("a\nb\n", 5), "a\nb\n");
  EXPECT_EQ(LastLines("", 3), "");
}

// The classification table: exit facts + log -> failure kind (empty: complete).
TEST(EngineLogTest, ClassificationTable) {
  const std::string v = kVersionLine;
  const std::string done = v + "SANDSWIM drive stop duration step 1000 t 0.01 z 0.1\n";
  struct Case {
    const char* name;
    api::JobKind kind;
    ExitFacts exit;
    std::string log;
    int64_t steps;
    std::string want;  // failure kind, "" for complete
  } cases[] = {
      {"complete run", api::JobKind::kRun, Exit(0), done, 1000, ""},
      {"early surface stop", api::JobKind::kRun, Exit(0), v + "SANDSWIM drive stop surface step 400 t 0.004 z 0.2\n",
       1000, ""},
      {"early floor stop", api::JobKind::kRun, Exit(0), v + "SANDSWIM drive stop floor step 400 t 0.004 z -0.2\n", 1000,
       ""},
      {"SIGTERM exit 0 without marker", api::JobKind::kRun, Exit(0), v + "  500 5025 0.01\n", 1000, "incomplete"},
      {"duration marker with wrong step", api::JobKind::kRun, Exit(0), done, 2000, "incomplete"},
      {"not started", api::JobKind::kRun, NotStarted(), "", 1000, "engine_missing"},
      {"mpirun cannot find liggghts", api::JobKind::kRun, Exit(134), "", 1000, "engine_missing"},
      {"exit 0 no log", api::JobKind::kRun, Exit(0), "", 1000, "bad_output"},
      {"deck error", api::JobKind::kRun, Exit(1), v + "ERROR: Illegal fix move command (fix_move.cpp:99)\n", 1000,
       "deck_error"},
      {"error on proc", api::JobKind::kRun, Exit(1), v + "ERROR on proc 1: Bad thing (x.cpp:1)\n", 1000, "deck_error"},
      {"lost atoms", api::JobKind::kRun, Exit(1),
       v + "ERROR: Lost atoms: original 5025 current 5024 (thermo.cpp:398)\n", 1000, "lost_atoms"},
      {"segfault", api::JobKind::kRun, Exit(0, 11), v, 1000, "signal"},
      {"segfault via mpirun", api::JobKind::kRun, Exit(139), v, 1000, "signal"},
      {"timeout wins over the signal", api::JobKind::kRun, Exit(0, 15, true), v, 1000, "timeout"},
      {"cancelled", api::JobKind::kRun, Exit(0, 0, false, true), v, 1000, "cancelled"},
      {"nonzero after marker", api::JobKind::kRun, Exit(1), done, 1000, "incomplete"},
      {"bed complete", api::JobKind::kBed, Exit(0), v + "SANDSWIM bed grains 10 so_z 0 grain_top 0.2 step 5\n", 0, ""},
      {"bed without marker", api::JobKind::kBed, Exit(0), v, 0, "incomplete"},
  };
  for (const Case& c : cases) {
    auto failure = ClassifyExit(c.kind, c.exit, ParseEngineLog(c.log), c.steps);
    EXPECT_EQ(failure ? failure->kind : "", c.want) << c.name << ": " << (failure ? failure->message : "");
    if (failure) {
      EXPECT_FALSE(failure->message.empty()) << c.name;
    }
  }
}

}  // namespace

// A count written as a number past int64's range is not a count (found by fuzz_engine_log: the
// conversion was undefined behaviour); one written as a whole double still reads.
TEST(EngineLogTest, ACountBeyondInt64IsABadMarker) {
  const std::string first = "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2019-03-19)\n";
  EngineLog huge = ParseEngineLog(first + "SANDSWIM drive start grains 5.024e48 so_z -0.01 surface 0.2\n");
  EXPECT_FALSE(huge.drive_start.has_value());
  EXPECT_FALSE(huge.bad_marker.empty());
  EXPECT_FALSE(
      ParseEngineLog(first + "SANDSWIM drive start grains 9223372036854775808.0 so_z 0 surface 0\n").drive_start);
  EngineLog whole = ParseEngineLog(first + "SANDSWIM drive start grains 5024.0 so_z -0.01 surface 0.2\n");
  ASSERT_TRUE(whole.drive_start.has_value());
  EXPECT_EQ(whole.drive_start->grains, 5024);
}

}  // namespace sandswim
