// sandswim-worker: leases runs from the daemon and runs them with LIGGGHTS (workers/worker.h).
// Wiring only: parse flags, build the client, launcher and worker, wait for signals.
#include <signal.h>
#include <unistd.h>

#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "platform/clock.h"
#include "platform/slurm.h"
#include "platform/tls.h"
#include "platform/token.h"
#include "workers/client.h"
#include "workers/launcher.h"
#include "workers/worker.h"

int main(int argc, char** argv) {
  using namespace sandswim::worker;
  CLI::App app{"sandswim-worker: runs sandswim's LIGGGHTS jobs leased from the daemon"};
  std::string server;
  int ranks = 1;
  int slots = 0;
  std::string launcher_name = "mpirun";
  std::string token_file;
  std::string tls_fingerprint, tls_ca;
  WorkerOptions options;
  app.add_option("--server", server, "daemon URL, e.g. http://127.0.0.1:8080 or https://login1:8640")->required();
  app.add_option("--ranks", ranks, "MPI ranks per job")->check(CLI::Range(1, 4096));
  app.add_option("--slots", slots, "jobs at once (default: cores / ranks)")->check(CLI::Range(1, 4096));
  app.add_option("--max-ranks", options.max_ranks,
                 "a job granted while nothing else is leasable (a bed its runs wait for, the queue's last runs) "
                 "runs on up to this many ranks, taken from this worker's idle slots (default: --ranks, never more)")
      ->check(CLI::Range(1, 4096));
  app.add_option("--launcher", launcher_name, "mpirun | srun | direct (direct: one rank, no MPI launcher)")
      ->check(CLI::IsMember({"mpirun", "srun", "direct"}));
  app.add_option("--workdir", options.workdir, "run directories and the bed cache")->capture_default_str();
  app.add_option(
      "--token-file", token_file,
      "file holding the bearer token (else $SANDSWIM_TOKEN, else ./var/data/token for a daemon on loopback)");
  app.add_option("--tls-fingerprint", tls_fingerprint,
                 "for https: the daemon's certificate must have this SHA-256 fingerprint (it prints it at start); "
                 "else $SANDSWIM_TLS_FINGERPRINT, else --tls-ca, else the system's CAs");
  app.add_option("--tls-ca", tls_ca,
                 "for https: CA certificate(s) (PEM) the daemon's certificate must chain to (else $SANDSWIM_TLS_CA, "
                 "else the system's CAs)");
  app.add_option("--engine", options.engine, "the LIGGGHTS executable")->capture_default_str();
  app.add_option("--heartbeat", options.heartbeat_every_s, "seconds between heartbeats")->capture_default_str();
  app.add_option("--stall-after", options.stall_after_s,
                 "seconds of wall time without the engine's simulated time moving before a run is stopped as stalled (0: never)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--name", options.name, "worker name (default host:pid)");
  app.add_option("--end-margin", options.end_margin_s,
                 "inside a Slurm allocation: seconds a run is expected to take before one has finished here "
                 "(no lease unless the allocation has that long left)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--once", options.once, "take one job (waiting for one if the queue is empty), run it, exit");
  app.add_option("--exit-when-idle", options.exit_when_idle_s,
                 "exit after this many seconds with nothing to lease (0: wait for work forever)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_flag("--keep-run-dirs", options.keep_run_dirs, "keep run directories of jobs that succeeded");
  CLI11_PARSE(app, argc, argv);

  options.launcher = launcher_name == "srun"     ? LauncherKind::kSrun
                     : launcher_name == "direct" ? LauncherKind::kDirect
                                                 : LauncherKind::kMpirun;
  if (options.launcher == LauncherKind::kDirect && ranks != 1) {
    spdlog::error("--launcher direct runs one rank: use --ranks 1, or --launcher mpirun for {} ranks", ranks);
    return 2;
  }
  if (options.launcher == LauncherKind::kDirect && options.max_ranks > 1) {
    spdlog::error("--launcher direct runs one rank: drop --max-ranks, or use --launcher mpirun for up to {} ranks",
                  options.max_ranks);
    return 2;
  }
  const int cores = std::max(1u, std::thread::hardware_concurrency());
  options.ranks = ranks;
  options.slots = slots > 0 ? slots : std::max(1, cores / ranks);
  char host[256] = {0};
  gethostname(host, sizeof(host) - 1);
  options.host = host;
  if (options.name.empty()) options.name = options.host + ":" + std::to_string(getpid());
  options.as_root = geteuid() == 0;

  // The daemon's host, for the token rule (platform/token.h): its default token file is read only
  // for a daemon on this machine.
  std::string server_host = server.substr(server.find("://") == std::string::npos ? 0 : server.find("://") + 3);
  server_host = server_host.substr(
      0, !server_host.empty() && server_host.front() == '[' ? server_host.find(']') + 1 : server_host.find(':'));
  auto token = sandswim::LoadClientToken(token_file, server_host);
  if (!token.ok()) {
    spdlog::error("{}", token.status().ToString());
    return 2;
  }
  auto tls = sandswim::ResolveTlsTrust(tls_fingerprint, tls_ca);
  if (!tls.ok()) {
    spdlog::error("{}", tls.status().ToString());
    return 2;
  }
  if (server.rfind("http://", 0) == 0 && !sandswim::IsLoopbackHost(server_host)) {
    spdlog::warn("--server {} is plain HTTP to another machine: the token and the decks this worker runs cross the "
                 "network readable and changeable. Use https:// (sandswimd --tls self-signed, then "
                 "--tls-fingerprint as it prints it)",
                 server);
  }

  // Signals are taken by one thread with sigwait; every other thread (and so every engine,
  // which resets its mask) never sees them asynchronously.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGUSR1);  // Slurm's warning before the allocation ends (--signal=B:USR1@N)
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  signal(SIGPIPE, SIG_IGN);

  std::atomic<bool> stopping{false};
  std::atomic<bool> done{false};
  sandswim::ClientOptions client_options;
  client_options.server = server;
  client_options.token = *token;
  client_options.tls = *tls;
  client_options.connect_timeout_s = 5;
  sandswim::SystemClock clock;
  options.clock = &clock;
  HttpServerClient client(client_options, &stopping, &clock);
  GuardedLauncher launcher;
  // Inside a Slurm allocation, the worker stops leasing runs that would outlast it.
  sandswim::slurm::ProcessSlurmCommands slurm_commands;
  std::unique_ptr<sandswim::slurm::AllocationDeadline> deadline;
  std::mutex deadline_mu;
  if (const char* job = getenv("SLURM_JOB_ID"); job != nullptr && *job != '\0') {
    options.slurm_job = job;  // the daemon frees this job's leases as soon as Slurm no longer runs it
    const double t0 = clock.Monotonic();
    deadline = std::make_unique<sandswim::slurm::AllocationDeadline>(slurm_commands, job,
                                                                     [&clock, t0] { return clock.Monotonic() - t0; });
    options.allocation_seconds_left = [&] {
      std::lock_guard<std::mutex> lock(deadline_mu);
      return deadline->SecondsLeft();
    };
    spdlog::info("in Slurm job {}: no lease for a run that would outlast the allocation", job);
  }
  Worker worker(options, client, launcher);

  std::thread signal_thread([&] {
    int sig = 0;
    sigwait(&signals, &sig);
    if (done) return;  // woken by main at exit
    spdlog::warn(
        "signal {}{}: stopping; running jobs are stopped and handed back to the daemon, which leases "
        "them again",
        sig, sig == SIGUSR1 ? " (the Slurm allocation is about to end)" : "");
    stopping = true;
    worker.RequestStop();
  });
  spdlog::info("sandswim-worker {}: server {}, {} slot(s) x {} rank(s){}, launcher {}, workdir {}", options.name, server,
               options.once ? 1 : options.slots, options.ranks,
               options.max_ranks > options.ranks && !options.once
                   ? " (up to " + std::to_string(options.max_ranks) + " when the queue runs dry)"
                   : std::string(),
               launcher_name, options.workdir);
  worker.Run();
  done = true;
  if (!stopping) pthread_kill(signal_thread.native_handle(), SIGTERM);
  signal_thread.join();
  return 0;
}
