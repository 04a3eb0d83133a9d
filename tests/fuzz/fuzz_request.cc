// Fuzz target: the REST request path. The input is what a client sends on one connection --
// request lines, headers, bodies, one request after another -- written into one end of a
// socketpair, whose other end sandswimd's own server serves as it serves an accepted connection
// (server/http/guarded_http_server.h: its deadlines, its keep-alive loop), with the HTTP library's
// parser (as Debian packages it: not instrumented, so coverage is sandswimd's own code) and
// sandswimd's routes, pre-routing checks, auth and handlers (server/http/routes.h) on a real SQLite file
// that holds a small sweep, so that ids 1 and 2 name a sweep, its runs and its bed. What the daemon
// answers is read and discarded; a crash, a sanitizer report or an exception that escapes is a
// finding. A 5xx is not: it is a problem document, and the store's own faults are 5xx by design.
//
// The store outlives one input (opening it takes milliseconds); it is made again every
// kInputsPerStore inputs so that what inputs submit does not grow without bound. A finding that
// depends on earlier inputs is replayed with them (-runs on the corpus) rather than alone.
// tests/fuzz/run.sh builds and runs it.
#include <sys/socket.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include <spdlog/spdlog.h>

#include "platform/clock.h"
#include "server/http/guarded_http_server.h"
#include "server/jobs/lease_queue.h"
#include "server/http/routes.h"
#include "server/store/store.h"

namespace {

constexpr int kInputsPerStore = 2000;

// Serves `bytes` as one connection: a client thread writes them, closes its sending side and
// reads every answer until the server closes the connection.
void ServeBytes(sandswim::GuardedHttpServer& server, const char* bytes, size_t size) {
  int fds[2];
  if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, fds) != 0) std::abort();
  std::thread client([fd = fds[1], bytes, size] {
    for (size_t off = 0; off < size;) {
      const ssize_t n = send(fd, bytes + off, size - off, MSG_NOSIGNAL);
      if (n <= 0) break;
      off += static_cast<size_t>(n);
    }
    shutdown(fd, SHUT_WR);
    char buf[1 << 16];
    while (recv(fd, buf, sizeof buf, 0) > 0) {
    }
    close(fd);
  });
  server.ServeConnection(fds[0]);  // closes fds[0]
  client.join();
}

struct Daemon {
  std::string dir;
  std::unique_ptr<sandswim::Store> store;
  sandswim::FakeClock clock{1.8e9};
  std::unique_ptr<sandswim::LeaseQueue> leases;
  sandswim::Deps deps;
  std::unique_ptr<sandswim::GuardedHttpServer> server;
};

std::unique_ptr<Daemon> Start() {
  auto d = std::make_unique<Daemon>();
  char pattern[] = "/dev/shm/sandswim-fuzz-request-XXXXXX";  // memory: the store syncs its writes
  if (mkdtemp(pattern) == nullptr) std::abort();
  d->dir = pattern;
  auto store = sandswim::Store::Open(d->dir + "/fuzz.db");
  if (!store.ok()) std::abort();
  d->store = std::move(*store);
  d->leases = std::make_unique<sandswim::LeaseQueue>(d->store.get(), &d->clock, sandswim::LeaseQueueOptions{});
  d->deps.store = d->store.get();
  d->deps.leases = d->leases.get();
  d->deps.clock = &d->clock;
  d->deps.data_dir = d->dir + "/data";
  d->deps.engine_version = "LIGGGHTS (Version fuzz)";
  d->deps.host_policy.listen_host = "127.0.0.1";  // any port: the seeds say "Host: 127.0.0.1"
  d->server = std::make_unique<sandswim::GuardedHttpServer>();
  sandswim::RegisterRoutes(*d->server, d->deps);
  // Bound, never listened on: a server serves connections only while it has its socket.
  if (d->server->bind_to_any_port("127.0.0.1") <= 0) std::abort();
  // A sweep of two runs and its bed, so that ids in paths find rows.
  const char* sweep = R"({"name": "fuzz", "scale": "smoke",
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
    "axes": [{"param": "Omega", "values": [-80, 80]}]})";
  std::string request =
      "POST /api/v1/sweeps HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: " +
      std::to_string(std::char_traits<char>::length(sweep)) + "\r\n\r\n" + sweep;
  ServeBytes(*d->server, request.data(), request.size());
  return d;
}

void Stop(std::unique_ptr<Daemon>& d) {
  if (!d) return;
  const std::string dir = d->dir;
  d.reset();
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}

std::unique_ptr<Daemon> daemon_now;
int inputs = 0;

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);  // every 4xx and 5xx would be logged
  std::atexit([] { Stop(daemon_now); });
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (!daemon_now || ++inputs % kInputsPerStore == 0) {
    Stop(daemon_now);
    daemon_now = Start();
  }
  ServeBytes(*daemon_now->server, reinterpret_cast<const char*>(data), size);
  return 0;
}
