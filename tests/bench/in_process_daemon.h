// InProcessDaemon: a sandswimd inside a benchmark's own process -- a Store, a LeaseQueue and the
// ApiServer on 127.0.0.1 and an ephemeral port, served by one thread -- so a bench can drive the
// real REST API without starting a process. For the programs in tests/bench/ only: a setup error
// ends the program with a message on stderr.
#ifndef SANDSWIM_TESTS_BENCH_IN_PROCESS_DAEMON_H_
#define SANDSWIM_TESTS_BENCH_IN_PROCESS_DAEMON_H_

#include <httplib.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "platform/clock.h"
#include "server/jobs/lease_queue.h"
#include "server/http/routes.h"
#include "server/store/store.h"

namespace sandswim::bench {

[[noreturn]] inline void DieInSetup(const std::string& what) {
  std::fprintf(stderr, "bench: %s\n", what.c_str());
  std::exit(1);
}

struct InProcessDaemon {
  std::unique_ptr<Store> store;
  SystemClock clock;
  std::unique_ptr<LeaseQueue> leases;
  std::unique_ptr<ApiServer> server;
  std::thread thread;
  int port = 0;

  // The database is DIR/sandswim.db, the data directory DIR/data.
  InProcessDaemon(const std::filesystem::path& dir, const std::string& engine_version) {
    auto s = Store::Open((dir / "sandswim.db").string());
    if (!s.ok()) DieInSetup("open store: " + s.status().ToString());
    store = std::move(s).value();
    leases = std::make_unique<LeaseQueue>(store.get(), &clock);
    Deps deps;
    deps.store = store.get();
    deps.leases = leases.get();
    deps.clock = &clock;
    deps.data_dir = (dir / "data").string();
    deps.engine_version = engine_version;
    server = std::make_unique<ApiServer>(deps);
    auto p = server->Bind({"127.0.0.1", 0});
    if (!p.ok()) DieInSetup("bind: " + p.status().ToString());
    port = *p;
    thread = std::thread([this] { server->Serve(); });
    httplib::Client probe("127.0.0.1", port);
    for (int i = 0; i < 500; ++i) {
      if (auto r = probe.Get("/healthz"); r && r->status == 200) return;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    DieInSetup("the in-process server did not answer /healthz");
  }
  ~InProcessDaemon() {
    server->Stop();
    thread.join();
  }
};

}  // namespace sandswim::bench

#endif  // SANDSWIM_TESTS_BENCH_IN_PROCESS_DAEMON_H_
