#include "cli/commands.h"

#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "cli/fake_client_test_util.h"

namespace sandswim::cli {
namespace {

using json = nlohmann::json;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

// RunCli against a FakeClient, with a chosen TTY-ness and environment.
struct Harness {
  std::ostringstream out, err;
  std::istringstream in;
  std::map<std::string, std::string> vars;
  FakeClient* fake = nullptr;  // owned by the Context once made
  std::unique_ptr<FakeClient> last;  // a copy of the fake as the command left it
  std::function<void(FakeClient&)> fill;
  std::function<Status(const std::string& command, const std::string& path)> editor;
  FakeClock clock;  // watch's: its sleeps move it, none waits

  int Run(std::vector<const char*> args, bool tty) {
    Environment env;
    env.out = &out;
    env.err = &err;
    env.in = &in;
    env.out_is_tty = tty;
    env.err_is_tty = tty;
    env.getenv = [this](const char* name) -> const char* {
      auto it = vars.find(name);
      return it == vars.end() ? nullptr : it->second.c_str();
    };
    env.clock = &clock;
    env.make_client = [this](const ClientOptions&) {
      auto client = std::make_unique<FakeClient>();
      if (fill) fill(*client);
      client->on_close = [this](const FakeClient& f) {
        last = std::make_unique<FakeClient>(f);
        last->on_close = nullptr;
      };
      fake = client.get();
      return std::unique_ptr<DaemonClient>(std::move(client));
    };
    env.run_editor = editor;
    env.probe_engine = [] { return Result<std::string>(Status::Unavailable("no engine in tests")); };
    args.insert(args.begin(), "sandswim");
    return RunCli(static_cast<int>(args.size()), args.data(), env);
  }
};

void OneRunningRun(FakeClient& c) {
  c.runs = json::array({{{"id", 1},
                         {"state", "running"},
                         {"point", {{"mode", "vibration"}, {"A", 0.03}, {"f", 3}, {"duration_s", 4}}},
                         {"run_duration_s", 4.0},
                         {"progress", {{"sim_time_s", 1.0}, {"so_z", 0.4}, {"step", 0}}}}});
}

TEST(CommandsTest, TableReadsTopToBottom) {
  EXPECT_THAT(CommandNames(),
              ElementsAre("submit", "status", "runs", "show", "results", "watch", "cancel", "rerun", "campaign",
                          "schedule", "expand", "report", "check", "backup", "analyze", "version", "slurm"));
}

TEST(CommandsTest, ColourOnlyOnATerminalWithoutNoColor) {
  Harness tty;
  tty.fill = OneRunningRun;
  ASSERT_EQ(tty.Run({"runs"}, /*tty=*/true), kExitOk) << tty.err.str();
  EXPECT_THAT(tty.out.str(), HasSubstr("\x1b[33mrunning\x1b[0m"));

  Harness no_color;
  no_color.fill = OneRunningRun;
  no_color.vars["NO_COLOR"] = "1";
  ASSERT_EQ(no_color.Run({"runs"}, /*tty=*/true), kExitOk);
  EXPECT_THAT(no_color.out.str(), Not(HasSubstr("\x1b[")));

  Harness piped;
  piped.fill = OneRunningRun;
  ASSERT_EQ(piped.Run({"runs"}, /*tty=*/false), kExitOk);
  EXPECT_THAT(piped.out.str(), Not(HasSubstr("\x1b[")));

  Harness flag;
  flag.fill = OneRunningRun;
  ASSERT_EQ(flag.Run({"--no-color", "runs"}, /*tty=*/true), kExitOk);
  EXPECT_THAT(flag.out.str(), Not(HasSubstr("\x1b[")));
}

TEST(CommandsTest, WatchExitsThreeWhenRunsFailed) {
  Harness h;
  h.fill = [](FakeClient& c) {
    c.sweeps[4] = {{"id", 4},
                   {"name", "s"},
                   {"scale", "smoke"},
                   {"counts", {{"queued", 0}, {"running", 0}, {"done", 1}, {"failed", 1}, {"cancelled", 0}}}};
  };
  EXPECT_EQ(h.Run({"watch", "4"}, false), kExitRunsFailed);
  EXPECT_THAT(h.out.str(), HasSubstr("1 failed"));
}

// A campaign run's claims: each with its verdict, what was measured and what the paper reports.
json Claims(const std::vector<std::string>& verdicts) {
  json claims = json::array();
  int n = 0;
  std::map<std::string, int> counts = {{"holds", 0}, {"differs", 0}, {"inconclusive", 0}};
  for (const std::string& v : verdicts) {
    ++counts[v];
    claims.push_back(
        {{"id", "F" + std::to_string(++n)},
         {"title", "claim " + std::to_string(n)},
         {"source", "Fig. " + std::to_string(n)},
         {"paper", {{"text", "the paper's finding " + std::to_string(n)}, {"Omega_rad_s", {-80, 80}}}},
         {"verdict", v},
         {"reason", "measured " + std::to_string(n)},
         {"parts", json::array({{{"name", "part " + std::to_string(n)}, {"verdict", v}, {"reason", "r"}}})},
         {"missing", v == "inconclusive" ? json::array({{{"sweep", "omega"},
                                                         {"point", "Omega = 160"},
                                                         {"run_ids", {12}},
                                                         {"why", "failed: engine crashed"}}})
                                         : json::array()}});
  }
  return {{"campaign_run_id", 7}, {"campaign", "paper-58"}, {"scale", "smoke"}, {"claims_source", "stored"},
          {"note", ""},           {"counts", counts},       {"claims", claims}};
}

TEST(CommandsTest, CheckExitsZeroOnlyWhenEveryClaimHolds) {
  Harness all;
  all.fill = [](FakeClient& c) { c.claims[7] = Claims({"holds", "holds"}); };
  EXPECT_EQ(all.Run({"check", "cr:7"}, false), kExitOk) << all.err.str();
  EXPECT_THAT(all.out.str(), HasSubstr("2 hold, 0 differ, 0 inconclusive"));
  EXPECT_THAT(all.out.str(), HasSubstr("the paper's finding 2 [Omega_rad_s = -80, 80]"));

  Harness differs;
  differs.fill = [](FakeClient& c) { c.claims[7] = Claims({"holds", "differs"}); };
  EXPECT_EQ(differs.Run({"check", "cr:7"}, true), kExitRunsFailed);
  EXPECT_THAT(differs.out.str(), HasSubstr("\x1b[31mdiffers\x1b[0m"));

  Harness inconclusive;
  inconclusive.fill = [](FakeClient& c) { c.claims[7] = Claims({"holds", "inconclusive"}); };
  EXPECT_EQ(inconclusive.Run({"check", "cr:7"}, false), kExitRunsFailed);
  EXPECT_THAT(inconclusive.out.str(), HasSubstr("omega Omega = 160 (run 12): failed: engine crashed"));

  Harness json_out;
  json_out.fill = [](FakeClient& c) { c.claims[7] = Claims({"holds"}); };
  EXPECT_EQ(json_out.Run({"check", "cr:7", "--json"}, false), kExitOk);
  EXPECT_EQ(json::parse(json_out.out.str())["claims"][0]["verdict"], "holds");

  // No claims decides nothing; a sweep id is not a campaign run; an unknown run is an error.
  Harness none;
  none.fill = [](FakeClient& c) { c.claims[7] = Claims({}); };
  EXPECT_EQ(none.Run({"check", "cr:7"}, false), kExitRunsFailed);
  EXPECT_THAT(none.out.str(), HasSubstr("no claims"));
  Harness sweep;
  EXPECT_EQ(sweep.Run({"check", "12"}, false), kExitUsage);
  EXPECT_THAT(sweep.err.str(), HasSubstr("cr:ID"));
  Harness unknown;
  EXPECT_EQ(unknown.Run({"check", "cr:9"}, false), kExitError);
}

TEST(CommandsTest, ServerFromTheEnvironmentIsValidated) {
  Harness h;
  h.vars["SANDSWIM_SERVER"] = "not a url";
  EXPECT_EQ(h.Run({"status"}, false), kExitUsage);
  EXPECT_EQ(h.err.str(),
            "sandswim: SANDSWIM_SERVER: expected http://HOST:PORT or https://HOST:PORT (e.g. http://127.0.0.1:8640), "
            "got \"not a url\"\n");
}

TEST(ClientOptionsTest, HttpsTakesAPinnedFingerprintFromTheFlagOrTheEnvironment) {
  std::map<std::string, std::string> vars;
  auto getenv = [&vars](const char* name) -> const char* {
    auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  };
  const std::string pin = "SHA256:" + [] {
    std::string hex;
    for (int i = 0; i < 32; ++i) hex += (i ? ":" : "") + std::string("0A");
    return hex;
  }();
  vars["SANDSWIM_TLS_FINGERPRINT"] = "0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a0a";
  auto o = ResolveClientOptions("https://login1:8640", "", getenv);
  ASSERT_TRUE(o.ok()) << o.status().ToString();
  EXPECT_EQ(o->server, "https://login1:8640");
  EXPECT_EQ(o->tls.fingerprint, pin);
  vars["SANDSWIM_TLS_FINGERPRINT"] = "SHA256:12:34";
  auto bad = ResolveClientOptions("https://login1:8640", "", getenv);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field(), "SANDSWIM_TLS_FINGERPRINT");
  auto flag_wins = ResolveClientOptions("https://login1:8640", "", getenv, pin);
  ASSERT_TRUE(flag_wins.ok()) << flag_wins.status().ToString();
  EXPECT_EQ(flag_wins->tls.fingerprint, pin);
}

TEST(CommandsTest, ExpandWithoutEngineWarnsAndUsesUnknown) {
  Harness h;
  ASSERT_EQ(h.Run({"expand", "paper-58", "--scale", "smoke"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(h.fake, nullptr);  // offline: no client was made
  EXPECT_THAT(h.err.str(), HasSubstr("engine version \"unknown\""));
}

// --cost: the daemon's measured rates and workers when it answers, the defaults when not.
TEST(CommandsTest, ExpandCostUsesTheDaemonsRates) {
  Harness h;
  h.fill = [](FakeClient& c) {
    c.cost_model = {
        {"run_rate", {{"s_per_unit", 1e-6}, {"rel_error", 0.1}, {"samples", 4}, {"basis", "measured: 4 done runs"}}},
        {"bed_rate", {{"s_per_unit", 0.1}, {"rel_error", 0.2}, {"samples", 1}, {"basis", "measured: 1 done bed"}}},
        {"bed_rates",
         {{{"ranks", 1}, {"s_per_unit", 0.1}, {"rel_error", 0.2}, {"samples", 1}, {"basis", "one"}},
          {{"ranks", 2}, {"s_per_unit", 0.07}, {"rel_error", 0.2}, {"samples", 1}, {"basis", "two"}}}},
        {"engine_slots", 2}};
  };
  ASSERT_EQ(h.Run({"expand", "paper-58", "--scale", "smoke", "--cost", "--cores", "4", "--json"}, false), kExitOk)
      << h.err.str();
  json j = json::parse(h.out.str());
  ASSERT_EQ(j["runs"].size(), 58u);
  const json& cost = j["cost"][0];
  EXPECT_EQ(cost["scale"], "smoke");
  EXPECT_EQ(cost["runs"], 58);
  double steps = 0;
  for (const json& r : j["runs"]) steps += r["steps"].get<double>();
  EXPECT_DOUBLE_EQ(cost["particle_steps"].get<double>(), steps * 6683);
  EXPECT_NEAR(cost["run_core_hours"].get<double>(), steps * 6683 * 1e-6 / 3600, 1e-9);
  EXPECT_NEAR(cost["bed_core_hours"].get<double>(), 668.2 / 3600, 1e-9);
  EXPECT_EQ(cost["rate_basis"], "measured: 4 done runs");
  // The bed, then the runs over 2 (the daemon's workers) or 4 engines. The one bed is granted with
  // the queue dry and widened over the idle slots: on the daemon's 2, at the 2-rank rate it
  // measured (0.07 s a grain); on 4 cores, at 4 ranks, where nothing was measured: the one-rank
  // rate over 1.42 a doubling of ranks.
  EXPECT_EQ(cost["bed_ranks"]["2"], json::array({2}));
  EXPECT_EQ(cost["bed_ranks"]["4"], json::array({4}));
  EXPECT_NEAR(cost["wall_s"]["2"].get<double>(), 6682 * 0.07 + steps * 6683 * 1e-6 / 2, 1e-6);
  EXPECT_NEAR(cost["wall_s"]["4"].get<double>(), 668.2 / (1.42 * 1.42) + steps * 6683 * 1e-6 / 4, 1e-6);
  EXPECT_GT(cost["wall_rel_error"]["4"].get<double>(), 0);

  // The text says the rule and what the bed's rate rests on.
  Harness text;
  text.fill = h.fill;
  ASSERT_EQ(text.Run({"expand", "paper-58", "--scale", "smoke", "--cost", "--cores", "4"}, false), kExitOk);
  EXPECT_THAT(text.out.str(), HasSubstr("wall time on the daemon's 2 one-rank engine(s): "));
  EXPECT_THAT(text.out.str(), HasSubstr("(1 bed on 2 ranks)"));
  EXPECT_THAT(text.out.str(), HasSubstr("(1 bed on 4 ranks)"));
  EXPECT_THAT(text.out.str(), HasSubstr("runs on the slots still\n     idle"));
  EXPECT_THAT(text.out.str(), HasSubstr("no bed measured on 4"));

  // A daemon without local workers: its workers widen only with --max-ranks, so its bed is on one rank.
  Harness remote;
  remote.fill = [&h](FakeClient& c) {
    h.fill(c);
    c.cost_model["engine_slots"] = 0;
  };
  ASSERT_EQ(remote.Run({"expand", "paper-58", "--scale", "smoke", "--cost", "--json"}, false), kExitOk);
  const json remote_cost = json::parse(remote.out.str())["cost"][0];
  ASSERT_EQ(remote_cost["bed_ranks"].size(), 1u);
  EXPECT_EQ(remote_cost["bed_ranks"].begin()->get<std::vector<int>>(), std::vector<int>{1});

  Harness offline;
  ASSERT_EQ(offline.Run({"expand", "paper-58", "--scale", "smoke", "--cost"}, false), kExitOk) << offline.err.str();
  EXPECT_THAT(offline.err.str(), HasSubstr("costing at the default rates"));
  EXPECT_THAT(offline.out.str(), HasSubstr("smoke: 58 runs on 1 bed(s)"));
  EXPECT_THAT(offline.out.str(), HasSubstr("default rate"));
}

// ---- campaign ... and schedule -------------------------------------------------------------------

json BuiltinPaper58() {
  return {{"name", "paper-58"},
          {"version", 0},
          {"builtin", true},
          {"definition", {{"name", "paper-58"}, {"scale", "paper"}}},
          {"resolved", {{"name", "paper-58"}, {"scale", "paper"}}},
          {"extends", nullptr},
          {"planned_runs", {{"smoke", 58}, {"mini", 58}, {"paper", 58}}},
          {"schedule", nullptr},
          {"versions", json::array()},
          {"runs", json::array()}};
}

// A stored campaign at version 2 that extends paper-58, scheduled, with one campaign run.
json StoredMine() {
  return {
      {"name", "mine"},
      {"version", 2},
      {"builtin", false},
      {"definition", {{"name", "mine"}, {"extends", "paper-58"}, {"replicates", 3}}},
      {"resolved", {{"name", "mine"}, {"scale", "paper"}, {"replicates", 3}}},
      {"extends", "paper-58"},
      {"extends_version", 0},
      {"notes", {"claim F4 left out: it needs sweep omega"}},
      {"planned_runs", {{"smoke", 174}, {"mini", 174}, {"paper", 174}}},
      {"schedule", {{"cron", "0 2 * * *"}, {"scale", "smoke"}, {"next_due", 1795658400}, {"source", "flag"}}},
      {"versions",
       {{{"version", 1},
         {"created_at", 1795600000},
         {"extends", "paper-58"},
         {"extends_version", 0},
         {"definition_sha256", "aaaabbbbccccddddeeee"}},
        {{"version", 2},
         {"created_at", 1795610000},
         {"extends", "paper-58"},
         {"extends_version", 0},
         {"definition_sha256", "1111222233334444"}}}},
      {"runs",
       {{{"id", 12}, {"campaign_version", 2}, {"scale", "smoke"}, {"status", "done"}, {"created_at", 1795620000}}}}};
}

void Campaigns(FakeClient& c) {
  c.campaigns["paper-58"] = BuiltinPaper58();
  c.campaigns["mine"] = StoredMine();
  c.campaign_run_lists["mine"] =
      json::array({{{"id", 12},
                    {"campaign", "mine"},
                    {"scale", "smoke"},
                    {"created_at", 1795620000},
                    {"counts", {{"queued", 0}, {"running", 0}, {"done", 173}, {"failed", 1}, {"cancelled", 0}}}}});
}

TEST(CampaignCommandsTest, ListShowsVersionBuiltInExtendsScheduleAndLastRun) {
  Harness h;
  h.fill = Campaigns;
  ASSERT_EQ(h.Run({"campaign", "list"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(h.out.str(),
            "NAME      VERSION  BUILT-IN  EXTENDS   SCHEDULE            LAST RUN\n"
            "mine            2  no        paper-58  0 2 * * * at smoke  cr:12 smoke, 2026-11-25 15:20 UTC, 173/174 "
            "done, 1 failed\n"
            "paper-58        -  yes       -         -                   -\n");
  Harness j;
  j.fill = Campaigns;
  ASSERT_EQ(j.Run({"campaign", "list", "--json"}, false), kExitOk) << j.err.str();
  json list = json::parse(j.out.str());
  ASSERT_EQ(list.size(), 2u);
  EXPECT_EQ(list[0]["last_run"]["id"], 12);
  EXPECT_TRUE(list[1]["last_run"].is_null());
}

TEST(CampaignCommandsTest, ShowPrintsPlanScheduleNotesDefinitionVersionsAndRuns) {
  Harness h;
  h.fill = Campaigns;
  ASSERT_EQ(h.Run({"campaign", "show", "mine"}, false), kExitOk) << h.err.str();
  const std::string out = h.out.str();
  EXPECT_THAT(out,
              StartsWith("campaign mine, version 2\n"
                         "  extends:   paper-58\n"
                         "  plans:     174 runs at smoke, 174 at mini, 174 at paper\n"
                         "  schedule:  0 2 * * * at smoke, next due 2026-11-26 02:00 UTC (from sandswimd --schedule)\n"
                         "  note:      claim F4 left out: it needs sweep omega\n"));
  EXPECT_THAT(out, HasSubstr("definition (as written; --resolved shows what runs):\n{\n  \"extends\": \"paper-58\""));
  EXPECT_THAT(out, HasSubstr("VERSION  CREATED               EXTENDS   SHA-256\n"
                             "      1  2026-11-25 09:46 UTC  paper-58  aaaabbbbcccc\n"));
  EXPECT_THAT(
      out, HasSubstr("RUN    VERSION  SCALE  STATUS  CREATED\ncr:12        2  smoke  done    2026-11-25 15:20 UTC\n"));

  Harness resolved;
  resolved.fill = Campaigns;
  ASSERT_EQ(resolved.Run({"campaign", "show", "mine", "--resolved"}, false), kExitOk);
  EXPECT_THAT(resolved.out.str(), HasSubstr("resolved definition (what runs: the base's fields filled in):\n{\n"
                                            "  \"name\": \"mine\",\n  \"replicates\": 3,\n  \"scale\": \"paper\"\n}"));

  Harness builtin;
  builtin.fill = Campaigns;
  ASSERT_EQ(builtin.Run({"campaign", "show", "paper-58"}, false), kExitOk);
  EXPECT_THAT(builtin.out.str(), StartsWith("campaign paper-58 (built-in, read-only: `sandswim campaign edit paper-58` "
                                            "starts your own copy)\n"));
  EXPECT_THAT(builtin.out.str(), HasSubstr("runs: none yet (sandswim campaign run paper-58 --scale smoke)\n"));

  // A past version says which one is current.
  Harness past;
  past.fill = [](FakeClient& c) {
    Campaigns(c);
    json v1 = StoredMine();
    v1["version"] = 1;
    v1["current_version"] = 2;
    c.versions[{"mine", 1}] = v1;
  };
  ASSERT_EQ(past.Run({"campaign", "show", "mine", "--version", "1"}, false), kExitOk) << past.err.str();
  EXPECT_THAT(past.out.str(), StartsWith("campaign mine, version 1 (the current one is 2)\n"));

  // Refusals: an unknown version names the field; a name that cannot be one never reaches the daemon.
  Harness version;
  version.fill = Campaigns;
  EXPECT_EQ(version.Run({"campaign", "show", "mine", "--version", "9"}, false), kExitError);
  EXPECT_EQ(version.err.str(), "sandswim: version: no version 9\n");
  Harness bad;
  EXPECT_EQ(bad.Run({"campaign", "show", "my campaign"}, false), kExitUsage);
  EXPECT_THAT(bad.err.str(), StartsWith("sandswim: NAME: "));
  EXPECT_EQ(bad.fake, nullptr);
}

// The README's example, true: paper-58 on three replicate beds is one line of JSON on stdin.
TEST(CampaignCommandsTest, PutFromStdinPrintsTheVersionAndThePlan) {
  Harness h;
  h.fill = Campaigns;
  h.in.str(R"({"name":"p58-3beds","extends":"paper-58","replicates":3})");
  ASSERT_EQ(h.Run({"campaign", "put", "-"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(h.out.str(),
            "p58-3beds: stored as version 1 (a new campaign)\n  plans 2 runs at smoke, 2 at mini, 2 at paper\n");
  ASSERT_EQ(h.last->puts.size(), 1u);
  EXPECT_EQ(h.last->puts[0].first, "p58-3beds");
  EXPECT_EQ(h.last->puts[0].second["replicates"], 3);
}

TEST(CampaignCommandsTest, PutRefusalsNameTheFieldOnce) {
  Harness refused;
  refused.fill = [](FakeClient& c) {
    c.put_refusals.push_back(Status(StatusCode::kInvalidArgument, "must be > 0", "sweeps[2].axes[0].values"));
  };
  refused.in.str(R"({"name":"mine","sweeps":[]})");
  EXPECT_EQ(refused.Run({"campaign", "put", "-"}, false), kExitError);
  EXPECT_EQ(refused.err.str(), "sandswim: sweeps[2].axes[0].values: must be > 0\n");
  EXPECT_EQ(refused.out.str(), "");

  // Before any request: no name, a name that cannot be one, not JSON, no such file (exit 2).
  for (std::string text : {R"({"extends":"paper-58"})", R"({"name":"a b"})", "{\"name\":", "[1]"}) {
    Harness h;
    h.in.str(text);
    EXPECT_EQ(h.Run({"campaign", "put", "-"}, false), kExitUsage) << text;
    EXPECT_EQ(h.fake, nullptr) << text;
  }
  Harness none;
  EXPECT_EQ(none.Run({"campaign", "put", "/no/such/file.json"}, false), kExitUsage);
  EXPECT_EQ(none.err.str(), "sandswim: FILE: cannot read /no/such/file.json\n");
}

TEST(CampaignCommandsTest, RmNamesTheRunsThatStayReadable) {
  Harness h;
  h.fill = Campaigns;
  ASSERT_EQ(h.Run({"campaign", "rm", "mine"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(h.out.str(), "removed campaign mine\n");
  EXPECT_THAT(h.err.str(), HasSubstr("stay readable (sandswim status / results / check): cr:12\n"));
  EXPECT_EQ(h.last->deleted, std::vector<std::string>{"mine"});

  Harness busy;
  busy.fill = [](FakeClient& c) {
    Campaigns(c);
    c.delete_refusal = Status(StatusCode::kConflict, "campaign run cr:12 of it is running; cancel it first", "name");
  };
  EXPECT_EQ(busy.Run({"campaign", "rm", "mine"}, false), kExitError);
  EXPECT_EQ(busy.err.str(), "sandswim: name: campaign run cr:12 of it is running; cancel it first\n");
  Harness unknown;
  EXPECT_EQ(unknown.Run({"campaign", "rm", "nobody"}, false), kExitError);
  EXPECT_EQ(unknown.err.str(), "sandswim: name: no campaign 'nobody'\n");
}

TEST(CampaignCommandsTest, RunSubmitsItAndWaitFollowsItAsWatchDoes) {
  Harness h;
  h.fill = Campaigns;
  ASSERT_EQ(h.Run({"campaign", "run", "mine", "--scale", "smoke", "--force"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(h.out.str(), "cr:7\nsweeps: 3 4\n");
  EXPECT_THAT(h.err.str(), HasSubstr("2 run(s): 2 new"));
  ASSERT_EQ(h.last->run_requests.size(), 1u);
  EXPECT_EQ(h.last->run_requests[0].second, (json{{"scale", "smoke"}, {"force", true}}));

  // --wait: the campaign run's progress, then its results; exit 3 as `watch` when a run failed.
  Harness wait;
  wait.fill = [](FakeClient& c) {
    Campaigns(c);
    c.campaign_runs[7] = {{"id", 7},
                          {"campaign", "mine"},
                          {"scale", "smoke"},
                          {"sweeps", {3, 4}},
                          {"counts", {{"queued", 0}, {"running", 0}, {"done", 1}, {"failed", 1}, {"cancelled", 0}}}};
  };
  EXPECT_EQ(wait.Run({"campaign", "run", "mine", "--wait"}, false), kExitRunsFailed) << wait.err.str();
  EXPECT_THAT(wait.err.str(), HasSubstr("1 failed"));

  Harness scale;
  EXPECT_EQ(scale.Run({"campaign", "run", "mine", "--scale", "huge"}, false), kExitUsage);
  Harness unknown;
  EXPECT_EQ(unknown.Run({"campaign", "run", "nobody"}, false), kExitError);
  EXPECT_EQ(unknown.err.str(), "sandswim: name: no campaign 'nobody'\n");
}

TEST(CampaignCommandsTest, ScheduleSetsListsAndRemoves) {
  Harness set;
  set.fill = Campaigns;
  // The cron's words may come unquoted (as long as the shell leaves the stars alone).
  ASSERT_EQ(set.Run({"schedule", "paper-58", "30", "3", "*", "*", "1", "--scale", "mini"}, false), kExitOk)
      << set.err.str();
  EXPECT_EQ(set.out.str(), "paper-58: 30 3 * * 1 at mini, next due 2027-01-15 08:00 UTC\n");

  Harness list;
  list.fill = Campaigns;
  ASSERT_EQ(list.Run({"schedule"}, false), kExitOk) << list.err.str();
  EXPECT_EQ(list.out.str(),
            "CAMPAIGN  CRON       SCALE  NEXT DUE              SET BY\n"
            "mine      0 2 * * *  smoke  2026-11-26 02:00 UTC  sandswimd --schedule\n");
  Harness list_json;
  list_json.fill = Campaigns;
  ASSERT_EQ(list_json.Run({"schedule", "--json"}, false), kExitOk);
  EXPECT_EQ(json::parse(list_json.out.str())[0]["campaign"], "mine");

  Harness off;
  off.fill = Campaigns;
  ASSERT_EQ(off.Run({"schedule", "mine", "--off"}, false), kExitOk) << off.err.str();
  EXPECT_EQ(off.out.str(), "mine: no schedule\n");
  EXPECT_TRUE(off.last->campaigns["mine"]["schedule"].is_null());
  Harness none;
  none.fill = Campaigns;
  EXPECT_EQ(none.Run({"schedule", "paper-58", "--off"}, false), kExitError);
  EXPECT_EQ(none.err.str(), "sandswim: schedule: 'paper-58' has no schedule\n");

  Harness bad_cron;
  bad_cron.fill = [](FakeClient& c) {
    Campaigns(c);
    c.schedule_refusal = Status(StatusCode::kInvalidArgument, "expected 5 fields, got 1", "cron");
  };
  EXPECT_EQ(bad_cron.Run({"schedule", "mine", "nightly"}, false), kExitError);
  EXPECT_EQ(bad_cron.err.str(), "sandswim: cron: expected 5 fields, got 1\n");

  // Usage: CRON or --off (not both, not neither); --scale only with CRON; --off names a campaign.
  for (std::vector<const char*> args : {std::vector<const char*>{"schedule", "mine"},
                                        {"schedule", "mine", "0 2 * * *", "--off"},
                                        {"schedule", "mine", "--off", "--scale", "smoke"},
                                        {"schedule", "--off"}}) {
    Harness h;
    EXPECT_EQ(h.Run(args, false), kExitUsage) << args.size();
    EXPECT_EQ(h.fake, nullptr);
  }
}

// `campaign edit`: the editor is a fake that writes what a user would.
struct ScriptedEditor {
  std::vector<std::function<std::string(const std::string&)>> edits;  // one per opening: old text -> new
  std::vector<std::string> seen;                                      // the text at each opening
  std::string path;
  Status operator()(const std::string& command, const std::string& file) {
    (void)command;
    path = file;
    std::ifstream in(file);
    std::stringstream text;
    text << in.rdbuf();
    seen.push_back(text.str());
    if (seen.size() <= edits.size()) std::ofstream(file, std::ios::trunc) << edits[seen.size() - 1](text.str());
    return Status::Ok();
  }
};

std::string TempDir() {
  std::string pattern = (std::filesystem::temp_directory_path() / "sandswim-edit-test-XXXXXX").string();
  return mkdtemp(pattern.data());
}

TEST(CampaignCommandsTest, EditSavesWhatTheEditorWroteAndLeavesNoFile) {
  auto editor = std::make_shared<ScriptedEditor>();
  editor->edits.push_back([](const std::string&) { return R"({"name":"mine","extends":"paper-58","replicates":5})"; });
  Harness h;
  h.fill = Campaigns;
  h.vars["TMPDIR"] = TempDir();
  h.editor = [editor](const std::string& c, const std::string& p) { return (*editor)(c, p); };
  ASSERT_EQ(h.Run({"campaign", "edit", "mine"}, false), kExitOk) << h.err.str();
  ASSERT_EQ(editor->seen.size(), 1u);
  EXPECT_EQ(json::parse(editor->seen[0]), StoredMine()["definition"]);  // the definition as written
  EXPECT_THAT(editor->path, StartsWith(h.vars["TMPDIR"] + "/sandswim-mine-"));
  EXPECT_EQ(h.out.str(), "mine: stored as version 3\n  plans 2 runs at smoke, 2 at mini, 2 at paper\n");
  EXPECT_EQ(h.last->puts.at(0).second["replicates"], 5);
  EXPECT_TRUE(std::filesystem::is_empty(h.vars["TMPDIR"]));
  std::filesystem::remove_all(h.vars["TMPDIR"]);
}

TEST(CampaignCommandsTest, EditLeftUnchangedSavesNothing) {
  auto editor = std::make_shared<ScriptedEditor>();
  Harness h;
  h.fill = Campaigns;
  h.vars["TMPDIR"] = TempDir();
  h.editor = [editor](const std::string& c, const std::string& p) { return (*editor)(c, p); };
  ASSERT_EQ(h.Run({"campaign", "edit", "mine"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(h.err.str(), "sandswim: no change; nothing saved (mine is still version 2)\n");
  EXPECT_TRUE(h.last->puts.empty());
  EXPECT_TRUE(std::filesystem::is_empty(h.vars["TMPDIR"]));
  std::filesystem::remove_all(h.vars["TMPDIR"]);
}

// A refusal is shown and the file re-opened with the user's text, until it is saved.
TEST(CampaignCommandsTest, EditReopensAfterARefusalUntilSaved) {
  auto editor = std::make_shared<ScriptedEditor>();
  editor->edits.push_back([](const std::string&) { return R"({"name":"mine","replicates":0})"; });
  editor->edits.push_back([](const std::string&) { return R"({"name":"mine","replicates":4)"; });  // not JSON
  editor->edits.push_back([](const std::string&) { return R"({"name":"mine","replicates":4})"; });
  Harness h;
  h.fill = [](FakeClient& c) {
    Campaigns(c);
    c.put_refusals.push_back(Status(StatusCode::kInvalidArgument, "must be >= 1", "replicates"));
  };
  h.vars["TMPDIR"] = TempDir();
  h.in.str("\ny\n");
  h.editor = [editor](const std::string& c, const std::string& p) { return (*editor)(c, p); };
  ASSERT_EQ(h.Run({"campaign", "edit", "mine"}, false), kExitOk) << h.err.str();
  ASSERT_EQ(editor->seen.size(), 3u);
  EXPECT_EQ(editor->seen[1], R"({"name":"mine","replicates":0})");  // re-opened on the user's text
  EXPECT_THAT(h.err.str(),
              HasSubstr("sandswim: replicates: must be >= 1\nsandswim: re-open the editor to fix it? [Y/n] "));
  EXPECT_THAT(h.err.str(), HasSubstr("sandswim: definition: not JSON: malformed at byte"));
  ASSERT_EQ(h.last->puts.size(), 2u);  // the text that was not JSON was never sent
  EXPECT_EQ(h.last->puts[1].second["replicates"], 4);
  EXPECT_EQ(h.out.str(), "mine: stored as version 3\n  plans 2 runs at smoke, 2 at mini, 2 at paper\n");
  std::filesystem::remove_all(h.vars["TMPDIR"]);
}

// Answering no (or re-opening and leaving it) keeps the user's text in the file and says where.
TEST(CampaignCommandsTest, EditKeepsTheTextWhenTheUserLeaves) {
  for (std::string answer : {"n\n", "y\n", ""}) {
    auto editor = std::make_shared<ScriptedEditor>();
    editor->edits.push_back([](const std::string&) { return R"({"name":"mine","replicates":0})"; });
    Harness h;
    h.fill = [](FakeClient& c) {
      Campaigns(c);
      c.put_refusals.push_back(Status(StatusCode::kInvalidArgument, "must be >= 1", "replicates"));
    };
    h.vars["TMPDIR"] = TempDir();
    h.in.str(answer);
    h.editor = [editor](const std::string& c, const std::string& p) { return (*editor)(c, p); };
    EXPECT_EQ(h.Run({"campaign", "edit", "mine"}, false), kExitError) << answer;
    EXPECT_EQ(editor->seen.size(), answer == "y\n" ? 2u : 1u) << answer;
    EXPECT_THAT(h.err.str(), HasSubstr("sandswim: nothing saved; your text is kept in " + editor->path +
                                       " (once fixed: sandswim campaign put " + editor->path + ")\n"));
    std::ifstream kept(editor->path);
    std::stringstream text;
    text << kept.rdbuf();
    EXPECT_EQ(text.str(), R"({"name":"mine","replicates":0})") << answer;
    EXPECT_EQ(h.last->campaigns["mine"], StoredMine());  // nothing stored
    std::filesystem::remove_all(h.vars["TMPDIR"]);
  }
}

// A built-in campaign is read-only: editing it starts a copy that extends it, under a free name.
TEST(CampaignCommandsTest, EditOfABuiltInStartsYourOwnCopy) {
  auto editor = std::make_shared<ScriptedEditor>();
  editor->edits.push_back([](const std::string& text) {
    json j = json::parse(text);
    j["replicates"] = 3;
    return j.dump();
  });
  Harness h;
  h.fill = [](FakeClient& c) {
    Campaigns(c);
    c.campaigns["paper-58-copy"] = StoredMine();
  };
  h.vars["TMPDIR"] = TempDir();
  h.editor = [editor](const std::string& c, const std::string& p) { return (*editor)(c, p); };
  ASSERT_EQ(h.Run({"campaign", "edit", "paper-58"}, false), kExitOk) << h.err.str();
  EXPECT_EQ(json::parse(editor->seen.at(0)), (json{{"name", "paper-58-copy-2"}, {"extends", "paper-58"}}));
  EXPECT_THAT(h.err.str(), HasSubstr("paper-58 is built-in and read-only: this starts your own campaign "
                                     "\"paper-58-copy-2\" that extends it"));
  ASSERT_EQ(h.last->puts.size(), 1u);
  EXPECT_EQ(h.last->puts[0].first, "paper-58-copy-2");
  EXPECT_EQ(h.out.str(),
            "paper-58-copy-2: stored as version 1 (a new campaign)\n  plans 2 runs at smoke, 2 at mini, 2 at paper\n");
  std::filesystem::remove_all(h.vars["TMPDIR"]);

  Harness unknown;
  EXPECT_EQ(unknown.Run({"campaign", "edit", "nobody"}, false), kExitError);
  EXPECT_THAT(unknown.err.str(), StartsWith("sandswim: NAME: no campaign 'nobody' to edit"));
}

TEST(ClientOptionsTest, FlagBeatsEnvironmentBeatsDefault) {
  std::map<std::string, std::string> vars;
  auto getenv = [&vars](const char* name) -> const char* {
    auto it = vars.find(name);
    return it == vars.end() ? nullptr : it->second.c_str();
  };
  auto o = ResolveClientOptions("", "", getenv);
  ASSERT_TRUE(o.ok());
  EXPECT_EQ(o->server, "http://127.0.0.1:8640");
  EXPECT_EQ(o->token, "");
  vars["SANDSWIM_SERVER"] = "http://node7:9000/";
  vars["SANDSWIM_TOKEN"] = " secret\n";
  o = ResolveClientOptions("", "", getenv);
  ASSERT_TRUE(o.ok());
  EXPECT_EQ(o->server, "http://node7:9000");
  EXPECT_EQ(o->token, "secret");
  o = ResolveClientOptions("http://[::1]:8640", "", getenv);
  ASSERT_TRUE(o.ok());
  EXPECT_EQ(o->server, "http://[::1]:8640");
  auto bad = ResolveClientOptions("", "/no/such/token", getenv);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.status().field(), "--token-file");
}

}  // namespace
}  // namespace sandswim::cli
