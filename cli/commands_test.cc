#include "cli/commands.h"

#include <map>
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

// RunCli against a FakeClient, with a chosen TTY-ness and environment.
struct Harness {
  std::ostringstream out, err;
  std::istringstream in;
  std::map<std::string, std::string> vars;
  FakeClient* fake = nullptr;  // owned by the Context once made
  std::function<void(FakeClient&)> fill;

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
    env.now = [] { return 0.0; };
    env.sleep = [](double) {};
    env.make_client = [this](const ClientOptions&) {
      auto client = std::make_unique<FakeClient>();
      if (fill) fill(*client);
      fake = client.get();
      return std::unique_ptr<DaemonClient>(std::move(client));
    };
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
  EXPECT_THAT(CommandNames(), ElementsAre("submit", "status", "runs", "show", "results", "watch", "cancel", "rerun",
                                          "expand", "report", "check", "backup", "analyze", "version", "slurm"));
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
