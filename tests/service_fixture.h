// Test support: the real sandswimd and sandswim-worker as child processes, and a REST client.
//
// Daemon starts `sandswimd --listen 127.0.0.1:0` on a fresh SQLite file and data directory under
// `dir`, and learns its port from the "listening on" line it prints. It serves with the token of
// $SANDSWIM_TOKEN when the test set one (its REST calls send it), else with --no-token. Worker starts
// `sandswim-worker --server URL`. Both run in their own process groups under the engine guard
// (workers/launcher.h); Kill(SIGKILL) kills the process alone (the guard passes the SIGKILL on;
// the process's own children, in their own groups, are left to their own guards), Stop() ends
// the whole group.
//
// Thread safety: none; one test thread drives them.
#ifndef SANDSWIM_TESTS_SERVICE_FIXTURE_H_
#define SANDSWIM_TESTS_SERVICE_FIXTURE_H_

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include <sys/types.h>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"
#include "workers/client.h"
#include "workers/launcher.h"

namespace sandswim::testing {

class ChildProcess {
 public:
  ChildProcess(std::vector<std::string> argv, const std::string& dir, const std::string& output_file);
  ~ChildProcess();
  bool running();
  void Kill(int signal);          // the process alone; see the top of this file
  // The signal to the program itself, not its guard: SIGSTOP and SIGCONT pause and resume it.
  void SignalProgram(int signal);
  void Stop(double grace_s = 5);  // SIGTERM to its group, then SIGKILL
  std::string Output() const;     // what it printed so far
  pid_t pid() const { return pid_; }

 private:
  std::unique_ptr<worker::EngineProcess> process_;
  std::string output_path_;
  pid_t pid_ = 0;
};

class Daemon {
 public:
  // Extra flags are appended (e.g. {"--lease-ttl", "5"}). `listen`: its address; a daemon started
  // again on the same files and port (Daemon(dir, extra, old.listen())) is found by the same
  // workers.
  Daemon(const std::string& dir, std::vector<std::string> extra = {}, const std::string& listen = "127.0.0.1:0");
  // "127.0.0.1:PORT", the port it got.
  std::string listen() const { return url_.substr(url_.find("//") + 2); }
  const std::string& url() const { return url_; }
  // The certificate's fingerprint a daemon serving HTTPS printed ("" for plain HTTP): the REST
  // calls, HandInBeds and StartWorker pin it.
  const std::string& tls_fingerprint() const { return tls_fingerprint_; }
  const std::string& db() const { return db_; }
  ChildProcess& process() { return *process_; }

  // REST calls; they fail the test on transport errors. `status` receives the HTTP status.
  nlohmann::json Get(const std::string& path, int* status = nullptr);
  nlohmann::json Post(const std::string& path, const nlohmann::json& body, int* status = nullptr);
  nlohmann::json Put(const std::string& path, const nlohmann::json& body, int* status = nullptr);
  // The body as it is (figures, files); throws on a transport error, as Get does.
  std::string GetText(const std::string& path, int* status = nullptr);

  // Polls GET /api/v1/sweeps/{id} until no run is queued or running; returns the last answer.
  nlohmann::json WaitForSweep(int64_t sweep_id, double timeout_s);
  // The first column of the first row of a read-only query on the daemon's SQLite file (opened
  // read-only beside the daemon), as text; "" when there is no row. Fails the test on an error.
  std::string Query(const std::string& sql) const;
  // Stores `deck` as the run's deck in the table the daemon reads a stored deck from (runs
  // submitted before migration 3 have one), so a run can be given a deck the engine rejects,
  // which no sweep can render. The one write a test makes past the API.
  void StoreDeckForRun(int64_t run_id, const std::string& deck);

 private:
  std::string dir_, db_, url_, tls_fingerprint_;
  std::unique_ptr<ChildProcess> process_;
};

// Hands the prepared bed restart at `restart` (a bed directory made by testing::PrepareBed, with
// its deck, engine log and bed dump beside it) to the daemon for the bed jobs it has queued,
// through the worker protocol a worker uses (lease, upload, complete, with the figures a worker
// reports), so tests need not prepare the bed again. Every queued bed must be that bed (same
// deck): a queued bed of another scale or replicate is released and an exception thrown.
void HandInBeds(const Daemon& daemon, const std::string& restart);

// Leases the first queued bed on construction (it must be the next job) and holds it, heartbeating,
// so that a worker started meanwhile prepares the beds after it; Complete() hands in a restart
// prepared meanwhile (testing::PrepareBed), as HandInBeds does. Released by the lease's expiry if
// never completed. Lets a test prepare one replicate through its worker while ctest's fixture
// prepares another.
class BedHandIn {
 public:
  explicit BedHandIn(const Daemon& daemon);
  ~BedHandIn();
  BedHandIn(const BedHandIn&) = delete;
  BedHandIn& operator=(const BedHandIn&) = delete;
  const api::LeaseGrant& grant() const { return grant_; }
  // Throws when the restart is not this bed's (another deck) or the daemon refuses it.
  void Complete(const std::string& restart);

 private:
  std::unique_ptr<worker::HttpServerClient> client_;
  api::LeaseGrant grant_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool done_ = false;
  std::string heartbeat_error_;  // the last refused heartbeat, named if the completion fails
  std::thread heartbeat_;
};

// A sandswim-worker of `slots` 1-rank slots (mpirun unless `extra` says otherwise, e.g.
// {"--launcher", "direct"}) with its workdir and output (worker.out) in `dir`.
std::unique_ptr<ChildProcess> StartWorker(const Daemon& daemon, const std::string& dir, int slots,
                                          const std::vector<std::string>& extra = {});

// A live process (not a zombie) and its command name (/proc/PID/comm, at most 15 characters).
struct ProcessInfo {
  pid_t pid = 0;
  std::string comm;
};
// The live processes whose working directory is under `dir`: the engines (and mpirun) a worker
// started there.
std::vector<ProcessInfo> ProcessesUnder(const std::string& dir);

// A TCP connection to "127.0.0.1:PORT" (Daemon::listen()), as a raw client's; -1 when refused.
// `from`: the loopback address it comes from (e.g. "127.0.0.2": another client to the daemon's
// per-client limits); "" the kernel's choice (127.0.0.1).
int ConnectTo(const std::string& listen, const std::string& from = "");

// A smoke-scale oscillatory sweep (A = 0.03 m, f = 3 Hz unless `f` says otherwise) over the
// given Omega values, each run `duration` s long: the sweep JSON to POST.
nlohmann::json OmegaSweep(const std::string& name, const std::vector<double>& omegas, double duration, double f = 3);

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_SERVICE_FIXTURE_H_
