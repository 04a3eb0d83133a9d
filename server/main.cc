// sandswimd: the process. Flags -> Store, LeaseQueue, ApiServer, the periodic jobs
// (server/periodic.h: lease expiry, the Slurm pilot watch, the scheduler's nightly reruns and drift
// reports) and the local-worker supervisor; SIGTERM/SIGINT stop them in reverse order. Before it
// serves, it recovers what a stopped daemon left, in this order, each step a call into the module
// that owns it: results of an older analysis analysed again (Store::ReanalyzeOldResults), the
// scratch directories emptied (ClearScratchDirs: unfinished backups and uploads), the running
// jobs' leases extended by the outage (LeaseQueue::ExtendLeasesAfterRestart), snapshot files no
// run recorded removed (LeaseQueue::RemoveUnrecordedSnapshots). A step that fails ends the start,
// saying what to check.
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <string>
#include <thread>
#include <vector>

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include "platform/clock.h"
#include "platform/data_dir.h"
#include "platform/engine_probe.h"
#include "platform/files.h"
#include "platform/tls.h"
#include "platform/token.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/claims_cache.h"
#include "server/analysis/drift_report.h"
#include "server/jobs/lease_queue.h"
#include "server/dashboard/live_feed.h"
#include "server/local_workers.h"
#include "server/jobs/rounds.h"
#include "server/periodic.h"
#include "server/jobs/pilot_watch.h"
#include "server/analysis/plot_renderer.h"
#include "server/http/routes.h"
#include "server/jobs/scheduler.h"
#include "server/store/eta_cache.h"
#include "server/store/store.h"

namespace {

using sandswim::Status;

struct Flags {
  std::string db = "./var/sandswim.db";
  std::string listen = "127.0.0.1:8640";
  std::string data = sandswim::kDefaultDataDir;
  std::string token_file;
  bool no_token = false;
  bool public_reads = false;
  std::string tls;  // "" or "self-signed"
  std::string tls_cert, tls_key;
  bool plain_http = false;
  std::vector<std::string> allow_hosts;
  int local_workers = 0;
  double lease_ttl_s = 60;
  int max_attempts = 3;
  double wall_budget_s = 0;
  std::string engine_version;
  std::string log_level = "info";
  std::vector<std::string> schedules;  // NAME[:SCALE]
  double scheduler_tick_s = 20;
  double slurm_check_s = 30;
  double http_head_timeout_s = 10;
  sandswim::ConnectionLimits http;  // the rest of the HTTP server's limits
  int live_streams_per_client = 8;
  int64_t max_queued_runs = sandswim::kMaxQueuedRuns;
  int max_renderers = 4;
};

void AddFlags(CLI::App& app, Flags& flags) {
  app.add_option("--db", flags.db, "SQLite file")->capture_default_str();
  app.add_option("--listen", flags.listen, "HOST:PORT to serve on (port 0: any free port)")->capture_default_str();
  app.add_option("--data", flags.data, "directory for beds, dumps and artifacts")->capture_default_str();
  app.add_option("--token-file", flags.token_file,
                 "file holding the bearer token (else $SANDSWIM_TOKEN, else DATA/token, made on the first start)");
  app.add_flag("--no-token", flags.no_token,
               "serve without a token (loopback only): anyone on this machine may read and write");
  app.add_flag("--public-reads", flags.public_reads, "reads (GET) need no token; writes still do");
  app.add_option("--tls", flags.tls,
                 "serve HTTPS with a certificate of its own: self-signed, made in DATA/tls on the first start "
                 "(its fingerprint is printed: pin it on workers and the CLI with --tls-fingerprint)")
      ->check(CLI::IsMember({"self-signed"}));
  app.add_option("--tls-cert", flags.tls_cert, "serve HTTPS with this certificate (PEM, with its chain)");
  app.add_option("--tls-key", flags.tls_key, "the certificate's private key (PEM, mode 0600, this user's)");
  app.add_flag("--plain-http", flags.plain_http,
               "serve plain HTTP on a non-loopback --listen (refused otherwise: the token and the decks would "
               "cross the network readable); for a TLS proxy or a private network in front");
  app.add_option("--allow-host", flags.allow_hosts,
                 "a name clients reach the daemon by, besides its address and localhost (repeatable; e.g. "
                 "the login node's name for Slurm workers, a proxy's name); other Host headers get 421");
  app.add_option("--local-workers", flags.local_workers,
                 "engines to run at once on this machine (one worker process with that many one-rank slots; a "
                 "job granted while nothing else is leasable takes the idle slots as extra ranks)")
      ->capture_default_str()
      ->check(CLI::Range(0, 1024));
  app.add_option("--lease-ttl", flags.lease_ttl_s, "seconds a lease lives without a heartbeat")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 86400.0));
  app.add_option("--max-attempts", flags.max_attempts, "leases a job gets before it fails")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  app.add_option("--wall-budget", flags.wall_budget_s,
                 "seconds of wall time a lease may run before its worker stops it as a time-out (0: 4x the cost "
                 "model's prediction for the job + 600 s; a hung engine is stopped anyway once its simulated time stands still: sandswim-worker --stall-after)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--http-head-timeout", flags.http_head_timeout_s,
                 "seconds a client may take to send a request's line and headers, from their first byte "
                 "(a slower connection is closed)")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 3600.0));
  app.add_option("--http-threads", flags.http.threads,
                 "requests served at once (any route); past them a request is answered 503 with Retry-After")
      ->capture_default_str()
      ->check(CLI::Range(2, 4096));
  app.add_option("--http-reserved-threads", flags.http.reserved_threads,
                 "more threads that serve only the worker protocol and /healthz, so that readers cannot cost "
                 "a worker its lease")
      ->capture_default_str()
      ->check(CLI::Range(1, 1024));
  app.add_option("--http-connections-per-client", flags.http.max_connections_per_client,
                 "connections one client (a peer address; every loopback address together) may open; past them its new connections are served only for the "
                 "worker protocol and /healthz, anything else answered 429 with Retry-After")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_flag("--http-loopback-clients-apart", flags.http.loopback_clients_apart,
               "count each loopback address (127.0.0.0/8, ::1) as a client of its own for "
               "--http-connections-per-client and the wrong-token throttle (default: all of them are one client, the local host, since a local "
               "user can connect from any of them)");
  app.add_option("--http-max-connections", flags.http.max_connections,
                 "connections open in all (at most the file limit allows); past them a new one is closed at once")
      ->capture_default_str()
      ->check(CLI::Range(16, 1000000));
  app.add_option("--http-requests-per-connection", flags.http.max_requests_per_connection,
                 "requests one keep-alive connection may carry before the server closes it")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  app.add_option("--max-queued-runs", flags.max_queued_runs,
                 "runs queued or running across all sweeps; a submission past it is refused (503) and stores nothing")
      ->capture_default_str()
      ->check(CLI::Range(int64_t{1}, int64_t{100000000}));
  app.add_option("--max-renderers", flags.max_renderers,
                 "figure renderers (sandswim-render processes) at once; a figure past them waits up to 10 s, "
                 "then is answered 503 with Retry-After")
      ->capture_default_str()
      ->check(CLI::Range(1, 256));
  app.add_option("--live-streams-per-client", flags.live_streams_per_client,
                 "dashboard live streams (GET /api/v1/live/events) one peer address may hold open; past them "
                 "503 (the page polls instead)")
      ->capture_default_str()
      ->check(CLI::Range(1, 128));
  app.add_option("--engine-version", flags.engine_version, "LIGGGHTS version string (default: ask liggghts)");
  app.add_option("--log-level", flags.log_level, "trace, debug, info, warn, error")
      ->capture_default_str()
      ->check(CLI::IsMember({"trace", "debug", "info", "warn", "error", "critical", "off"}));
  app.add_option("--schedule", flags.schedules,
                 "rerun this campaign on its cron schedule, NAME[:SCALE] (repeatable; e.g. paper-58:smoke)");
  app.add_option("--scheduler-tick", flags.scheduler_tick_s,
                 "seconds between looks for due reruns and finished ones (drift reports)")
      ->capture_default_str()
      ->check(CLI::Range(0.05, 3600.0));
  app.add_option("--slurm-check", flags.slurm_check_s,
                 "seconds between asking Slurm (squeue) whether the jobs holding leases still run; "
                 "the runs of a job that is gone are queued again at once (0: never ask)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
}

int Die(const Status& s, const std::string& next) {
  spdlog::critical("{}; {}", s.ToString(), next);
  return 1;
}

// The daemon's token (platform/token.h has the rule): --token-file, $SANDSWIM_TOKEN, else
// DATA/token, made on the first start. `file` is where local workers read it ("" from the
// environment, which they inherit); `token` is "" with --no-token.
struct DaemonToken {
  std::string token;
  std::string file;
  bool own = false;  // DATA/token, the daemon's own
};

sandswim::Result<DaemonToken> ResolveToken(const Flags& flags) {
  DaemonToken out;
  const char* env = std::getenv("SANDSWIM_TOKEN");
  const bool env_set = env != nullptr && *env != '\0';
  if (flags.no_token) {
    if (!flags.token_file.empty() || env_set) {
      return Status::InvalidArgument("--no-token", "cannot be given with a token (--token-file or SANDSWIM_TOKEN)");
    }
    spdlog::warn(
        "*** --no-token: serving WITHOUT A TOKEN. Every process and user on this machine (and every web page "
        "your browser opens that gets past the Host and Origin checks) may read and change this daemon's "
        "studies. Drop --no-token to serve with the token in {} ***",
        sandswim::DataDir(flags.data).Token());
    return out;
  }
  if (!flags.token_file.empty() || env_set) {
    auto given = sandswim::LoadToken(flags.token_file);
    if (!given.ok()) return given.status();
    if (Status s = sandswim::CheckTokenStrength(*given, flags.token_file.empty() ? "SANDSWIM_TOKEN" : "--token-file");
        !s.ok()) {
      return s;
    }
    out.token = *given;
    out.file = flags.token_file;
    return out;
  }
  auto file = sandswim::LoadOrCreateTokenFile(sandswim::DataDir(flags.data).Token());
  if (!file.ok()) return file.status();
  out.token = file->token;
  out.file = file->path;
  out.own = true;
  spdlog::info("{} the token in {} (mode 0600): the CLI and local workers read it from there",
               file->created ? "made" : "using", file->path);
  return out;
}

// Where a new user goes: the dashboard's link, with the token when the daemon keeps it in a file
// of its own (one the operator gave is theirs to paste) and stdout is a terminal -- under systemd
// stdout is the journal, which more users read than the 0600 file: there the link names the file.
// On stdout, after the "listening on" line.
void PrintDashboardLink(const sandswim::ListenAddress& address, int port, const DaemonToken& token,
                        const std::string& scheme) {
  std::string host = address.host;
  if (host == "0.0.0.0" || host == "::" || host.empty()) host = "127.0.0.1";
  if (host.find(':') != std::string::npos) host = "[" + host + "]";
  const std::string base = scheme + "://" + host + ":" + std::to_string(port) + "/";
  if (token.token.empty()) {
    std::cout << "dashboard: " << base << " (no token: --no-token)" << std::endl;
  } else if (token.own && isatty(STDOUT_FILENO)) {
    std::cout << "dashboard: " << base << "?token=" << token.token << std::endl;
  } else if (token.own) {
    std::cout << "dashboard: " << base << "?token=TOKEN, TOKEN the contents of " << token.file << std::endl;
  } else {
    std::cout << "dashboard: " << base << "?token=TOKEN (your token: it stays in the browser tab)" << std::endl;
  }
}

// The certificate the daemon serves HTTPS with: the operator's (--tls-cert/--tls-key) or its own
// (--tls self-signed, DATA/tls); nullopt for plain HTTP.
sandswim::Result<std::optional<sandswim::TlsFiles>> ResolveTls(const Flags& flags,
                                                               const sandswim::ListenAddress& address) {
  if (flags.tls_cert.empty() != flags.tls_key.empty()) {
    return Status::InvalidArgument(flags.tls_cert.empty() ? "--tls-cert" : "--tls-key",
                                   "--tls-cert and --tls-key go together");
  }
  if (!flags.tls.empty() && !flags.tls_cert.empty()) {
    return Status::InvalidArgument("--tls", "give --tls self-signed or --tls-cert/--tls-key, not both");
  }
  if (!flags.tls_cert.empty()) {
    auto files = sandswim::CheckCertificateFiles(flags.tls_cert, flags.tls_key);
    if (!files.ok()) return files.status();
    return std::optional<sandswim::TlsFiles>(*files);
  }
  if (flags.tls.empty()) return std::optional<sandswim::TlsFiles>();
  std::vector<std::string> names = flags.allow_hosts;
  names.push_back(address.host);
  char host[256] = {0};
  if (gethostname(host, sizeof(host) - 1) == 0) names.push_back(host);
  auto files = sandswim::LoadOrCreateSelfSigned(sandswim::DataDir(flags.data).Tls(), names);
  if (!files.ok()) return files.status();
  spdlog::info("{} the self-signed certificate {} (key {}, mode 0600)", files->created ? "made" : "using",
               files->cert, files->key);
  return std::optional<sandswim::TlsFiles>(*files);
}

// The engine the workers on this machine run, for content keys; "unknown" (with a warning) when
// it cannot be asked.
std::string ProbedEngineVersion() {
  auto version = sandswim::ProbeEngineVersion();
  if (version.ok()) return *version;
  spdlog::warn(
      "{}; using engine version \"unknown\" in content keys (install LIGGGHTS on PATH "
      "or pass --engine-version to key results by the engine the workers run)",
      version.status().ToString());
  return "unknown";
}

// Results made by an older U_z analysis are re-analysed from their stored trajectories.
Status ReanalyzeOldResults(sandswim::Store& store) {
  auto re = store.ReanalyzeOldResults();
  if (!re.ok()) return re.status();
  if (re->reanalysed + re->kept_old > 0) {
    spdlog::info(
        "re-analysed {} result(s) made by an older U_z analysis from their stored trajectories "
        "(analysed_from \"trajectory\"); {} could not be and are shown as inconclusive (analysed_from "
        "\"unreadable\"): submit their sweeps again with --force for results of this analysis",
        re->reanalysed, re->kept_old);
  }
  return Status();
}

// Registers the --schedule flags (NAME[:SCALE]) with the scheduler and logs what is due when.
Status RegisterSchedules(sandswim::Scheduler& scheduler, const std::vector<std::string>& flags,
                         sandswim::Clock& clock) {
  std::vector<sandswim::ScheduleRequest> requests;
  for (const std::string& text : flags) {
    auto request = sandswim::ParseScheduleFlag(text);
    if (!request.ok()) return request.status();
    requests.push_back(*request);
  }
  if (Status registered = scheduler.Register(requests); !registered.ok()) return registered;
  spdlog::info("scheduling in local time zone {}", sandswim::LocalTimeZoneDescription(clock.Now()));
  if (auto list = scheduler.List(); list.ok()) {
    for (const sandswim::ScheduledCampaign& s : *list) {
      if (!s.enabled) continue;
      spdlog::info("schedule: {}@{} \"{}\", next due {}", s.campaign, s.scale, s.cron,
                   s.next_due ? sandswim::FormatWallMinute(*s.next_due) : std::string("never"));
    }
  }
  return Status();
}

// Leases run out by time: their jobs are queued again.
void ExpireLeases(sandswim::LeaseQueue& leases, const std::string& db) {
  auto expired = leases.ExpireLeases();
  if (!expired.ok()) {
    spdlog::error("expiring leases: {}; will retry in 1 s (check the disk holding {})", expired.status().ToString(),
                  db);
  } else if (*expired > 0) {
    spdlog::info("{} lease(s) expired; their jobs are queued again", *expired);
  }
}

// Asks Slurm about the jobs holding leases; `warned`: squeue failing is said once, not every look.
void WatchPilots(sandswim::PilotWatch& pilot_watch, bool& warned) {
  auto check = pilot_watch.CheckOnce();
  if (!check.ok()) {
    if (!warned) {
      spdlog::warn(
          "cannot ask Slurm about the jobs holding leases ({}); their runs wait for the lease TTL. "
          "Run sandswimd where squeue works, or pass --slurm-check 0",
          check.status().ToString());
    }
    warned = true;
    return;
  }
  warned = false;
  for (const std::string& job : check->gone) {
    spdlog::warn("Slurm job {} is gone without handing its runs back: reclaimed its leases", job);
  }
  if (check->reclaimed > 0) spdlog::info("{} job(s) of gone Slurm pilots queued again", check->reclaimed);
}

// Due reruns are submitted; adaptive campaign runs whose round finished get their next round (or
// stop, saying why); finished campaign runs get their drift reports.
void SchedulerPass(sandswim::Scheduler& scheduler, sandswim::RoundDriver& rounds, sandswim::Store& store,
                   sandswim::Clock& clock) {
  auto tick = scheduler.Tick();
  if (!tick.ok()) {
    spdlog::error("scheduler: {}; will retry at the next tick", tick.status().ToString());
  } else {
    for (const auto& rerun : tick->submitted) spdlog::info("{}", sandswim::DescribeRerun(rerun, scheduler.zone()));
    for (const auto& [campaign, why] : tick->errors) {
      spdlog::error("scheduled rerun of {}: {}; will retry at the next tick", campaign, why.ToString());
    }
  }
  auto pass = rounds.Tick(clock.Now());
  if (!pass.ok()) {
    spdlog::error("rounds: {}; will retry at the next tick", pass.status().ToString());
  } else {
    for (const auto& step : pass->steps) spdlog::info("{}", step.text);
    for (const auto& [id, why] : pass->errors) {
      spdlog::error("rounds of campaign run {}: {}; will retry at the next tick", id, why.ToString());
    }
  }
  auto reports = sandswim::ReportFinishedCampaignRuns(store, clock.Now(), scheduler.zone());
  if (!reports.ok()) {
    spdlog::error("drift reports: {}; will retry at the next tick", reports.status().ToString());
  } else {
    for (const auto& report : *reports) spdlog::info("{}", report.summary);
  }
}

// The studies, the token and the leases are the daemon's user's alone: what an earlier daemon (or
// another umask) left readable by others is made private before anything is opened.
Status RestrictDataToOwner(const Flags& flags) {
  std::vector<std::string> paths = {flags.data};
  if (!flags.db.empty()) paths.insert(paths.end(), {flags.db, flags.db + "-wal", flags.db + "-shm", flags.db + "-journal"});
  int changed = 0;
  for (const std::string& path : paths) {
    if (path.empty()) continue;
    auto n = sandswim::RestrictToOwner(path);
    if (!n.ok()) return n.status();
    changed += *n;
  }
  if (changed > 0) {
    spdlog::warn("made {} file(s) and directories of {} and {} private to this user (0600 files, 0700 directories): "
                 "they were readable by others",
                 changed, flags.data, flags.db);
  }
  return Status::Ok();
}

}  // namespace

int main(int argc, char** argv) {
  // Every file and directory the daemon makes -- the database and its WAL, backups, uploads, beds,
  // snapshots, the TLS key, the token -- is its user's alone (0600, 0700), whatever umask it was
  // started under; its local workers inherit the same.
  umask(077);
  Flags flags;
  CLI::App app{"sandswimd: the sandswim daemon (REST API, SQLite store, lease queue)"};
  AddFlags(app, flags);
  CLI11_PARSE(app, argc, argv);
  // Logs go to stderr; stdout carries only the "listening on" line that scripts wait for.
  spdlog::set_default_logger(spdlog::stderr_color_mt("sandswimd"));
  spdlog::set_level(spdlog::level::from_str(flags.log_level));

  // Signals are taken by one thread with sigwait; every other thread (httplib's pool too)
  // inherits the blocked mask from here.
  sigset_t stop_signals;
  sigemptyset(&stop_signals);
  sigaddset(&stop_signals, SIGTERM);
  sigaddset(&stop_signals, SIGINT);
  pthread_sigmask(SIG_BLOCK, &stop_signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  auto address = sandswim::ParseListenAddress(flags.listen);
  if (!address.ok()) return Die(address.status(), "use --listen HOST:PORT, e.g. 127.0.0.1:8640");
  if (Status s = RestrictDataToOwner(flags); !s.ok()) {
    return Die(s, "run sandswimd as the owner of --data " + flags.data + " and --db " + flags.db);
  }
  auto token = ResolveToken(flags);
  if (!token.ok()) return Die(token.status(), "sandswimd serves with a token unless told --no-token");
  auto tls = ResolveTls(flags, *address);
  if (!tls.ok()) {
    return Die(tls.status(), "give a readable certificate and its key, or --tls self-signed, or neither for plain HTTP");
  }
  const std::string scheme = tls->has_value() ? "https" : "http";
  Status policy = sandswim::CheckListenPolicy(*address, !token->token.empty(), tls->has_value(), flags.plain_http);
  if (!policy.ok()) return Die(policy, "serve with a token and HTTPS, or listen on a loopback address");
  if (!tls->has_value() && !sandswim::IsLoopbackHost(address->host)) {
    spdlog::warn("*** --plain-http: serving plain HTTP on {}: the token and the decks workers run cross the network "
                 "readable and changeable unless a TLS proxy or a private network stands in front ***",
                 address->host);
  }

  if (flags.engine_version.empty()) flags.engine_version = ProbedEngineVersion();
  spdlog::info("engine: {}", flags.engine_version);

  auto store = sandswim::Store::Open(flags.db);
  if (!store.ok()) return Die(store.status(), "check that --db " + flags.db + " is writable (or pick another path)");
  if (Status s = ReanalyzeOldResults(**store); !s.ok()) {
    return Die(s, "the database's results could not be re-analysed; restore a backup of " + flags.db);
  }
  if (auto stale = sandswim::ClearScratchDirs(flags.data); !stale.ok()) {
    return Die(stale.status(), "check that --data " + flags.data + " is writable");
  } else if (*stale > 0) {
    spdlog::info("removed {} unfinished backup or upload file(s) left by an earlier daemon in {} and {}", *stale,
                 sandswim::DataDir(flags.data).Backups(), sandswim::DataDir(flags.data).Uploads());
  }
  sandswim::SystemClock clock;
  sandswim::LeaseQueueOptions lease_options;
  lease_options.ttl_s = flags.lease_ttl_s;
  lease_options.max_attempts = flags.max_attempts;
  lease_options.wall_budget_s = flags.wall_budget_s;
  lease_options.data_dir = flags.data;
  sandswim::LeaseQueue leases(store->get(), &clock, lease_options);
  // This daemon's local worker is named for it; one of an earlier daemon (stopped or killed) held
  // its leases under such a name on this host, and died with it unless it heartbeats again.
  const std::string host = sandswim::HostName();
  const std::string local_worker = sandswim::LocalWorkerName(host, getpid());
  if (auto extended = leases.ExtendLeasesAfterRestart(
          [&host](const std::string& worker) { return sandswim::IsLocalWorkerName(worker, host); });
      !extended.ok()) {
    return Die(extended.status(), "check that --db " + flags.db + " is writable");
  } else if (*extended > 0) {
    spdlog::info("{} job(s) were running when the daemon stopped: their leases run {} s from now, so their "
                 "workers can carry on (a worker that died meanwhile is reclaimed then)",
                 *extended, flags.lease_ttl_s);
  }
  if (size_t left = leases.LeasesLeftByStoppedDaemon(); left > 0) {
    spdlog::info("{} of the running job(s) were leased by the local workers of the daemon that stopped: unless a "
                 "heartbeat comes within {} s they are handed back, their attempts uncounted (the daemon stopping "
                 "was not their fault)",
                 left, flags.lease_ttl_s);
  }
  if (auto unrecorded = leases.RemoveUnrecordedSnapshots(); !unrecorded.ok()) {
    return Die(unrecorded.status(), "check that --data " + flags.data + " is readable and writable");
  } else if (*unrecorded > 0) {
    spdlog::info("removed {} snapshot file(s) no completed run recorded (uploads of runs that did not finish)",
                 *unrecorded);
  }

  // Nightly reruns: registered now (a --schedule left out is disabled), checked every tick.
  sandswim::Scheduler scheduler(store->get(), &clock, flags.engine_version);
  if (Status s = RegisterSchedules(scheduler, flags.schedules, clock); !s.ok()) {
    return Die(s, "use --schedule NAME[:SCALE] (e.g. paper-58:smoke) with a campaign that exists, or drop it");
  }
  // Adaptive campaign runs (server/jobs/rounds.h), looked at as their claims are shown.
  sandswim::RoundDriverOptions round_options;
  round_options.engine_version = flags.engine_version;
  round_options.max_queued_runs = flags.max_queued_runs;
  sandswim::RoundDriver rounds(store->get(), &sandswim::LookAtClaims, round_options);
  // Figures are drawn by sandswim-render in processes of their own (server/analysis/plot_renderer.h).
  sandswim::PosixSubprocesses renderer_processes;
  const std::string renderer_path = sandswim::ExecutableDir() + "/sandswim-render";
  if (access(renderer_path.c_str(), X_OK) != 0) {
    spdlog::warn(
        "{} is missing or not executable: figures and reports will answer 503 until it is installed next "
        "to sandswimd (cmake --build build; deploy/install.sh)",
        renderer_path);
  }
  sandswim::SubprocessRenderer renderer(&renderer_processes, renderer_path, /*timeout_s=*/120, flags.max_renderers);
  sandswim::Deps deps;
  deps.renderer = &renderer;
  deps.store = store->get();
  deps.leases = &leases;
  deps.clock = &clock;
  deps.data_dir = flags.data;
  deps.engine_version = flags.engine_version;
  deps.token = token->token;
  deps.public_reads = flags.public_reads;
  deps.host_policy.allowed_names = flags.allow_hosts;
  deps.max_queued_runs = flags.max_queued_runs;
  // A status poll's ETA is read once per change, not per request (server/store/eta_cache.h).
  sandswim::EtaCache etas(store->get());
  // A campaign run's verdicts are evaluated once per change (server/analysis/claims_cache.h).
  sandswim::ClaimsCache claims(store->get());
  // The dashboard's live view: one snapshot a second however many pages are open (server/dashboard/live_feed.h).
  sandswim::LiveFeed live(store->get(), &clock, /*tick_s=*/1.0, /*max_streams=*/128, /*sweeps=*/50,
                          /*campaign_runs=*/20, flags.live_streams_per_client);
  leases.SetProgressObserver(
      [&live](int64_t run_id, const sandswim::api::Heartbeat& beat) { live.RecordBeat(run_id, beat.sim_time_s, beat.so_z); });
  deps.live = &live;
  deps.engine_slots = flags.local_workers;
  live.set_engine_slots(flags.local_workers);
  deps.etas = &etas;
  deps.claims = &claims;
  live.set_eta_cache(&etas);
  flags.http.head_s = flags.http_head_timeout_s;
  sandswim::ApiServer server(deps, flags.http);
  if (tls->has_value()) {
    if (Status s = server.UseTls((*tls)->cert, (*tls)->key); !s.ok()) {
      return Die(s, "check the certificate and key files");
    }
  }
  auto port = server.Bind(*address);
  if (!port.ok()) return Die(port.status(), "stop whatever holds the port, or pass another --listen");
  std::thread serve([&server] { server.Serve(); });

  // Background work, every so often: leases that ran out (every second), Slurm pilots that died
  // without handing their runs back (node lost, SIGKILL, time limit), nightly reruns and drift
  // reports (at once, then every tick).
  sandswim::slurm::ProcessSlurmCommands slurm_commands(/*timeout_s=*/20);
  sandswim::PilotWatch pilot_watch(&leases, &slurm_commands, &clock);
  sandswim::PeriodicJobs periodic(&clock);
  periodic.Add("lease expiry", 1, [&] { ExpireLeases(leases, flags.db); });
  periodic.Add("pilot watch", flags.slurm_check_s, [&, warned = false]() mutable { WatchPilots(pilot_watch, warned); });
  periodic.Add(
      "scheduler", flags.scheduler_tick_s, [&] { SchedulerPass(scheduler, rounds, **store, clock); },
      /*run_at_start=*/true);
  periodic.Start();

  // Before the line scripts wait for, which ends what they read.
  if (tls->has_value()) {
    std::cout << "tls: certificate " << (*tls)->cert << ", fingerprint " << (*tls)->fingerprint
              << " (workers and the CLI elsewhere: --tls-fingerprint " << (*tls)->fingerprint << ")" << std::endl;
  }
  PrintDashboardLink(*address, *port, *token, scheme);
  std::cout << "sandswimd listening on " << scheme << "://" << address->host << ":" << *port << std::endl;

  sandswim::PosixSubprocesses processes;
  sandswim::LocalWorkersOptions worker_options;
  // One process with N slots, not N processes: its slots know which of them idle, so a bed that
  // every run waits for is prepared on their cores (sandswim-worker --max-ranks).
  worker_options.count = flags.local_workers > 0 ? 1 : 0;
  const std::string slots = std::to_string(flags.local_workers);
  worker_options.argv = {sandswim::ExecutableDir() + "/sandswim-worker",
                         "--server",
                         scheme + "://127.0.0.1:" + std::to_string(*port),
                         "--slots",
                         slots,
                         "--ranks",
                         "1",
                         "--max-ranks",
                         slots,
                         "--workdir",
                         sandswim::DataDir(flags.data).Worker(),
                         "--name",
                         local_worker};
  // A token from SANDSWIM_TOKEN reaches the workers through the environment; one from a file, as
  // that file.
  if (!token->file.empty()) worker_options.argv.insert(worker_options.argv.end(), {"--token-file", token->file});
  // Local workers pin the certificate itself: it need not name 127.0.0.1 nor chain to a CA they know.
  if (tls->has_value()) {
    worker_options.argv.insert(worker_options.argv.end(), {"--tls-fingerprint", (*tls)->fingerprint});
  }
  sandswim::LocalWorkers workers(worker_options, &processes, &clock);
  std::thread supervisor;
  int exit_code = 0;
  Status started = workers.Start();
  if (!started.ok()) {
    exit_code = Die(started, "the daemon is stopping");
  } else {
    if (flags.local_workers > 0) supervisor = std::thread([&workers] { workers.RunUntilStopped(); });
    int signal_number = 0;
    sigwait(&stop_signals, &signal_number);
    spdlog::info("{} received: stopping", strsignal(signal_number));
  }

  // Workers first (they may still report to the server), then the server, then the store.
  workers.RequestStop();
  if (supervisor.joinable()) supervisor.join();
  workers.Stop();
  // The local worker hands its jobs back as it stops; what it could not (killed after the grace, or
  // its hand-back lost) the daemon hands back for it, rather than let the leases expire and count an
  // attempt against runs that did nothing wrong.
  if (auto handed = leases.HandBackLeasesOf(local_worker, "the daemon stopped, and its local worker with it");
      !handed.ok()) {
    spdlog::error("handing back the local worker's jobs: {}; their leases will expire instead", handed.status().ToString());
  } else if (*handed > 0) {
    spdlog::info("handed back {} job(s) the local worker left running; they are queued again, attempts uncounted",
                 *handed);
  }
  periodic.Stop();
  live.Stop();  // open dashboard streams end, so the server's threads can
  server.Stop();
  serve.join();
  spdlog::info("sandswimd stopped");
  return exit_code;
}
