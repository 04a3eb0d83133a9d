#include "cli/format.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim::cli {
namespace {

using json = nlohmann::json;
using ::testing::HasSubstr;
using ::testing::EndsWith;
using ::testing::Not;

json TwoResultRows() {
  return json::parse(R"([
    {"run_id": 1, "key": "k1", "state": "done", "mode": "oscillatory", "A": 0.03, "f": 3.0,
     "Omega": -80.0, "omega": null, "axis": null, "duration_s": 5.0, "run_duration_s": 5.0,
     "Uz_text": "0.0123 ± 0.0001, 4 periods", "Uz": 0.0123456, "Uz_stderr": 0.0001, "Uz_ci95": 0.000318,
     "Uz_blocks": 4, "conclusive": true, "inconclusive_reason": "", "window_end": "surface",
     "dz": 0.061728, "dz_rate": 0.012346, "broke_surface": true, "near_floor": false,
     "stop_reason": "surface", "analysis": 2},
    {"run_id": 12, "key": "k,2", "state": "failed", "mode": "vibration+rotation", "A": 0.03,
     "f": 3.0, "Omega": null, "omega": 80.0, "axis": "xz", "duration_s": 4.0,
     "run_duration_s": 4.0, "Uz": null, "Uz_stderr": null, "dz": null, "broke_surface": null,
     "near_floor": null, "stop_reason": null}
  ])");
}

TEST(FormatTest, TableAlignsColumnsWithoutTrailingBlanks) {
  Table t;
  t.header = {"ID", "NAME", "N"};
  t.align = {Align::kRight, Align::kLeft, Align::kRight};
  t.rows = {{"1", "a", "10"}, {"123", "longer", "2"}};
  EXPECT_EQ(RenderTable(t),
            " ID  NAME     N\n"
            "  1  a       10\n"
            "123  longer   2\n");
}

TEST(FormatTest, ColourWrapsTheTextNotThePadding) {
  Table t;
  t.header = {"ID", "STATE", "X"};
  t.rows = {{"1", "done", "x"}};
  t.color = {{"", "32", ""}};
  EXPECT_EQ(RenderTable(t), "ID  STATE  X\n1   \x1b[32mdone\x1b[0m   x\n");
}

TEST(FormatTest, DisplayWidthCountsCodePoints) {
  EXPECT_EQ(DisplayWidth("Δz (m)"), 6u);
  EXPECT_EQ(DisplayWidth(""), 0u);
}

TEST(FormatTest, NumbersAndDurations) {
  EXPECT_EQ(DisplayNumber(0.03), "0.03");
  EXPECT_EQ(DisplayNumber(-80.0), "-80");
  EXPECT_EQ(DisplayNumber(-0.0), "0");
  EXPECT_EQ(DisplayNumber(0.0123456, 4), "0.01235");
  EXPECT_EQ(FormatDuration(45), "45s");
  EXPECT_EQ(FormatDuration(200), "3m20s");
  EXPECT_EQ(FormatDuration(3720), "1h02m");
  EXPECT_EQ(FormatDuration(2 * 86400 + 3 * 3600 + 59), "2d03h");
  EXPECT_EQ(FormatDuration(-1), "?");
}

TEST(FormatTest, ProgressBar) {
  EXPECT_EQ(ProgressBar(0.0, 10), "[..........]   0%");
  EXPECT_EQ(ProgressBar(0.45, 10), "[####......]  45%");
  EXPECT_EQ(ProgressBar(1.0, 10), "[##########] 100%");
  EXPECT_EQ(ProgressBar(7.0, 4), "[####] 100%");   // clamped
  EXPECT_EQ(ProgressBar(-1.0, 4), "[....]   0%");  // clamped
}

// The daemon's ETA is shown while work moves; with nothing in flight there is no time to give.
TEST(FormatTest, EtaIsTheDaemonsWhileWorkMoves) {
  Snapshot s;
  s.counts.queued = 3;
  s.eta = Snapshot::DaemonEta{600, 0.25, "measured: 2 done runs", 467, 770};
  EXPECT_FALSE(s.eta_s().has_value()) << "nothing in flight, no bed being prepared";
  s.waiting_bed_state = "running";
  EXPECT_EQ(s.eta_s(), 600.0);
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("ETA 10m00s (7m47s-12m50s) (preparing the granular bed first)"));
  s.counts = {0, 0, 3, 0, 0};
  EXPECT_EQ(s.eta_s(), 0.0);
  s.counts = {1, 1, 0, 0, 0};
  s.eta.reset();
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("ETA unknown (the daemon gives none"));
}

TEST(FormatTest, CountsAndPoints) {
  Counts c = CountsFromJson(json::parse(R"({"queued":2,"running":1,"done":5,"failed":0,"cancelled":0})"));
  EXPECT_EQ(c.total(), 8);
  EXPECT_FALSE(c.finished());
  EXPECT_EQ(FormatCounts(c), "2 queued, 1 running, 5 done, 0 failed, 0 cancelled");
  EXPECT_EQ(FormatPoint(json::parse(R"({"mode":"oscillatory","A":0.03,"f":3,"Omega":-80,"duration_s":5})")),
            "oscillatory A=0.03 f=3 Omega=-80 T=5s");
  EXPECT_EQ(FormatPoint(json::parse(R"({"mode":"rotation","omega":80,"axis":"x","duration_s":4})")),
            "rotation omega=80 axis=x T=4s");
  EXPECT_EQ(FormatPoint(json::parse(
                R"({"mode":"oscillatory","A":0.03,"f":3,"Omega":-80,"duration_s":5,"so_density":5000,"grain_youngs":1e8})")),
            "oscillatory A=0.03 f=3 Omega=-80 T=5s so_density=5000 grain_youngs=1e+08");
}

TEST(FormatTest, ResultsTableGolden) {
  EXPECT_EQ(RenderResultsTable(TwoResultRows(), {}),
            "RUN  STATE   MODE                   A  f  Omega/omega  AXIS  DURATION                   U_z (m/s)  "
            "Δz/T (m/s)  Δz (m)  FLAGS\n"
            "  1  done    oscillatory         0.03  3          -80  -            5  0.0123 ± 0.0001, 4 periods  "
            "     0.012  0.0617  surface,window<surface\n"
            " 12  failed  vibration+rotation  0.03  3           80  xz           4                           -  "
            "         -       -  -\n");
}

TEST(FormatTest, ResultsTableNamesSweepsOfCampaignRows) {
  json rows = TwoResultRows();
  rows[0]["sweeps"] = {"baseline", "Omega-sweep"};
  rows[1]["sweeps"] = {"modes.vibration-rotation-xz"};
  std::string table = RenderResultsTable(rows, {});
  EXPECT_THAT(table, HasSubstr("SWEEPS"));
  EXPECT_THAT(table, HasSubstr("baseline,Omega-sweep"));
}

TEST(FormatTest, ResultsCsvGolden) {
  EXPECT_EQ(
      RenderResultsCsv(TwoResultRows()),
      "run_id,key,state,mode,A,f,Omega,omega,axis,duration_s,run_duration_s,replicate,bed_id,Uz_text,Uz,Uz_stderr,"
      "Uz_ci95,Uz_blocks,block_s,block_kind,window_t0,window_t1,window_end,conclusive,inconclusive_reason,trending,"
      "trend_p,trend_slope,trend_slope_se,trend_note,dz,dz_rate,z_osc_amplitude,x_osc_amplitude,x_drift,"
      "broke_surface,near_floor,stop_reason,stop_note,precision_met,sim_time_s,grains,analysis,analysed_from,"
      "engine_version,so_density_kg_m3,so_diameter_m,so_friction,so_restitution,grain_diameter_m,"
      "grain_density_kg_m3,grain_friction,grain_restitution,grain_youngs_Pa,grain_poisson\n"
      "1,k1,done,oscillatory,0.03,3.0,-80.0,,,5.0,5.0,,,\"0.0123 ± 0.0001, 4 periods\",0.0123456,0.0001,0.000318,4,"
      ",,,,surface,true,,,,,,,0.061728,0.012346,,,,true,false,surface,,,,,2,,,"
      "2500.0,0.12,0.5,0.5,0.02,2500.0,0.45,0.9,10000000.0,0.25\n"
      "12,\"k,2\",failed,vibration+rotation,0.03,3.0,,80.0,xz,4.0,4.0,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,,"
      "2500.0,0.12,0.5,0.5,0.02,2500.0,0.45,0.9,10000000.0,0.25\n");
}

// A sweep over materials: its rows show the swept materials as columns after the drive's (Table
// 1's value where a row sets none), its CSV their values; a Table 1 sweep's table is unchanged
// (ResultsTableGolden).
TEST(FormatTest, ResultsShowTheSweptMaterials) {
  json rows = TwoResultRows();
  rows[1]["so_density"] = 5000;
  rows[1]["grain_youngs"] = 1e8;
  const std::string table = RenderResultsTable(rows, {});
  EXPECT_THAT(table, HasSubstr("DURATION  so_density (kg/m^3)  grain_youngs (Pa)  "));
  EXPECT_THAT(table, HasSubstr("2500"));  // row 1: Table 1's
  EXPECT_THAT(table, HasSubstr("5000"));
  EXPECT_THAT(table, HasSubstr("1e+07"));
  EXPECT_THAT(table, HasSubstr("1e+08"));
  EXPECT_THAT(RenderResultsCsv(rows), HasSubstr(",2,,,2500.0,0.12,0.5,0.5,0.02,2500.0,0.45,0.9,10000000.0,0.25\n"));
  EXPECT_THAT(RenderResultsCsv(rows), HasSubstr(",5000,0.12,0.5,0.5,0.02,2500.0,0.45,0.9,100000000.0,0.25\n"));
  json aggregates = json::array({{{"mode", "oscillatory"}, {"A", 0.03}, {"so_density", 5000}, {"replicates", 2}}});
  EXPECT_THAT(RenderAggregatesTable(aggregates, {}), HasSubstr("AXIS  so_density (kg/m^3)  U_z"));
}

// A point on three beds: its mean ± standard error, K as conclusive/all, each bed's value (an
// inconclusive one in brackets); the table is shown only when some point ran on more than one bed.
TEST(FormatTest, AggregatesFollowTheRunsWhenPointsRanOnSeveralBeds) {
  json reply = {
      {"results", TwoResultRows()},
      {"aggregates", json::parse(R"j([{"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "replicates": 3,
                   "conclusive": 2, "uz_text": "0.110 ± 0.010, 2 of 3 beds (between-bed sd 0.014)",
                   "note": "over 2 of 3 replicate(s): the others are not conclusive",
                   "values": [{"replicate": 0, "state": "done", "conclusive": true, "uz": 0.1},
                              {"replicate": 1, "state": "done", "conclusive": true, "uz": 0.12},
                              {"replicate": 2, "state": "done", "conclusive": false, "uz": 0.3}]}])j")}};
  const std::string out = RenderResults(reply, {});
  EXPECT_THAT(out, HasSubstr("over its replicate beds"));
  EXPECT_THAT(out, HasSubstr("0.110 ± 0.010, 2 of 3 beds"));
  EXPECT_THAT(out, HasSubstr("2/3"));
  EXPECT_THAT(out, HasSubstr("0.1 0.12 (0.3)"));
  // One bed per point: the runs' table alone.
  reply["aggregates"][0]["replicates"] = 1;
  EXPECT_EQ(RenderResults(reply, {}), RenderResultsTable(TwoResultRows(), {}));
}

TEST(FormatTest, ResultFlags) {
  EXPECT_EQ(ResultFlags(json::parse(R"({"broke_surface":true,"near_floor":true})")), "surface,floor");
  EXPECT_EQ(ResultFlags(json::parse(R"({"broke_surface":false,"near_floor":true})")), "floor");
  EXPECT_EQ(ResultFlags(json::parse(R"({"broke_surface":null})")), "");
}

TEST(FormatTest, CsvCellQuotes) {
  EXPECT_EQ(CsvCell(json("a\"b")), "\"a\"\"b\"");
  EXPECT_EQ(CsvCell(json(nullptr)), "");
  EXPECT_EQ(CsvCell(json::array({"a", "b"})), "a;b");
}

Snapshot SampleSnapshot() {
  Snapshot s;
  s.title = "sweep 3 omega-sign (scale smoke)";
  s.counts = {2, 1, 5, 1, 0};
  s.running.push_back({7, "oscillatory A=0.03 f=3 Omega=-80 T=5s", 2.5, 5.0, 0.4321, "node1:12"});
  s.failed.push_back({9, "oscillatory A=0.03 f=3 Omega=80 T=5s", "engine_error: ERROR: Lost atoms"});
  s.eta = Snapshot::DaemonEta{300, 0.2, "measured: 2 done runs; 1 engine", 246, 366};
  return s;
}

TEST(FormatTest, StatusGolden) {
  EXPECT_EQ(RenderStatus(SampleSnapshot(), {}),
            "sweep 3 omega-sign (scale smoke)\n"
            "  runs: 9 (2 queued, 1 running, 5 done, 1 failed, 0 cancelled)\n"
            "  ETA 5m00s (4m06s-6m06s)\n"
            "    (measured: 2 done runs; 1 engine)\n"
            "in flight:\n"
            "  run 7  [##########..........]  50%  2.5/5 s  z=0.4321 m  oscillatory A=0.03 f=3 Omega=-80 T=5s"
            "  on node1:12\n"
            "failed:\n"
            "  run 9  oscillatory A=0.03 f=3 Omega=80 T=5s\n"
            "    engine_error: ERROR: Lost atoms\n");
}

// An adaptive campaign run's status: each round, what it added and why, what it cost, the budget
// left and the claims' states after it; the stop reason last.
TEST(FormatTest, StatusShowsTheRoundsOfAnAdaptiveCampaignRun) {
  Snapshot s = SampleSnapshot();
  s.adaptive = {{"budget_core_h", 20}, {"max_rounds", 4}};
  s.rounds = nlohmann::json::parse(R"([
    {"round": 1, "finished_at": 5, "core_h_planned": 14.7, "core_h_spent": 10.31, "budget_left_core_h": 9.69,
     "actions": [{"kind": "first round", "claim": "", "reason": "every declared point once, on one bed", "runs": 51}],
     "claims_after": [{"claim": "F1", "verdict": "holds", "frozen_at_round": 1}, {"claim": "F4", "verdict": "inconclusive"}],
     "stop_reason": null},
    {"round": 2, "finished_at": null, "core_h_planned": 0.48, "core_h_spent": null, "budget_left_core_h": null,
     "actions": [{"kind": "new point", "claim": "F4", "reason": "F4: the peak lies between 4 and 6 Hz; adding f = 4.5, 5.5 on 1 bed: +0.48 core-h", "runs": 2}],
     "claims_after": null, "stop_reason": null}])");
  const std::string out = RenderStatus(s, {});
  EXPECT_NE(out.find("rounds (budget 20 core-h, at most 4 rounds):\n"
                     "  round 1  finished  planned 14.7 core-h, spent 10.3, 9.69 core-h left\n"
                     "    every declared point once, on one bed\n"
                     "    after it: F1 holds (round 1), F4 inconclusive\n"
                     "  round 2  running  planned 0.48 core-h\n"
                     "    F4: the peak lies between 4 and 6 Hz; adding f = 4.5, 5.5 on 1 bed: +0.48 core-h\n"),
            std::string::npos)
      << out;
  s.rounds[1]["finished_at"] = 9;
  s.rounds[1]["stop_reason"] = "every claim runs can decide is decided";
  EXPECT_NE(RenderStatus(s, {}).find("  stopped: every claim runs can decide is decided\n"), std::string::npos);
  EXPECT_EQ(SnapshotToJson(s)["rounds"].size(), 2u);
  EXPECT_EQ(RenderRounds(nullptr, nlohmann::json::array()), "");  // the fixed design: no lines
}

// The band is the daemon's (a log-scale band, not symmetric about the ETA), printed as it comes; from
// a daemon that sends only rel_error the same band is computed; with no error, no band.
TEST(FormatTest, EtaPrintsTheDaemonsBand) {
  Snapshot s;
  s.counts = {0, 1, 0, 0, 0};
  s.eta = Snapshot::DaemonEta{3480, 0.15, "b", 3000, 4020};
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("ETA 58m00s (50m00s-1h07m)"));
  s.eta = Snapshot::DaemonEta{3480, 0.15, "b"};  // 3480/e^0.15 = 2995, 3480*e^0.15 = 4043
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("ETA 58m00s (49m55s-1h07m)"));
  s.eta = Snapshot::DaemonEta{3480, 0, "b"};
  EXPECT_THAT(RenderWatchLine(s), EndsWith("ETA 58m00s"));
  EXPECT_FALSE(SnapshotToJson(s).contains("eta_low_s"));
}

// While the bed is prepared nothing runs; the ETA says so instead of asking for a worker.
TEST(FormatTest, EtaNamesTheBedWhileNothingRuns) {
  Snapshot s;
  s.title = "sweep 1 x (scale smoke)";
  s.counts.queued = 2;
  s.waiting_bed_state = "running";
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("ETA unknown (preparing the granular bed first)"));
  s.waiting_bed_state = "queued";
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("the bed waits for a worker"));
  s.waiting_bed_state = "done";
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("no run in flight: is a worker running?"));
  // The daemon's estimate, while its workers prepare the campaign's other beds.
  s.eta = Snapshot::DaemonEta{600, 0.2, "test"};
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("ETA 10m00s (8m11s-12m13s) (none of its runs has started: they wait for a free worker)"));
}

TEST(FormatTest, WatchLineAndFrame) {
  Snapshot s = SampleSnapshot();
  EXPECT_EQ(RenderWatchLine(s),
            "sweep 3 omega-sign (scale smoke): 5/9 done, 1 running, 2 queued, 1 failed, 0 cancelled; ETA 5m00s (4m06s-6m06s)");
  std::string frame = RenderWatchFrame(s, {});
  EXPECT_THAT(frame, HasSubstr("[##########..........]  50%"));
  EXPECT_THAT(frame, Not(HasSubstr("\x1b[")));
  EXPECT_THAT(RenderWatchFrame(s, RenderOptions{true}), HasSubstr("\x1b[31m1 failed\x1b[0m"));
  s.running.clear();
  s.counts = {0, 0, 7, 2, 0};
  EXPECT_THAT(RenderWatchLine(s), HasSubstr("; finished"));
}

TEST(FormatTest, SnapshotJson) {
  json j = SnapshotToJson(SampleSnapshot());
  EXPECT_EQ(j["counts"]["queued"], 2);
  EXPECT_EQ(j["running"][0]["id"], 7);
  EXPECT_EQ(j["failed"][0]["reason"], "engine_error: ERROR: Lost atoms");
  EXPECT_DOUBLE_EQ(j["eta_s"].get<double>(), 300);
  EXPECT_DOUBLE_EQ(j["eta_rel_error"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(j["eta_low_s"].get<double>(), 246);
  EXPECT_DOUBLE_EQ(j["eta_high_s"].get<double>(), 366);
  EXPECT_EQ(j["eta_basis"], "measured: 2 done runs; 1 engine");
  EXPECT_EQ(j["finished"], false);
}

TEST(FormatTest, SweepsAndRunsTables) {
  json sweeps = json::parse(R"([{"id": 1, "name": "omega-sign", "scale": "smoke", "cancelled": true,
      "counts": {"queued":0,"running":0,"done":1,"failed":0,"cancelled":1}}])");
  EXPECT_EQ(RenderSweepsTable(sweeps, {}),
            "ID  NAME                    SCALE  RUNS  QUEUED  RUNNING  DONE  FAILED  CANCELLED\n"
            " 1  omega-sign (cancelled)  smoke     2       0        0     1       0          1\n");
  json runs = json::parse(R"([{"id": 4, "state": "running", "run_duration_s": 5.0, "worker": "n1:3",
      "point": {"mode":"vibration","A":0.03,"f":3,"duration_s":5},
      "progress": {"sim_time_s": 1.25, "so_z": 0.4, "step": 125000}}])");
  EXPECT_EQ(RenderRunsTable(runs, {}),
            "ID  STATE    PROGRESS  U_z  POINT                      WORKER\n"
            " 4  running  1.25/5 s    -  vibration A=0.03 f=3 T=5s  n1:3\n");
}

TEST(FormatTest, RunDetailShowsDeckResultAndLog) {
  json run = json::parse(R"J({"id": 4, "state": "done", "key": "abc", "run_duration_s": 5.0, "steps": 500000,
      "bed_id": 1, "bed_state": "done", "sweeps": [2, 3], "attempts": 1, "worker": "n1:3",
      "point": {"mode":"vibration","A":0.03,"f":3,"duration_s":5},
      "progress": {"sim_time_s": 5.0, "so_z": 0.4, "step": 500000},
      "result": {"uz": 0.012, "uz_stderr": 0.0001, "uz_ci95": 0.00032, "uz_blocks": 4, "block_kind": "period",
                 "uz_text": "0.0120 ± 0.0001 m/s, 4 periods", "window_t0": 0.333, "window_t1": 1.667,
                 "window_end": "run_end", "dz": 0.06, "x_drift": 0.001, "stop_reason": "duration",
                 "engine_version": "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0)", "host": "n1", "ranks": 2,
                 "wall_s": 95},
      "deck": "run 1000\n", "log_tail": "Loop time of 95"})J");
  std::string text = RenderRunDetail(run, {});
  EXPECT_THAT(text, HasSubstr("run 4  done\n"));
  EXPECT_THAT(text, HasSubstr("sweeps:    2, 3\n"));
  EXPECT_THAT(text, HasSubstr("U_z = 0.0120 ± 0.0001 m/s, 4 periods\n"));
  EXPECT_THAT(text, HasSubstr("95 % interval ± 0.00032 m/s (Student t, 4 whole period rates)"));
  EXPECT_THAT(text, HasSubstr("window:    0.333 .. 1.667 s, ended by run_end"));
  EXPECT_THAT(text, HasSubstr("--- deck ---\nrun 1000\n--- log tail ---\nLoop time of 95\n"));
  // A result without x's amplitude or a trend test (an older analysis) says so.
  EXPECT_THAT(text, HasSubstr("x not measured"));
  EXPECT_THAT(text, Not(HasSubstr("trend:")));

  run["result"]["x_osc_amplitude"] = 0.0031;
  run["result"]["z_osc_amplitude"] = 0.004;
  run["result"]["trend_slope"] = 0.021;
  run["result"]["trend_slope_se"] = 0.004;
  run["result"]["trend_p"] = 0.0003;
  run["result"]["trending"] = true;
  text = RenderRunDetail(run, {});
  EXPECT_THAT(text, HasSubstr("at f:      z oscillates 0.004 m, x 0.0031 m\n"));
  EXPECT_THAT(text, HasSubstr("trend:     period rate changes by 0.021 ± 0.004 m/s² (p = 0.0003): TRENDING"));
  run["result"].erase("trend_p");
  run["result"]["trending"] = false;
  run["result"]["trend_note"] = "the window holds 3 whole periods; a trend test needs at least 4";
  text = RenderRunDetail(run, {});
  EXPECT_THAT(text, HasSubstr("trend:     not tested: the window holds 3 whole periods"));
}

TEST(FormatTest, ResultsTableFlagsATrendingRun) {
  json rows = json::parse(R"([{"run_id": 1, "state": "done", "mode": "vibration", "A": 0.03, "f": 3,
      "duration_s": 4, "Uz_text": "0.0120 ± 0.0001, 9 periods", "dz": 0.05, "dz_rate": 0.0125,
      "trending": true, "trend_p": 0.001}])");
  EXPECT_THAT(RenderResultsTable(rows, {}), HasSubstr("trend"));
  rows[0]["trending"] = false;
  EXPECT_THAT(RenderResultsTable(rows, {}), Not(HasSubstr("trend")));
}

}  // namespace
}  // namespace sandswim::cli

namespace sandswim::cli {
namespace {

// `sandswim check` prints each claim's and part's error rates at the design, and what would help;
// a reply from a daemon without rates prints none.
TEST(FormatTest, ClaimsShowTheirRatesAtTheDesign) {
  json reply = json::parse(R"J({"campaign": "paper-58", "scale": "smoke", "campaign_run_id": 7,
    "counts": {"holds": 0, "differs": 0, "inconclusive": 1},
    "claims": [{"id": "F4", "title": "peaks", "source": "Fig. 8", "verdict": "inconclusive",
      "verdict_text": "inconclusive at smoke", "reason": "no interior maximum established",
      "rates": {"calibrated": true, "text": "false holds <= 2.4 %, false differs <= 1.9 %, power 4 % [2.3, 7] at this design (paper-58 at smoke, K = 1 bed, rules 2, analysis 3; 300 simulated campaigns a law)",
                "advice": "power 4 % at this design: longer runs; measured at K = 3: 0 %", "low_power": true},
      "parts": [{"name": "the rising rate peaks at an interior f", "verdict": "inconclusive", "reason": "p = 0.2",
                 "rates": {"calibrated": false, "text": "not calibrated at this design (x)", "advice": "calibrate it", "low_power": false}}],
      "paper": {"text": "f_c = 5 Hz"}, "missing": []}]})J");
  RenderOptions options;
  const std::string out = RenderClaims(reply, options);
  EXPECT_THAT(out, HasSubstr("    rates: false holds <= 2.4 %, false differs <= 1.9 %, power 4 % [2.3, 7] at this design"));
  EXPECT_THAT(out, HasSubstr("power 4 % at this design: longer runs; measured at K = 3: 0 %"));
  EXPECT_THAT(out, HasSubstr("rates: not calibrated at this design (x)"));
  reply["claims"][0].erase("rates");
  reply["claims"][0]["parts"][0].erase("rates");
  EXPECT_THAT(RenderClaims(reply, options), Not(HasSubstr("rates:")));
}

TEST(FormatTest, TimestampsSchedulesAndPlans) {
  EXPECT_EQ(FormatTimestamp(1795658400), "2026-11-26 02:00 UTC");
  EXPECT_EQ(FormatTimestamp(1795658459.9), "2026-11-26 02:00 UTC");  // minutes are not rounded up
  EXPECT_EQ(FormatTimestamp("tomorrow"), "tomorrow");
  EXPECT_EQ(FormatTimestamp(nlohmann::json()), "-");
  EXPECT_EQ(FormatSchedule(nlohmann::json()), "-");
  EXPECT_EQ(FormatSchedule("0 2 * * *"), "0 2 * * *");  // a daemon older than stored schedules
  EXPECT_EQ(FormatSchedule({{"cron", "0 2 * * *"}, {"scale", "smoke"}, {"next_due", nullptr}}), "0 2 * * * at smoke");
  EXPECT_EQ(FormatPlannedRuns({{"paper", 58}, {"smoke", 174}}), "174 runs at smoke, 58 at paper");
  EXPECT_EQ(FormatPlannedRuns(nlohmann::json()), "");
}

}  // namespace
}  // namespace sandswim::cli
