#include "cli/commands.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <regex>
#include <sstream>
#include <thread>

#include <CLI/CLI.hpp>

#include "cli/analyze.h"
#include "cli/campaign_edit.h"
#include "cli/format.h"
#include "cli/slurm_submit.h"
#include "cli/snapshot.h"
#include "cli/watch.h"
#include "core/campaign_definition.h"
#include "core/cost.h"
#include "core/job_state.h"
#include "core/scale.h"
#include "core/sweep.h"

#ifndef SANDSWIM_VERSION
#define SANDSWIM_VERSION "0.0.0"
#endif

namespace sandswim::cli {
namespace {

using json = nlohmann::json;

class Context;

// Every flag of every subcommand; each subcommand's setup binds the ones it takes.
struct Args {
  // Global.
  std::string server;
  std::string token_file;
  std::string tls_fingerprint;
  std::string tls_ca;
  bool no_color = false;
  // Subcommands.
  std::string target;  // the positional: FILE | CAMPAIGN | SWEEP | CAMPAIGN-RUN | RUN
  std::string scale;
  bool force = false;
  bool wait = false;
  std::string idempotency_key;
  bool json = false;
  std::string format = "table";
  int64_t sweep = 0;
  std::string state;
  int64_t limit = 0;
  int64_t campaign_run = 0;
  double interval_s = 1.0;
  double give_up_after_s = 600;  // watch: a daemon unreachable this long ends it
  std::string engine_version;
  bool cost = false;  // `expand --cost`
  int cores = 0;      // `expand --cost --cores N`
  std::string out_file;      // `report --out`, `backup FILE`
  SlurmSubmitOptions slurm;  // `slurm submit`
  // `campaign ...`: the sub-subcommand parsed, and its flags; `schedule`.
  int (*campaign_action)(Context&) = nullptr;
  int64_t version = 0;
  bool resolved = false;
  std::vector<std::string> cron;  // `schedule NAME CRON`: its words, joined by spaces
  bool off = false;
  // `analyze`: NaN / -1 mean "not given".
  std::vector<std::string> dumps;
  double an_f = NAN, an_dt = NAN, an_floor = NAN, an_surface = NAN;
  int64_t an_id = -1;
  std::string an_deck, an_log;
  WindowRule an_rule;
};

class Context {
 public:
  Context(Args& args, Environment& env) : args(args), env(env) {}
  Args& args;
  Environment& env;

  std::ostream& out() { return *env.out; }
  std::ostream& err() { return *env.err; }

  bool ColorFor(bool tty) const {
    if (!tty || args.no_color) return false;
    const char* no_color = env.getenv("NO_COLOR");
    if (no_color != nullptr && *no_color != '\0') return false;
    const char* term = env.getenv("TERM");
    return term == nullptr || std::string(term) != "dumb";
  }
  RenderOptions OutRender() const { return RenderOptions{ColorFor(env.out_is_tty)}; }
  Clock& clock() { return env.clock != nullptr ? *env.clock : system_clock_; }

  // The REST client, made on first use (offline commands never make one).
  Result<DaemonClient*> Client() {
    if (!client_) {
      auto options = ResolveClientOptions(args.server, args.token_file, env.getenv, args.tls_fingerprint, args.tls_ca);
      if (!options.ok()) return options.status();
      client_ = env.make_client(*options);
    }
    return client_.get();
  }

 private:
  std::unique_ptr<DaemonClient> client_;
  SystemClock system_clock_;
};

int Fail(Context& c, const Status& s, int code = kExitError) {
  c.err() << "sandswim: " << Describe(s) << "\n";
  return code;
}

// Malformed input the user typed: a usage error (exit 2); anything else: exit 1.
int FailUsageIfInvalid(Context& c, const Status& s) {
  return Fail(c, s, s.code() == StatusCode::kInvalidArgument ? kExitUsage : kExitError);
}

void PrintJson(Context& c, const json& j) { c.out() << j.dump(2) << "\n"; }

// ---- FILE | CAMPAIGN ---------------------------------------------------------------------------

struct Input {
  std::optional<std::string> campaign;  // a campaign by name
  json body;                            // else: the JSON the file holds
};

bool LooksLikeCampaignName(const std::string& text) {
  static const std::regex kName(R"([A-Za-z0-9._-]+)");
  return std::regex_match(text, kName) && text.size() <= kMaxNameLength && text.find(".json") == std::string::npos;
}

bool IsFile(const std::string& arg) {
  std::error_code ec;
  return std::filesystem::is_regular_file(arg, ec);
}

// The JSON object in FILE, or on stdin for "-". `what` says what it should hold, for the error.
Result<json> ReadJsonObject(Context& c, const std::string& arg, const std::string& what) {
  std::string text;
  std::string where = arg;
  if (arg == "-") {
    std::stringstream buffer;
    buffer << c.env.in->rdbuf();
    text = buffer.str();
    where = "stdin";
  } else {
    std::ifstream in(arg, std::ios::binary);
    if (!in) return Status::InvalidArgument("FILE", "cannot read " + arg);
    std::stringstream buffer;
    buffer << in.rdbuf();
    text = buffer.str();
  }
  json body;
  try {
    body = json::parse(text);
  } catch (const json::parse_error& e) {
    return Status::InvalidArgument(where, "malformed JSON at byte " + std::to_string(e.byte) + ": " + e.what());
  }
  if (!body.is_object()) return Status::InvalidArgument(where, "expected a JSON object (" + what + ")");
  return body;
}

// "-": JSON on stdin; an existing file: its JSON; a name: a campaign.
Result<Input> ReadInput(Context& c, const std::string& arg) {
  Input input;
  if (arg != "-" && !IsFile(arg)) {
    if (!LooksLikeCampaignName(arg)) {
      return Status::InvalidArgument(
          "FILE",
          "no such file: " + arg + " (give a sweep JSON file, - for stdin, or a campaign name such as paper-58)");
    }
    input.campaign = arg;
    return input;
  }
  auto body = ReadJsonObject(c, arg, "a sweep, {\"sweeps\": [...]} or {\"campaign\": NAME}");
  if (!body.ok()) return body.status();
  input.body = std::move(*body);
  return input;
}

// The POST /api/v1/sweeps body for `input` with --scale and --force applied.
json SubmitBody(const Input& input, const Args& args) {
  json body;
  if (input.campaign) {
    body = {{"campaign", *input.campaign}};
    if (!args.scale.empty()) body["scale"] = args.scale;
  } else {
    body = input.body;
    if (!args.scale.empty()) {
      if (body.contains("campaign")) {
        body["scale"] = args.scale;
      } else if (body.contains("sweeps") && body["sweeps"].is_array()) {
        for (auto& s : body["sweeps"]) {
          if (s.is_object()) s["scale"] = args.scale;
        }
      } else {
        body["scale"] = args.scale;
      }
    }
  }
  if (args.force) body["force"] = true;
  return body;
}

// What a submission created: a campaign run, or sweeps.
std::vector<Target> SubmittedTargets(const json& reply) {
  std::vector<Target> targets;
  if (reply.contains("campaign_run_id") && reply["campaign_run_id"].is_number_integer()) {
    targets.push_back({Target::Kind::kCampaignRun, reply["campaign_run_id"].get<int64_t>()});
    return targets;
  }
  for (const auto& id : reply.value("ids", json::array())) {
    if (id.is_number_integer()) targets.push_back({Target::Kind::kSweep, id.get<int64_t>()});
  }
  return targets;
}

void PrintSubmission(Context& c, const json& reply) {
  std::vector<Target> targets = SubmittedTargets(reply);
  for (const Target& t : targets) c.out() << t.ToString() << "\n";
  std::string sweeps;
  if (!targets.empty() && targets[0].kind == Target::Kind::kCampaignRun) {
    for (const auto& id : reply.value("ids", json::array())) sweeps += (sweeps.empty() ? "" : " ") + id.dump();
    c.out() << "sweeps: " << sweeps << "\n";
  }
  c.err() << "sandswim: " << reply.value("runs", 0) << " run(s): " << reply.value("runs_new", 0) << " new, "
          << reply.value("runs_reused", 0) << " reused, " << reply.value("runs_requeued", 0) << " requeued, "
          << reply.value("runs_shared", 0) << " shared with other sweeps"
          << (reply.value("runs_failed_bed", 0) > 0
                  ? "; " + std::to_string(reply.value("runs_failed_bed", 0)) +
                        " failed at once, their bed having failed for good (sandswim status says why)"
                  : std::string())
          << (reply.value("replayed", false) ? " (an earlier identical submission answered)" : "") << "\n";
}

// Follows each target (progress on stderr), then prints its results on stdout.
int WaitAndReport(Context& c, DaemonClient& client, const std::vector<Target>& targets, const json* reply) {
  WatchOptions options;
  options.tty = c.env.err_is_tty;
  options.color = c.ColorFor(c.env.err_is_tty);
  options.interval_s = c.args.interval_s;
  options.notices = &c.err();
  bool failed = false;
  json all = json::array();
  for (const Target& t : targets) {
    auto last = Watch(client, t, options, c.clock(), c.err());
    if (!last.ok()) return Fail(c, last.status());
    failed = failed || last->counts.failed > 0;
    auto rows = FetchResults(client, t);
    if (!rows.ok()) return Fail(c, rows.status());
    if (c.args.json) {
      all.push_back({{"target", t.ToString()}, {"results", (*rows)["results"]}, {"aggregates", (*rows)["aggregates"]}});
    } else {
      c.out() << RenderResults(*rows, c.OutRender());
    }
  }
  if (c.args.json) PrintJson(c, {{"submission", *reply}, {"results", all}});
  return failed ? kExitRunsFailed : kExitOk;
}

// Prints what a submission created; with --wait, follows it and prints its results.
int ReportSubmission(Context& c, DaemonClient& client, const json& reply) {
  if (c.args.wait) {
    if (!c.args.json) PrintSubmission(c, reply);
    return WaitAndReport(c, client, SubmittedTargets(reply), &reply);
  }
  if (c.args.json) {
    PrintJson(c, reply);
  } else {
    PrintSubmission(c, reply);
  }
  return kExitOk;
}

int SubmitBodyAndReport(Context& c, const json& body) {
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto reply = (*client)->Submit(body, c.args.idempotency_key);
  if (!reply.ok()) return Fail(c, reply.status());
  return ReportSubmission(c, **client, *reply);
}

// ---- Subcommands: setup and run ----------------------------------------------------------------

void AddJson(CLI::App& sub, Args& a) { sub.add_flag("--json", a.json, "print the daemon's JSON instead of text"); }

void AddTarget(CLI::App& sub, Args& a, const std::string& name, const std::string& help, bool required = true) {
  auto* opt = sub.add_option(name, a.target, help);
  if (required) opt->required();
}

void SetupSubmit(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "FILE|CAMPAIGN", "a sweep JSON file (- for stdin) or a campaign name (paper-58)");
  sub.add_option("--scale", a.scale, "scale to run at: paper, mini or smoke (default: the file's or campaign's)");
  sub.add_flag("--force", a.force, "rerun even runs whose result is already stored");
  sub.add_flag("--wait", a.wait, "follow the runs (progress on stderr), then print the results");
  sub.add_option("--idempotency-key", a.idempotency_key, "submitting again with the same key returns the same ids");
  sub.add_option("--interval", a.interval_s, "with --wait: seconds between polls")->check(CLI::Range(0.05, 3600.0));
  AddJson(sub, a);
}

int RunSubmit(Context& c) {
  auto input = ReadInput(c, c.args.target);
  if (!input.ok()) return FailUsageIfInvalid(c, input.status());
  return SubmitBodyAndReport(c, SubmitBody(*input, c.args));
}

void SetupStatus(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "SWEEP|CAMPAIGN-RUN|CAMPAIGN",
            "a sweep id (12), a campaign run (cr:7) or a campaign name (its last drift report); none: all sweeps",
            false);
  sub.add_option("--scale", a.scale, "with CAMPAIGN: the last report at this scale (default: any)");
  AddJson(sub, a);
}

// `status CAMPAIGN`: the campaign's last drift report, one row per point.
int RunCampaignStatus(Context& c, DaemonClient& client) {
  auto report = client.CampaignDrift(c.args.target, c.args.scale);
  if (!report.ok()) return Fail(c, report.status());
  if (c.args.json) {
    PrintJson(c, *report);
    return kExitOk;
  }
  c.out() << report->value("summary", "") << "\n";
  // What a flag is worth: the rule's false alarms at this design (core/drift.h).
  if (const std::string alarms = report->value("false_alarms", ""); !alarms.empty())
    c.out() << "drift rule " << report->value("rule", 1) << ": " << alarms << "\n";
  Table t;
  t.header = {"run", "point", "state", "Uz m/s", "before", "diff", ""};
  t.align = {Align::kRight, Align::kLeft, Align::kLeft, Align::kRight, Align::kRight, Align::kRight, Align::kLeft};
  auto number = [](const json& row, const char* name) {
    auto it = row.find(name);
    return it != row.end() && it->is_number() ? DisplayNumber(it->get<double>()) : std::string("-");
  };
  for (const json& row : report->value("rows", json::array())) {
    const json drive = row.value("point", json::object());
    std::string point = drive.value("mode", "");
    for (const auto& [k, v] : drive.items()) {
      if (k == "duration_s" || k == "mode") continue;
      point += (point.empty() ? "" : " ") + k + "=" +
               (v.is_string() ? v.get<std::string>() : DisplayNumber(v.get<double>()));
    }
    bool drifted = row.value("drifted", false);
    // An inconclusive rate is never compared: no number that looks like one is shown for it.
    const bool inconclusive = row.value("inconclusive", false);
    t.rows.push_back({std::to_string(row.value("run_id", int64_t{0})), point, row.value("state", ""),
                      inconclusive ? "inconclusive" : number(row, "uz"), number(row, "uz_previous"),
                      number(row, "difference"),
                      drifted                                 ? "DRIFT"
                      : row.value("estimator_changed", false) ? "analysis changed"
                      : row.value("reused", false)            ? "reused"
                                                              : ""});
    t.color.push_back({"", "", StateColor(row.value("state", "")), "", "", "", drifted ? "1;31" : ""});
  }
  if (!c.OutRender().color) t.color.clear();
  c.out() << RenderTable(t);
  return kExitOk;
}

int RunStatus(Context& c) {
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  if (c.args.target.empty()) {
    auto sweeps = (*client)->ListSweeps();
    if (!sweeps.ok()) return Fail(c, sweeps.status());
    if (c.args.json) {
      PrintJson(c, *sweeps);
    } else {
      c.out() << RenderSweepsTable(*sweeps, c.OutRender());
    }
    return kExitOk;
  }
  auto target = ParseTarget(c.args.target);
  if (!target.ok() && LooksLikeCampaignName(c.args.target)) return RunCampaignStatus(c, **client);
  if (!target.ok()) return Fail(c, target.status(), kExitUsage);
  auto snapshot = FetchSnapshot(**client, *target);
  if (!snapshot.ok()) return Fail(c, snapshot.status());
  if (c.args.json) {
    json j = SnapshotToJson(*snapshot);
    j["target"] = target->ToString();
    PrintJson(c, j);
  } else {
    c.out() << RenderStatus(*snapshot, c.OutRender());
  }
  return kExitOk;
}

void SetupRuns(CLI::App& sub, Args& a) {
  sub.add_option("--sweep", a.sweep, "only the runs of this sweep")->check(CLI::PositiveNumber);
  sub.add_option("--state", a.state, "only runs in this state")
      ->check(CLI::IsMember([] {
        std::vector<std::string> names;
        for (JobState s : kJobStates) names.push_back(ToString(s));
        return names;
      }()));
  sub.add_option("--limit", a.limit, "at most N runs (default: all)")->check(CLI::PositiveNumber);
  AddJson(sub, a);
}

int RunRuns(Context& c) {
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  RunQuery query;
  if (c.args.sweep > 0) query.sweep = c.args.sweep;
  if (!c.args.state.empty()) query.state = c.args.state;
  query.limit = c.args.limit;
  auto runs = (*client)->ListRuns(query);
  if (!runs.ok()) return Fail(c, runs.status());
  if (c.args.json) {
    PrintJson(c, *runs);
  } else {
    c.out() << RenderRunsTable(*runs, c.OutRender());
  }
  return kExitOk;
}

void SetupShow(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "RUN", "a run id");
  AddJson(sub, a);
}

int RunShow(Context& c) {
  auto id = ParseId(c.args.target, "RUN");
  if (!id.ok()) return Fail(c, id.status(), kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto run = (*client)->GetRun(*id);
  if (!run.ok()) return Fail(c, run.status());
  if (c.args.json) {
    PrintJson(c, *run);
  } else {
    c.out() << RenderRunDetail(*run, c.OutRender());
  }
  return kExitOk;
}

void SetupResults(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "SWEEP|CAMPAIGN-RUN", "a sweep id (12) or a campaign run (cr:7)", false);
  sub.add_option("--campaign-run", a.campaign_run, "a campaign run id (same as cr:ID)")->check(CLI::PositiveNumber);
  sub.add_option("--format", a.format, "table, csv or json")->check(CLI::IsMember({"table", "csv", "json"}));
  AddJson(sub, a);
}

int RunResults(Context& c) {
  Target target;
  if (c.args.campaign_run > 0) {
    if (!c.args.target.empty()) {
      return Fail(
          c, Status::InvalidArgument("--campaign-run", "give either SWEEP|CAMPAIGN-RUN or --campaign-run, not both"),
          kExitUsage);
    }
    target = {Target::Kind::kCampaignRun, c.args.campaign_run};
  } else if (c.args.target.empty()) {
    return Fail(c,
                Status::InvalidArgument("SWEEP", "name a sweep id (12) or a campaign run (cr:7 or --campaign-run 7)"),
                kExitUsage);
  } else {
    auto parsed = ParseTarget(c.args.target);
    if (!parsed.ok()) return Fail(c, parsed.status(), kExitUsage);
    target = *parsed;
  }
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto rows = FetchResults(**client, target);
  if (!rows.ok()) return Fail(c, rows.status());
  std::string format = c.args.json ? "json" : c.args.format;
  if (format == "json") {
    PrintJson(c, (*rows)["results"]);  // the rows, as always; the aggregates are the REST reply's
  } else if (format == "csv") {
    c.out() << RenderResultsCsv((*rows)["results"]);
  } else {
    c.out() << RenderResults(*rows, c.OutRender());
  }
  return kExitOk;
}

void SetupWatch(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "SWEEP|CAMPAIGN-RUN", "a sweep id (12) or a campaign run (cr:7)");
  sub.add_option("--interval", a.interval_s, "seconds between polls")->check(CLI::Range(0.05, 3600.0));
  sub.add_option("--give-up-after", a.give_up_after_s,
                 "seconds an unreachable daemon is waited for (the last frame stays) before the watch ends")
      ->check(CLI::Range(0.0, 86400.0));
}

int RunWatch(Context& c) {
  auto target = ParseTarget(c.args.target);
  if (!target.ok()) return Fail(c, target.status(), kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  WatchOptions options;
  options.tty = c.env.out_is_tty;
  options.color = c.ColorFor(c.env.out_is_tty);
  options.interval_s = c.args.interval_s;
  options.give_up_after_s = c.args.give_up_after_s;
  options.notices = &c.err();
  auto last = Watch(**client, *target, options, c.clock(), c.out());
  if (!last.ok()) return Fail(c, last.status());
  return last->counts.failed > 0 ? kExitRunsFailed : kExitOk;
}

void SetupCancel(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "SWEEP", "a sweep id");
  AddJson(sub, a);
}

int RunCancel(Context& c) {
  auto id = ParseId(c.args.target, "SWEEP");
  if (!id.ok()) return Fail(c, id.status(), kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto reply = (*client)->CancelSweep(*id);
  if (!reply.ok()) return Fail(c, reply.status());
  if (c.args.json) {
    PrintJson(c, *reply);
    return kExitOk;
  }
  json cancel = reply->value("cancel", json::object());
  c.out() << "sweep " << *id << " cancelled: " << cancel.value("cancelled", 0) << " queued run(s) cancelled, "
          << cancel.value("stopping", 0) << " running run(s) told to stop\n";
  return kExitOk;
}

void SetupRerun(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "CAMPAIGN", "a campaign name (paper-58, or one stored in the daemon)");
  sub.add_option("--scale", a.scale, "scale to run at (default: the campaign's)");
  sub.add_flag("--force", a.force, "rerun every run, even those whose result is current");
  sub.add_option("--idempotency-key", a.idempotency_key, "rerunning again with the same key returns the same ids");
  AddJson(sub, a);
}

int RunRerun(Context& c) {
  if (!LooksLikeCampaignName(c.args.target)) {
    return Fail(
        c, Status::InvalidArgument("CAMPAIGN", "\"" + c.args.target + "\" is not a campaign name ([A-Za-z0-9._-]+)"),
        kExitUsage);
  }
  Input input;
  input.campaign = c.args.target;
  return SubmitBodyAndReport(c, SubmitBody(input, c.args));
}

void SetupExpand(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "FILE|CAMPAIGN",
            "a sweep or campaign JSON file (- for stdin), a builtin campaign name (offline) or a stored one (its "
            "definition from the daemon)");
  sub.add_option("--scale", a.scale, "scale to plan at (default: the file's or campaign's)");
  sub.add_option("--engine-version", a.engine_version, "the LIGGGHTS version for the keys (default: ask liggghts)");
  sub.add_flag("--cost", a.cost,
               "also print what it costs: particle-steps, core-hours, and the wall time on the daemon's workers at "
               "the rates it measured (a default rate when no daemon answers)");
  sub.add_option("--cores", a.cores,
                 "with --cost: also the wall time on this many cores (one-rank engines; a bed every queued run "
                 "waits for is costed on the idle ones, as sandswimd --local-workers N runs it)")
      ->check(CLI::PositiveNumber);
  AddJson(sub, a);
}

// The engine rates for `expand --cost`: the daemon's measured ones when one answers (and its
// local workers), else core/cost.h's defaults. Says which on stderr.
struct CostRates {
  EngineRate run = DefaultRate(), bed = DefaultBedRate();
  std::vector<RankRate> bed_by_ranks;  // beds per rank count; always holds ranks 1 (`bed`)
  bool daemon = false;                 // a daemon answered
  int slots = 0;                       // the daemon's local workers; 0: none, or no daemon answered
};
EngineRate RateFrom(const json& j, const EngineRate& fallback) {
  if (!j.is_object() || !j.value("s_per_unit", json()).is_number() || !(j["s_per_unit"].get<double>() > 0))
    return fallback;
  return {j["s_per_unit"].get<double>(), j.value("rel_error", fallback.rel_error), j.value("samples", 0),
          j.value("basis", std::string())};
}
CostRates RatesForCost(Context& c) {
  CostRates r;
  auto with_one_rank = [&r] { r.bed_by_ranks.insert(r.bed_by_ranks.begin(), RankRate{1, r.bed}); };
  auto client = c.Client();
  if (!client.ok()) {
    with_one_rank();
    return r;
  }
  auto model = (*client)->CostModel();
  if (!model.ok()) {
    c.err() << "sandswim: no cost model from the daemon (" << Describe(model.status())
            << "); costing at the default rates\n";
    with_one_rank();
    return r;
  }
  r.daemon = true;
  r.run = RateFrom(model->value("run_rate", json()), r.run);
  r.bed = RateFrom(model->value("bed_rate", json()), r.bed);
  // Beds on 2 or more ranks (a daemon before bed ranks were recorded sends none).
  const json by_ranks = model->value("bed_rates", json::array());
  for (const json& b : by_ranks.is_array() ? by_ranks : json::array()) {
    const int ranks = b.is_object() && b.value("ranks", json()).is_number_integer() ? b["ranks"].get<int>() : 0;
    if (ranks < 2) continue;
    const EngineRate rate = RateFrom(b, EngineRate{});
    if (rate.s_per_unit > 0) r.bed_by_ranks.push_back({ranks, rate});
  }
  with_one_rank();
  r.slots = model->value("engine_slots", 0);
  return r;
}

// "1 bed on 2 ranks", "3 beds: 2 on 1 rank, 1 on 6 ranks".
std::string DescribeBedRanks(const std::vector<int>& ranks) {
  std::map<int, int> count;
  for (int r : ranks) ++count[r];
  auto on = [](int r) { return " on " + std::to_string(r) + (r == 1 ? " rank" : " ranks"); };
  const std::string beds = std::to_string(ranks.size()) + (ranks.size() == 1 ? " bed" : " beds");
  if (count.size() == 1) return beds + on(count.begin()->first);
  std::string out = beds + ":";
  for (auto it = count.begin(); it != count.end(); ++it)
    out += (it == count.begin() ? " " : ", ") + std::to_string(it->second) + on(it->first);
  return out;
}

// "1h05m ± 20m"
std::string WithError(double s, double rel) { return FormatDuration(s) + " ± " + FormatDuration(s * rel); }

// The cost lines of `expand --cost` for every scale's plan, and their JSON.
// Beds are costed at the ranks they would get (core/cost.h BedRanks): on the daemon's local
// worker (--local-workers N: N slots, --max-ranks N) or, with no daemon, on this machine's cores
// as such a worker would run them; on --cores N as --local-workers N. A daemon with no local
// workers has workers that widen only with --max-ranks: its beds are costed on one rank.
json PrintCost(Context& c, const std::vector<ScalePlan>& plans) {
  const CostRates rates = RatesForCost(c);
  const int local = rates.slots > 0 ? rates.slots : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int local_max_ranks = rates.daemon && rates.slots == 0 ? 1 : local;
  json all = json::array();
  for (const ScalePlan& group : plans) {
    const PlanCost cost = CostOfPlan(group.plan, {}, rates.run, rates.bed);
    std::vector<std::pair<int, PlanWall>> walls = {
        {local, PlanWallOn(cost, local, local_max_ranks, rates.bed_by_ranks)}};
    if (c.args.cores > 0)
      walls.push_back({c.args.cores, PlanWallOn(cost, c.args.cores, c.args.cores, rates.bed_by_ranks)});
    json j = {{"scale", group.scale},
              {"runs", cost.runs},
              {"beds", cost.beds},
              {"particle_steps", cost.particle_steps},
              {"run_core_hours", cost.run_core_s / 3600},
              {"bed_core_hours", cost.bed_core_s / 3600},
              {"rel_error", cost.rel_error},
              {"s_per_particle_step", rates.run.s_per_unit},
              {"rate_basis", rates.run.basis},
              {"wall_s", json::object()},
              {"wall_rel_error", json::object()},
              {"bed_ranks", json::object()}};
    for (const auto& [cores, wall] : walls) {
      j["wall_s"][std::to_string(cores)] = wall.s;
      j["wall_rel_error"][std::to_string(cores)] = wall.rel_error;
      j["bed_ranks"][std::to_string(cores)] = wall.bed_ranks;
    }
    all.push_back(j);
    if (c.args.json) continue;
    char line[256];
    std::snprintf(line, sizeof line, "%s: %lld runs on %lld bed(s), %.3g particle-steps at most (each run to its deck's end)\n",
                  group.scale.c_str(), static_cast<long long>(cost.runs), static_cast<long long>(cost.beds),
                  cost.particle_steps);
    c.out() << line;
    std::snprintf(line, sizeof line,
                  "  %.3g core-hours of runs + %.2g of beds (on one rank), ± %.0f %%, at %.3g s a particle-step\n",
                  cost.run_core_s / 3600, cost.bed_core_s / 3600, cost.rel_error * 100, rates.run.s_per_unit);
    c.out() << line << "    (" << rates.run.basis << ")\n";
    for (size_t i = 0; i < walls.size(); ++i) {
      const auto& [cores, wall] = walls[i];
      c.out() << "  wall time on "
              << (i > 0             ? ""
                  : rates.slots > 0 ? "the daemon's "
                                    : "this machine's ")
              << cores << " one-rank engine(s): " << WithError(wall.s, wall.rel_error);
      if (cost.beds > 0) c.out() << " (" << DescribeBedRanks(wall.bed_ranks) << ")";
      c.out() << "\n";
    }
    if (cost.beds > 0) {
      const int widest = *std::max_element(walls.back().second.bed_ranks.begin(), walls.back().second.bed_ranks.end());
      c.out() << "    (beds first; the last bed granted, which every queued run waits for, runs on the slots still\n"
                 "     idle, as sandswimd --local-workers N widens it)\n"
              << "    (beds: " << BedRateOnRanks(rates.bed_by_ranks, widest).basis << ")\n";
    }
  }
  return all;
}

// "paper-58" (the built-in campaigns, for messages).
std::string BuiltinNames() {
  std::string names;
  for (const auto& n : BuiltinCampaignNames()) names += (names.empty() ? "" : ", ") + n;
  return names;
}

// The sweeps `input` names and the scale each runs at.
Result<std::vector<SweepSpec>> SweepsOf(const Input& input, const std::string& scale_flag) {
  std::vector<SweepSpec> sweeps;
  auto from_campaign = [&](const Campaign& campaign, const std::string& scale) {
    for (SweepSpec s : campaign.sweeps) {
      s.scale = scale.empty() ? campaign.scale : scale;
      sweeps.push_back(std::move(s));
    }
  };
  if (input.campaign || input.body.contains("campaign")) {
    std::string name = input.campaign                       ? *input.campaign
                       : input.body["campaign"].is_string() ? input.body["campaign"].get<std::string>()
                                                            : "";
    auto campaign = BuiltinCampaign(name);  // RunExpand fetched any other one from the daemon
    if (!campaign.ok()) return Status::NotFound("no builtin campaign \"" + name + "\" (builtin: " + BuiltinNames() + ")");
    std::string scale = scale_flag;
    if (scale.empty() && input.body.contains("scale") && input.body["scale"].is_string()) {
      scale = input.body["scale"].get<std::string>();
    }
    from_campaign(*campaign, scale);
    return sweeps;
  }
  json body = input.body;
  body.erase("force");
  if (body.contains("sweeps") && body.contains("name")) {
    auto campaign = ParseCampaign(body);
    if (!campaign.ok()) return campaign.status();
    from_campaign(*campaign, scale_flag);
    return sweeps;
  }
  std::vector<json> specs;
  if (body.contains("sweeps")) {
    if (!body["sweeps"].is_array()) return Status::InvalidArgument("sweeps", "must be an array of sweeps");
    for (const auto& s : body["sweeps"]) specs.push_back(s);
  } else {
    specs.push_back(body);
  }
  for (size_t i = 0; i < specs.size(); ++i) {
    if (!scale_flag.empty() && specs[i].is_object()) specs[i]["scale"] = scale_flag;
    auto spec = ParseSweep(specs[i]);
    if (!spec.ok()) {
      return body.contains("sweeps") ? spec.status().WithFieldPrefix("sweeps[" + std::to_string(i) + "]")
                                     : spec.status();
    }
    sweeps.push_back(std::move(*spec));
  }
  return sweeps;
}

// A campaign `expand` names that is not built in is one stored in the daemon: its current version's
// resolved definition (GET /api/v1/campaigns/NAME, with the daemon and token every command finds),
// expanded here as a campaign file would be. Says on stderr which version came from where; with no
// daemon to ask, says what to do instead.
Result<json> DaemonCampaignDefinition(Context& c, const std::string& name) {
  auto client = c.Client();
  if (!client.ok()) return client.status();
  auto reply = (*client)->GetCampaign(name, 0);
  if (!reply.ok()) {
    const Status& s = reply.status();
    if (s.code() == StatusCode::kUnavailable) {
      return Status(StatusCode::kUnavailable,
                    "campaign \"" + name + "\" is not built in (builtin: " + BuiltinNames() +
                        "), so expand asks the daemon for it: " + s.reason() +
                        "; or point --server at the daemon that stores it, or expand its definition from a "
                        "file: sandswim expand mine.json");
    }
    if (s.code() == StatusCode::kNotFound) {
      return Status(StatusCode::kNotFound,
                    "no campaign \"" + name + "\": not built in (builtin: " + BuiltinNames() +
                        ") and not stored in the daemon at " + (*client)->base_url() +
                        " (sandswim campaign list shows the ones it has)");
    }
    return s;
  }
  auto resolved = reply->find("resolved");
  if (resolved == reply->end() || !resolved->is_object()) {
    return Status::Corruption("the daemon's answer to GET /api/v1/campaigns/" + name + " has no \"resolved\" definition");
  }
  c.err() << "sandswim: campaign " << name << " version " << reply->value("version", 0)
          << " (as it runs, its base filled in) from the daemon at " << (*client)->base_url() << "\n";
  return *resolved;
}

int RunExpand(Context& c) {
  auto input = ReadInput(c, c.args.target);
  if (!input.ok()) return FailUsageIfInvalid(c, input.status());
  // A campaign by name (or a {"campaign": NAME} file) that is not built in: the daemon's.
  std::string named = input->campaign ? *input->campaign
                      : input->body.contains("campaign") && input->body["campaign"].is_string()
                          ? input->body["campaign"].get<std::string>()
                          : "";
  if (!named.empty() && !BuiltinCampaign(named).ok()) {
    auto definition = DaemonCampaignDefinition(c, named);
    if (!definition.ok()) return FailUsageIfInvalid(c, definition.status());
    if (c.args.scale.empty() && input->body.contains("scale") && input->body["scale"].is_string()) {
      c.args.scale = input->body["scale"].get<std::string>();
    }
    input->campaign.reset();
    input->body = std::move(definition).value();
  }
  auto sweeps = SweepsOf(*input, c.args.scale);
  if (!sweeps.ok()) return FailUsageIfInvalid(c, sweeps.status());
  std::string engine = c.args.engine_version;
  if (engine.empty()) {
    auto probed =
        c.env.probe_engine ? c.env.probe_engine() : Result<std::string>(Status::Unavailable("no engine probe"));
    if (probed.ok()) {
      engine = *probed;
    } else {
      engine = "unknown";
      c.err() << "sandswim: " << Describe(probed.status())
              << "; keys use engine version \"unknown\" (pass --engine-version to match the daemon's)\n";
    }
  }
  // The daemon's planning (core/sweep.h PlanSubmission), offline.
  PlanOptions options;
  options.keep_decks = false;
  auto plans = PlanSubmission(*sweeps, engine, options, /*campaign=*/false);
  if (!plans.ok()) return FailUsageIfInvalid(c, plans.status());
  json all = json::array();
  std::string lines;
  size_t runs = 0;
  for (const ScalePlan& group : *plans) {
    for (const PlannedRun& r : group.plan.runs) {
      json j = PlannedRunToJson(r);
      ++runs;
      if (c.args.json) {
        all.push_back(j);
        continue;
      }
      std::string sweep_names;
      for (const auto& s : r.sweeps) sweep_names += (sweep_names.empty() ? "" : ",") + s;
      lines += r.key.substr(0, 12) + "  " + FormatPoint(j) + "  (runs " + DisplayNumber(r.run_duration_s, 4) + " s, " +
               std::to_string(r.steps) + " steps at " + group.scale + ")  " + sweep_names + "\n";
    }
  }
  if (c.args.json) {
    if (c.args.cost) {
      PrintJson(c, {{"runs", all}, {"cost", PrintCost(c, *plans)}});
    } else {
      PrintJson(c, all);
    }
  } else {
    c.out() << lines;
    c.err() << "sandswim: " << runs << " distinct run(s); engine " << engine << "\n";
    if (c.args.cost) PrintCost(c, *plans);
  }
  return kExitOk;
}

void SetupReport(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "CAMPAIGN|CAMPAIGN-RUN", "a campaign name (its latest run) or a campaign run (cr:7)");
  sub.add_option("--scale", a.scale, "with CAMPAIGN: its latest run at this scale (default: any)");
  sub.add_option("--out", a.out_file, "where to write the HTML (default: sandswim-report-CAMPAIGN.html here)");
}

// Writes the campaign's HTML report (every figure inlined) and says where.
int RunReport(Context& c) {
  int64_t campaign_run = 0;
  std::string name;
  if (c.args.target.rfind("cr:", 0) == 0) {
    auto target = ParseTarget(c.args.target, "CAMPAIGN");
    if (!target.ok()) return FailUsageIfInvalid(c, target.status());
    campaign_run = target->id;
  } else if (LooksLikeCampaignName(c.args.target)) {
    name = c.args.target;
  } else {
    return Fail(
        c,
        Status::InvalidArgument(
            "CAMPAIGN", "expected a campaign name (paper-58) or a campaign run (cr:7), got \"" + c.args.target + "\""),
        kExitUsage);
  }
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto html = (*client)->CampaignReport(name, c.args.scale, campaign_run);
  if (!html.ok()) return Fail(c, html.status());
  std::string path = c.args.out_file;
  if (path.empty())
    path = "sandswim-report-" + (campaign_run > 0 ? "cr" + std::to_string(campaign_run) : name) + ".html";
  // Written aside and renamed: an interrupted write never leaves half a report under the name.
  const std::string temp = path + ".part";
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    out << *html;
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(temp, ignored);
      return Fail(c, Status::IOError("cannot write " + temp));
    }
  }
  std::error_code ec;
  std::filesystem::rename(temp, path, ec);
  if (ec) return Fail(c, Status::IOError("cannot write " + path + ": " + ec.message()));
  std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  c.out() << (ec ? path : absolute.string()) << "\n";
  c.err() << "sandswim: wrote the report (" << html->size() << " bytes, self-contained HTML): open it in a browser\n";
  return kExitOk;
}

void SetupCheck(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "CAMPAIGN-RUN", "a campaign run (cr:7)");
  AddJson(sub, a);
}

// The verdict of each claim the campaign states, for one campaign run. Exit 0 only when every
// claim holds; 3 when one differs or is inconclusive, or the campaign states none (the output says
// which and why), so that a script can tell "the findings hold" from everything else.
int RunCheck(Context& c) {
  auto target = ParseTarget(c.args.target, "CAMPAIGN-RUN");
  if (!target.ok()) return Fail(c, target.status(), kExitUsage);
  if (target->kind != Target::Kind::kCampaignRun) {
    return Fail(c,
                Status::InvalidArgument("CAMPAIGN-RUN",
                                        "claims belong to a campaign run: name one as cr:ID (cr:7); "
                                        "`sandswim status` lists them"),
                kExitUsage);
  }
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto reply = (*client)->CampaignRunClaims(target->id);
  if (!reply.ok()) return Fail(c, reply.status());
  if (c.args.json) {
    PrintJson(c, *reply);
  } else {
    c.out() << RenderClaims(*reply, c.OutRender());
  }
  const json claims = reply->value("claims", json::array());
  bool all_hold = !claims.empty();
  for (const auto& claim : claims) all_hold = all_hold && claim.value("verdict", "") == "holds";
  return all_hold ? kExitOk : kExitRunsFailed;
}

void SetupBackup(CLI::App& sub, Args& a) {
  sub.add_option("FILE", a.out_file, "where to write the copy (replaced when there; written aside and renamed)")
      ->required();
}

// Writes a consistent copy of the daemon's database (made while it serves) and says how to restore it.
int RunBackup(Context& c) {
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  const std::string& path = c.args.out_file;
  // Written aside and renamed: an interrupted download never leaves half a database under the name.
  const std::string temp = path + ".part";
  auto bytes = (*client)->DownloadBackup(temp);
  std::error_code ec;
  if (!bytes.ok()) {
    std::filesystem::remove(temp, ec);
    return Fail(c, bytes.status());
  }
  std::filesystem::rename(temp, path, ec);
  if (ec) {
    std::error_code ignored;
    std::filesystem::remove(temp, ignored);
    return Fail(c, Status::IOError("cannot write " + path + ": " + ec.message()));
  }
  std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  c.out() << (ec ? path : absolute.string()) << "\n";
  c.err() << "sandswim: wrote a consistent copy of the daemon's database (" << *bytes
          << " bytes, checked by the daemon with PRAGMA quick_check). To restore it: stop sandswimd, put the file "
             "at its --db path (removing any -wal and -shm files beside it), start sandswimd\n";
  return kExitOk;
}

// A number option that must be finite: "nan" or "inf" is a usage error, not a silent default.
const CLI::Validator kFinite(
    [](std::string& s) {
      double v = 0;
      return CLI::detail::lexical_cast(s, v) && std::isfinite(v) ? std::string() : "must be a finite number";
    },
    "FINITE");

void SetupAnalyze(CLI::App& sub, Args& a) {
  sub.add_option("DUMP", a.dumps,
                 "LIGGGHTS dump files of the SO (a run directory's so.dump, or any dump custom "
                 "with id, x, y, z)")
      ->required();
  sub.add_option("--f", a.an_f,
                 "drive frequency in Hz, 0 for constant rotation (default: from drive.in beside the dump)")
      ->check(kFinite);
  sub.add_option("--dt", a.an_dt, "time step in s (default: from the deck, else Table 1's 1e-5)")->check(kFinite);
  sub.add_option("--id", a.an_id, "the SO's atom id (default: the only atom, else the largest particle)")
      ->check(CLI::PositiveNumber);
  sub.add_option("--floor", a.an_floor, "z of the floor in m (default: from the deck; unknown: not checked)")
      ->check(kFinite);
  sub.add_option("--surface", a.an_surface,
                 "z of the bed surface in m (default: from log.liggghts beside the dump; unknown: not checked)")
      ->check(kFinite);
  sub.add_option("--deck", a.an_deck, "the run's deck (default: drive.in beside the dump)");
  sub.add_option("--log", a.an_log, "the run's engine log (default: log.liggghts beside the dump)");
  sub.add_option("--transient", a.an_rule.transient_s,
                 "s skipped at the start (the start-up transient; at least --transient-periods periods)")
      ->capture_default_str();
  sub.add_option("--transient-periods", a.an_rule.transient_blocks,
                 "whole periods (blocks, for constant rotation) skipped at the start at least")
      ->capture_default_str();
  sub.add_option("--clearance", a.an_rule.clearance_m,
                 "m of grains kept between the SO and the surface or floor: the window ends before")
      ->capture_default_str();
  sub.add_option("--min-periods", a.an_rule.min_periods, "fewer whole periods in the window: inconclusive")
      ->capture_default_str();
  sub.add_flag("--json", a.json, "print JSON instead of text");
}

// Analyses each dump as the worker would; goes on past a dump it cannot read (at the end, the exit
// code of the first failure: 2 for a usage error, 1 for an unreadable file).
int RunAnalyze(Context& c) {
  AnalyzeOptions o;
  if (!std::isnan(c.args.an_f)) o.f = c.args.an_f;
  if (!std::isnan(c.args.an_dt)) o.dt = c.args.an_dt;
  if (!std::isnan(c.args.an_floor)) o.floor = c.args.an_floor;
  if (!std::isnan(c.args.an_surface)) o.surface = c.args.an_surface;
  if (c.args.an_id >= 0) o.so_id = c.args.an_id;
  o.deck = c.args.an_deck;
  o.log = c.args.an_log;
  o.rule = c.args.an_rule;
  if (!(o.rule.transient_s >= 0) || !(o.rule.transient_blocks >= 0) || !(o.rule.clearance_m >= 0) ||
      o.rule.min_periods < 1) {
    return Fail(c,
                Status::InvalidArgument("--transient/--transient-periods/--clearance/--min-periods",
                                        "must be >= 0, >= 0, >= 0 and >= 1"),
                kExitUsage);
  }
  json all = json::array();
  int code = kExitOk;
  for (const std::string& dump : c.args.dumps) {
    auto a = AnalyzeDumpFile(dump, o);
    if (!a.ok()) {
      const int failed = a.status().code() == StatusCode::kInvalidArgument ? kExitUsage : kExitError;
      Fail(c, a.status(), failed);
      if (code == kExitOk) code = failed;  // the first failure decides the exit code
      continue;
    }
    if (c.args.json) {
      all.push_back(DumpAnalysisJson(*a));
    } else {
      c.out() << RenderDumpAnalysis(*a);
    }
  }
  if (c.args.json) PrintJson(c, all);
  return code;
}

void SetupVersion(CLI::App& sub, Args& a) { AddJson(sub, a); }

int RunVersion(Context& c) {
  json j = {{"client", ClientVersion()}};
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto health = (*client)->Healthz();
  j["server_url"] = (*client)->base_url();
  if (health.ok()) {
    j["server"] = *health;
  } else {
    j["server"] = nullptr;
    j["server_error"] = Describe(health.status());
  }
  if (c.args.json) {
    PrintJson(c, j);
    return kExitOk;
  }
  c.out() << "sandswim " << ClientVersion() << "\n";
  if (health.ok()) {
    c.out() << "daemon at " << (*client)->base_url() << ": " << health->value("status", "?") << ", engine "
            << health->value("engine_version", "?") << ", schema " << health->value("schema_version", 0) << "\n";
  } else {
    c.out() << "daemon at " << (*client)->base_url() << ": not reachable\n";
    c.err() << "sandswim: " << Describe(health.status()) << "\n";
  }
  return kExitOk;
}

void SetupSlurm(CLI::App& sub, Args& a) {
  sub.require_subcommand(1);
  CLI::App* submit = sub.add_subcommand(
      "submit",
      "sbatch a pilot (one sandswim-worker for the allocation) or, with --array, one one-shot worker per "
      "element; prints the Slurm job id");
  slurm::PilotRequest& r = a.slurm.request;
  submit->add_option("--nodes", r.nodes, "nodes per allocation")->capture_default_str();
  submit->add_option("--ranks-per-run", r.ranks_per_run, "MPI ranks of each run (srun -n)")->capture_default_str();
  submit->add_option("--time", r.time, "time limit, Slurm syntax (30, 2:00:00, 1-00:00:00)")->required();
  submit->add_option("--tasks-per-node", r.tasks_per_node,
                     "pilot: CPUs (tasks) per node; runs side by side = tasks / ranks-per-run (default: one run)");
  submit->add_option("--array", r.array, "a job array of this many elements, one run each (instead of a pilot)");
  submit->add_option("--throttle", r.throttle, "array elements running at once (%k)");
  submit->add_option("--partition", r.partition, "Slurm partition");
  submit->add_option("--account", r.account, "Slurm account");
  submit->add_option("--job-name", r.job_name, "Slurm job name")->capture_default_str();
  submit->add_option("--output", r.output, "sbatch --output pattern for the worker's log");
  submit->add_option("--script", r.script, "the batch script (default: pilot.sbatch / array.sbatch, see deploy/slurm/README.md)");
  submit->add_option("--worker", a.slurm.worker, "sandswim-worker on the compute nodes (default: on PATH)");
  submit->add_option("--workdir", a.slurm.workdir, "run directories on the compute nodes");
  submit
      ->add_option("--end-margin", a.slurm.end_margin_s,
                   "seconds a run is expected to take before a worker has finished one")
      ->check(CLI::NonNegativeNumber);
  AddJson(*submit, a);
}

int RunSlurm(Context& c) {
  auto options = ResolveClientOptions(c.args.server, c.args.token_file, c.env.getenv, c.args.tls_fingerprint, c.args.tls_ca);
  if (!options.ok()) return FailUsageIfInvalid(c, options.status());
  SlurmSubmitOptions submit = c.args.slurm;
  submit.server = options->server;
  submit.token = options->token;
  submit.scripts_dir = DefaultSlurmScriptsDir(c.env.getenv("SANDSWIM_SLURM_SCRIPTS"));
  std::unique_ptr<slurm::SlurmCommands> commands =
      c.env.make_slurm ? c.env.make_slurm() : std::make_unique<slurm::ProcessSlurmCommands>();
  auto done = SubmitToSlurm(*commands, submit);
  if (!done.ok()) return FailUsageIfInvalid(c, done.status());
  if (c.args.json) {
    PrintJson(c, {{"job_id", done->job_id}, {"sbatch", done->sbatch}, {"server", submit.server}});
    return kExitOk;
  }
  c.out() << done->job_id << "\n";
  const slurm::PilotRequest& r = submit.request;
  c.err() << "sandswim: submitted " << (r.array > 0 ? "job array " : "pilot ") << done->job_id << " (runs of "
          << r.ranks_per_run << " rank(s), time " << r.time << ", workers report to " << submit.server << ")\n";
  return kExitOk;
}

// ---- The tables' rows --------------------------------------------------------------------------

struct Command {
  const char* name;
  const char* summary;
  const char* examples;
  void (*setup)(CLI::App&, Args&);
  int (*run)(Context&);
};

// ---- campaign ... and schedule: campaigns as data -------------------------------------------------

void AddScaleChoice(CLI::App& sub, Args& a, const std::string& help) {
  sub.add_option("--scale", a.scale, help)->check(CLI::IsMember({"paper", "mini", "smoke"}));
}

void AddCampaignName(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "NAME", "a campaign name (built-in such as paper-58, or stored)");
}

// The positional NAME as a campaign's name (core/campaign_definition.h), checked before any request.
Status CheckNameArg(const Context& c) { return CheckCampaignName("NAME", c.args.target); }

void SetupCampaignList(CLI::App& sub, Args& a) { AddJson(sub, a); }

// Every campaign, each with its latest campaign run (one request each: campaigns are few).
int RunCampaignList(Context& c) {
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto campaigns = (*client)->ListCampaigns();
  if (!campaigns.ok()) return Fail(c, campaigns.status());
  for (json& campaign : *campaigns) {
    auto runs = (*client)->ListCampaignRuns(campaign.value("name", ""), 1);
    if (!runs.ok()) return Fail(c, runs.status());
    campaign["last_run"] = runs->empty() ? json(nullptr) : (*runs)[0];
  }
  if (c.args.json) {
    PrintJson(c, *campaigns);
  } else {
    c.out() << RenderCampaignsTable(*campaigns);
  }
  return kExitOk;
}

void SetupCampaignShow(CLI::App& sub, Args& a) {
  AddCampaignName(sub, a);
  sub.add_option("--version", a.version, "this version of it (default: the current one)")->check(CLI::PositiveNumber);
  sub.add_flag("--resolved", a.resolved, "the definition that runs (its base's fields filled in), not as written");
  AddJson(sub, a);
}

int RunCampaignShow(Context& c) {
  if (Status s = CheckNameArg(c); !s.ok()) return Fail(c, s, kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto reply = (*client)->GetCampaign(c.args.target, c.args.version);
  if (!reply.ok()) return Fail(c, reply.status());
  if (c.args.json) {
    PrintJson(c, *reply);
  } else {
    c.out() << RenderCampaignDetail(*reply, c.args.resolved, c.OutRender());
  }
  return kExitOk;
}

void SetupCampaignPut(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "FILE", "a campaign definition (JSON, schema/campaign.schema.json); - for stdin");
  AddJson(sub, a);
}

// The name a definition is stored under: its own "name".
Result<std::string> NameOfDefinition(const json& definition) {
  auto name = definition.find("name");
  if (name == definition.end() || !name->is_string()) {
    return Status::InvalidArgument("name", "the definition must name its campaign: {\"name\": \"mine\", ...}");
  }
  if (Status s = CheckCampaignName("name", name->get<std::string>()); !s.ok()) return s;
  return name->get<std::string>();
}

// Stores a definition as a new campaign or a new version of one; the daemon validates it and stores
// nothing it refuses (the refusal names the field).
int RunCampaignPut(Context& c) {
  auto definition =
      ReadJsonObject(c, c.args.target, "a campaign: {\"name\": ..., \"extends\": ...} or with \"sweeps\"");
  if (!definition.ok()) return FailUsageIfInvalid(c, definition.status());
  auto name = NameOfDefinition(*definition);
  if (!name.ok()) return Fail(c, name.status(), kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto reply = (*client)->PutCampaign(*name, *definition);
  if (!reply.ok()) return Fail(c, reply.status());
  if (c.args.json) {
    PrintJson(c, *reply);
  } else {
    c.out() << RenderCampaignStored(*reply);
  }
  return kExitOk;
}

void SetupCampaignEdit(CLI::App& sub, Args& a) { AddCampaignName(sub, a); }

// A name for the user's copy of built-in campaign `name` that no campaign has yet: NAME-copy,
// else NAME-copy-2 ... -9 (else NAME-copy, which the daemon refuses only if it is built-in).
std::string CopyName(DaemonClient& client, const std::string& name) {
  for (int i = 1; i <= 9; ++i) {
    std::string copy = name + "-copy" + (i > 1 ? "-" + std::to_string(i) : "");
    auto existing = client.GetCampaign(copy, 0);
    if (!existing.ok() && existing.status().code() == StatusCode::kNotFound) return copy;
  }
  return name + "-copy";
}

// A yes/no question on stderr, the answer from stdin (default yes; the end of input is no).
bool Ask(Context& c, const std::string& question) {
  c.err() << "sandswim: " << question << " [Y/n] " << std::flush;
  std::string line;
  if (!std::getline(*c.env.in, line)) {
    c.err() << "\n";
    return false;
  }
  const size_t start = line.find_first_not_of(" \t\r");
  return start == std::string::npos || line[start] == 'y' || line[start] == 'Y';
}

// Opens the definition in $EDITOR and saves it when it changed; a built-in campaign is read-only,
// so editing one starts a copy that extends it.
int RunCampaignEdit(Context& c) {
  if (Status s = CheckNameArg(c); !s.ok()) return Fail(c, s, kExitUsage);
  const std::string& name = c.args.target;
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto current = (*client)->GetCampaign(name, 0);
  if (!current.ok()) {
    if (current.status().code() != StatusCode::kNotFound) return Fail(c, current.status());
    return Fail(c, Status(StatusCode::kNotFound,
                          "no campaign '" + name +
                              "' to edit (sandswim campaign list names them; `sandswim campaign edit paper-58` starts "
                              "a copy of a built-in one, `sandswim campaign put FILE` stores a new one)",
                          "NAME"));
  }
  const bool builtin = current->value("builtin", false);
  std::string text;
  if (builtin) {
    const std::string copy = CopyName(**client, name);
    text = json{{"name", copy}, {"extends", name}}.dump(2) + "\n";
    c.err() << "sandswim: " << name << " is built-in and read-only: this starts your own campaign \"" << copy
            << "\" that extends it. Rename it if you like, add the fields to change (\"replicates\": 3, "
               "\"scale\", \"precision\", \"sweeps\": [names of "
            << name << "'s sweeps to keep], \"claims\": [ids to keep]; `sandswim campaign show " << name
            << "` lists them); saving stores it under its \"name\"\n";
  } else {
    text = current->value("definition", json::object()).dump(2) + "\n";
  }
  const std::string editor = EditorCommand(c.env.getenv);
  EditEdges edges;
  edges.open = [&](const std::string& path) {
    return c.env.run_editor ? c.env.run_editor(editor, path) : OpenInEditor(editor, path);
  };
  edges.ask = [&](const std::string& question) { return Ask(c, question); };
  std::string saved_as;
  edges.save = [&](const json& definition) -> Result<json> {
    // A stored campaign's file may leave its name out; a copy must have one of its own.
    std::string to = builtin ? "" : name;
    if (definition.contains("name")) {
      auto named = NameOfDefinition(definition);
      if (!named.ok()) return named.status();
      to = *named;
    } else if (builtin) {
      return Status::InvalidArgument("name", "name your copy: {\"name\": \"mine\", \"extends\": \"" + name + "\"}");
    }
    saved_as = to;
    return (*client)->PutCampaign(to, definition);
  };
  const char* tmp = c.env.getenv("TMPDIR");
  const std::string dir = tmp != nullptr && *tmp != '\0' ? tmp : "/tmp";
  auto outcome = EditUntilSaved(text, dir, name, edges, c.err());
  if (!outcome.ok()) return Fail(c, outcome.status());
  switch (outcome->kind) {
    case EditOutcome::Kind::kSaved:
      c.out() << RenderCampaignStored(outcome->reply);
      if (!builtin && saved_as != name) {
        c.err() << "sandswim: saved as campaign " << saved_as << " (the file names it); " << name << " is as it was\n";
      }
      return kExitOk;
    case EditOutcome::Kind::kUnchanged:
      c.err() << "sandswim: no change; nothing saved"
              << (builtin ? "" : " (" + name + " is still version " + current->value("version", json()).dump() + ")")
              << "\n";
      return kExitOk;
    case EditOutcome::Kind::kKept:
      break;
  }
  c.err() << "sandswim: nothing saved; your text is kept in " << outcome->kept_path
          << " (once fixed: sandswim campaign put " << outcome->kept_path << ")\n";
  return kExitError;
}

void SetupCampaignRm(CLI::App& sub, Args& a) { AddTarget(sub, a, "NAME", "a stored campaign's name"); }

// Removes a stored campaign (and its schedule); its past campaign runs stay readable, and the
// output names them.
int RunCampaignRm(Context& c) {
  if (Status s = CheckNameArg(c); !s.ok()) return Fail(c, s, kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  auto before = (*client)->GetCampaign(c.args.target, 0);
  if (Status s = (*client)->DeleteCampaign(c.args.target); !s.ok()) return Fail(c, s);
  std::string runs;
  if (before.ok()) {
    for (const auto& r : before->value("runs", json::array())) runs += " cr:" + r.value("id", json(0)).dump();
  }
  c.out() << "removed campaign " << c.args.target << "\n";
  if (!runs.empty()) {
    c.err() << "sandswim: its past campaign runs stay readable (sandswim status / results / check):" << runs << "\n";
  }
  return kExitOk;
}

void SetupCampaignRun(CLI::App& sub, Args& a) {
  AddCampaignName(sub, a);
  AddScaleChoice(sub, a, "scale to run at: paper, mini or smoke (default: the campaign's)");
  sub.add_flag("--force", a.force, "rerun even runs whose result is already stored");
  sub.add_flag("--wait", a.wait, "follow the runs (progress on stderr, as `watch`), then print the results");
  sub.add_option("--interval", a.interval_s, "with --wait: seconds between polls")->check(CLI::Range(0.05, 3600.0));
  AddJson(sub, a);
}

int RunCampaignRun(Context& c) {
  if (Status s = CheckNameArg(c); !s.ok()) return Fail(c, s, kExitUsage);
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  json body = json::object();
  if (!c.args.scale.empty()) body["scale"] = c.args.scale;
  if (c.args.force) body["force"] = true;
  auto reply = (*client)->RunCampaign(c.args.target, body);
  if (!reply.ok()) return Fail(c, reply.status());
  return ReportSubmission(c, **client, *reply);
}

// clang-format off
const Command kCampaignCommands[] = {
  {"list", "every campaign: version, built-in, what it extends, schedule, its last run",
   "  sandswim campaign list\n"
   "  sandswim campaign list --json",
   SetupCampaignList, RunCampaignList},
  {"show", "one campaign: its plan, schedule, notes, definition, versions and runs",
   "  sandswim campaign show paper-58\n"
   "  sandswim campaign show mine --version 2 --resolved",
   SetupCampaignShow, RunCampaignShow},
  {"put", "store a definition (a new campaign, or a new version of one); prints the version and notes",
   "  sandswim campaign put mine.json\n"
   "  echo '{\"name\":\"p58-3beds\",\"extends\":\"paper-58\",\"replicates\":3}' | sandswim campaign put -",
   SetupCampaignPut, RunCampaignPut},
  {"edit", "edit a campaign in $EDITOR (VISUAL, EDITOR, else vi); saved when changed and valid, else re-open it; "
           "a built-in one starts your own copy",
   "  sandswim campaign edit mine\n"
   "  EDITOR=nano sandswim campaign edit paper-58   # a new campaign paper-58-copy extending it",
   SetupCampaignEdit, RunCampaignEdit},
  {"rm", "remove a stored campaign and its schedule (its past runs stay readable)",
   "  sandswim campaign rm mine",
   SetupCampaignRm, RunCampaignRm},
  {"run", "submit a campaign; prints the campaign run (cr:ID) and its sweeps",
   "  sandswim campaign run mine\n"
   "  sandswim campaign run p58-3beds --scale smoke --wait",
   SetupCampaignRun, RunCampaignRun},
};
// clang-format on

void SetupCampaignGroup(CLI::App& sub, Args& a) {
  sub.require_subcommand(1);
  for (const Command& command : kCampaignCommands) {
    CLI::App* s = sub.add_subcommand(command.name, command.summary);
    s->footer(std::string("Examples:\n") + command.examples + "\n");
    command.setup(*s, a);
    s->callback([&a, run = command.run] { a.campaign_action = run; });
  }
}

int RunCampaignGroup(Context& c) { return c.args.campaign_action ? c.args.campaign_action(c) : kExitUsage; }

void SetupSchedule(CLI::App& sub, Args& a) {
  AddTarget(sub, a, "NAME", "a campaign (built-in or stored); none: list the schedules", false);
  sub.add_option("CRON", a.cron, "when, cron's five fields in the daemon's local time zone (\"0 2 * * *\": 02:00 every night)");
  AddScaleChoice(sub, a, "with CRON: the scale its runs take (default: the campaign's)");
  sub.add_flag("--off", a.off, "remove its schedule");
  AddJson(sub, a);
}

// `schedule`: the schedules; `schedule NAME CRON`: set one (stored: it survives a restart);
// `schedule NAME --off`: remove it.
int RunSchedule(Context& c) {
  std::string cron;
  for (const std::string& word : c.args.cron) cron += (cron.empty() ? "" : " ") + word;
  if (c.args.target.empty()) {
    if (c.args.off || !c.args.scale.empty()) {
      return Fail(c, Status::InvalidArgument("NAME", "name the campaign: sandswim schedule NAME --off"), kExitUsage);
    }
  } else if (Status s = CheckNameArg(c); !s.ok()) {
    return Fail(c, s, kExitUsage);
  } else if (c.args.off == !cron.empty()) {
    return Fail(
        c,
        Status::InvalidArgument("CRON", "give CRON (sandswim schedule " + c.args.target +
                                            " \"0 2 * * *\") or --off, not " + (c.args.off ? "both" : "neither")),
        kExitUsage);
  } else if (c.args.off && !c.args.scale.empty()) {
    return Fail(c, Status::InvalidArgument("--scale", "goes with CRON, not with --off"), kExitUsage);
  }
  auto client = c.Client();
  if (!client.ok()) return FailUsageIfInvalid(c, client.status());
  if (c.args.target.empty()) {
    auto campaigns = (*client)->ListCampaigns();
    if (!campaigns.ok()) return Fail(c, campaigns.status());
    json schedules = json::array();
    for (const json& campaign : *campaigns) {
      json s = campaign.value("schedule", json());
      if (s.is_null()) continue;
      if (s.is_string()) s = {{"cron", s}};
      s["campaign"] = campaign.value("name", "");
      schedules.push_back(s);
    }
    if (c.args.json) {
      PrintJson(c, schedules);
      return kExitOk;
    }
    c.out() << RenderSchedulesTable(*campaigns);
    if (schedules.empty()) c.err() << "sandswim: no campaign is scheduled (sandswim schedule NAME \"0 2 * * *\")\n";
    return kExitOk;
  }
  if (c.args.off) {
    if (Status s = (*client)->DeleteSchedule(c.args.target); !s.ok()) return Fail(c, s);
    c.out() << c.args.target << ": no schedule\n";
    return kExitOk;
  }
  json body = {{"cron", cron}};
  if (!c.args.scale.empty()) body["scale"] = c.args.scale;
  auto reply = (*client)->PutSchedule(c.args.target, body);
  if (!reply.ok()) return Fail(c, reply.status());
  if (c.args.json) {
    PrintJson(c, *reply);
  } else {
    c.out() << c.args.target << ": " << FormatSchedule(*reply) << "\n";
  }
  return kExitOk;
}

// ---- The table ---------------------------------------------------------------------------------

// clang-format off
const Command kCommands[] = {
  {"submit", "submit a sweep file or a campaign; prints the sweep id(s) or the campaign run (cr:ID)",
   "  sandswim submit sweep.json\n"
   "  sandswim submit - < sweep.json\n"
   "  sandswim submit paper-58 --scale mini\n"
   "  sandswim submit sweep.json --wait        # follow it, then print the results (exit 3: some failed)",
   SetupSubmit, RunSubmit},
  {"status", "counts, runs in flight, failures and ETA of a sweep or campaign run (none: all sweeps); "
             "for a campaign name, its last drift report",
   "  sandswim status\n"
   "  sandswim status 12\n"
   "  sandswim status cr:7 --json\n"
   "  sandswim status paper-58 --scale smoke",
   SetupStatus, RunStatus},
  {"runs", "list runs (all pages), optionally of one sweep or in one state",
   "  sandswim runs --sweep 12\n"
   "  sandswim runs --state failed --limit 20\n"
   "  sandswim runs --sweep 12 --json",
   SetupRuns, RunRuns},
  {"show", "one run: point, state, progress, result, deck and log tail",
   "  sandswim show 42\n"
   "  sandswim show 42 --json",
   SetupShow, RunShow},
  {"results",
   "one row per run: point, U_z, dz, flags, state; with replicate beds, then one row per point: mean U_z ± its "
   "standard error over the beds, between-bed sd, K (campaign runs: cr:ID or --campaign-run ID)",
   "  sandswim results 12\n"
   "  sandswim results 12 --format csv > omega.csv\n"
   "  sandswim results cr:7 --format json\n"
   "  sandswim results --campaign-run 7",
   SetupResults, RunResults},
  {"watch", "follow a sweep or campaign run until nothing is queued or running (exit 3: some failed)",
   "  sandswim watch 12\n"
   "  sandswim watch cr:7 --interval 5\n"
   "  sandswim watch 12 | tee progress.log   # plain lines when piped",
   SetupWatch, RunWatch},
  {"cancel", "cancel a sweep: its queued runs are cancelled, its running runs stop",
   "  sandswim cancel 12",
   SetupCancel, RunCancel},
  {"rerun", "submit a campaign again; results whose content key is unchanged are reused",
   "  sandswim rerun paper-58\n"
   "  sandswim rerun paper-58 --scale mini --force",
   SetupRerun, RunRerun},
  {"campaign", "your own campaigns: list, show, put, edit, rm, run (`sandswim campaign --help`)",
   "  sandswim campaign list\n"
   "  echo '{\"name\":\"p58-3beds\",\"extends\":\"paper-58\",\"replicates\":3}' | sandswim campaign put -\n"
   "  sandswim campaign run p58-3beds --scale smoke\n"
   "  sandswim campaign edit paper-58                # your own copy, in $EDITOR",
   SetupCampaignGroup, RunCampaignGroup},
  {"schedule", "rerun a campaign on a cron schedule (stored: survives a restart); none: list the schedules",
   "  sandswim schedule p58-3beds \"0 2 * * *\" --scale smoke\n"
   "  sandswim schedule p58-3beds --off\n"
   "  sandswim schedule",
   SetupSchedule, RunSchedule},
  {"expand", "the distinct runs a sweep or campaign plans to (offline; a stored campaign is fetched from the daemon)",
   "  sandswim expand sweep.json\n"
   "  sandswim expand paper-58 --json | jq length   # 58\n"
   "  sandswim expand paper-58 --scale smoke\n"
   "  sandswim expand paper-58 --scale smoke --cost --cores 8\n"
   "  sandswim expand mine --scale smoke        # a stored campaign: its current version, from the daemon",
   SetupExpand, RunExpand},
  {"report", "write a campaign's HTML report (figures, fits, drift report) to a file and print its path",
   "  sandswim report paper-58\n"
   "  sandswim report paper-58 --scale smoke --out paper-58.html\n"
   "  sandswim report cr:7",
   SetupReport, RunReport},
  {"check", "which of the campaign's claims (the paper's findings) hold, differ or are inconclusive for one campaign "
   "run, with the numbers behind each and the paper's (exit 0: every claim holds; 3: one differs or is inconclusive, "
   "or there are none)",
   "  sandswim check cr:7\n"
   "  sandswim check cr:7 --json | jq '.claims[] | {id, verdict}'",
   SetupCheck, RunCheck},
  {"backup", "write a consistent copy of the daemon's database, made while it runs, to FILE",
   "  sandswim backup sandswim-$(date +%F).db",
   SetupBackup, RunBackup},
  {"analyze", "offline: U_z of LIGGGHTS dumps of the SO, analysed exactly as the worker does (no daemon needed)",
   "  sandswim analyze var/data/runs/42/so.dump       # drive.in and log.liggghts beside it are read\n"
   "  sandswim analyze old/*.dump --f 3 --floor -0.5 --json\n"
   "  sandswim analyze bed.dump --id 2621 --f 3        # a dump of every particle: the SO by its id",
   SetupAnalyze, RunAnalyze},
  {"version", "the client's version and the daemon's /healthz answer",
   "  sandswim version\n"
   "  sandswim version --json",
   SetupVersion, RunVersion},
  {"slurm", "run workers on a Slurm cluster: `slurm submit` sbatches a pilot or a job array of workers",
   "  sandswim --server http://login1:8080 slurm submit --nodes 2 --ranks-per-run 4 --tasks-per-node 16 --time 4:00:00\n"
   "  sandswim slurm submit --array 58 --throttle 8 --ranks-per-run 4 --time 30",
   SetupSlurm, RunSlurm},
};
// clang-format on

}  // namespace

std::vector<std::string> CommandNames() {
  std::vector<std::string> names;
  for (const Command& c : kCommands) names.push_back(c.name);
  return names;
}

const char* ClientVersion() { return SANDSWIM_VERSION; }

int RunCli(int argc, const char* const* argv, Environment& env) {
  Args args;
  CLI::App app{"sandswim: submit, follow and read DEM parameter studies run by sandswimd"};
  app.footer("Where the daemon is: --server, else $SANDSWIM_SERVER, else " + std::string(kDefaultServer) +
             ".\nSweeps are named by id (12), campaign runs by cr:ID (cr:7).\n"
             "Exit codes: 0 ok, 1 error, 2 bad arguments, 3 finished but some runs failed (check: not every claim "
             "holds).\n");
  app.require_subcommand(1);
  app.fallthrough();
  app.add_option("--server", args.server, "daemon URL, http://HOST:PORT or https://HOST:PORT (else $SANDSWIM_SERVER)");
  app.add_option("--tls-fingerprint", args.tls_fingerprint,
                 "for https: the daemon's certificate must have this SHA-256 fingerprint, as sandswimd prints it "
                 "(else $SANDSWIM_TLS_FINGERPRINT; for a daemon on loopback, ./var/data/tls/cert.pem's)");
  app.add_option("--tls-ca", args.tls_ca,
                 "for https: CA certificate(s) (PEM) the daemon's certificate must chain to (else $SANDSWIM_TLS_CA, "
                 "else the system's CAs)");
  app.add_option(
      "--token-file", args.token_file,
      "file holding the bearer token (else $SANDSWIM_TOKEN, else ./var/data/token for a daemon on loopback)");
  app.add_flag("--no-color", args.no_color, "no colour (also: NO_COLOR set, or output not a terminal)");

  std::vector<std::pair<CLI::App*, const Command*>> subs;
  for (const Command& command : kCommands) {
    CLI::App* sub = app.add_subcommand(command.name, command.summary);
    sub->footer(std::string("Examples:\n") + command.examples + "\n");
    command.setup(*sub, args);
    subs.emplace_back(sub, &command);
  }

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    int code = app.exit(e, *env.out, *env.err);
    return code == 0 ? kExitOk : kExitUsage;
  }
  Context context(args, env);
  for (const auto& [sub, command] : subs) {
    if (sub->parsed()) return command->run(context);
  }
  return kExitUsage;
}

}  // namespace sandswim::cli
