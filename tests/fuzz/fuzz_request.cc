// Fuzz target: the REST request path. The input is what a client sends on one connection --
// request lines, headers, bodies, one request after another -- read by the HTTP library's parser
// and served by sandswimd's own server (server/guarded_http_server.h) with its routes, pre-routing
// checks, auth and handlers (server/routes.h) on a real SQLite file that holds a small sweep, so
// that ids 1 and 2 name a sweep, its runs and its bed. What the daemon answers is discarded; a
// crash, a sanitizer report or an exception that escapes is a finding. A 5xx is not: it is a
// problem document, and the store's own faults are 5xx by design.
//
// The store outlives one input (opening it takes milliseconds); it is made again every
// kInputsPerStore inputs so that what inputs submit does not grow without bound. A finding that
// depends on earlier inputs is replayed with them (-runs on the corpus) rather than alone.
// tests/fuzz/run.sh builds and runs it.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>

#include <spdlog/spdlog.h>

#include "platform/clock.h"
#include "server/guarded_http_server.h"
#include "server/lease_queue.h"
#include "server/routes.h"
#include "server/store.h"

namespace {

constexpr int kInputsPerStore = 2000;

// The input as a connection's bytes; what is written back is dropped.
class InputStream final : public httplib::Stream {
 public:
  InputStream(const uint8_t* data, size_t size) : data_(reinterpret_cast<const char*>(data)), size_(size) {}
  bool at_end() const { return offset_ >= size_; }
  bool is_readable() const override { return !at_end(); }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override {
    const size_t n = std::min(size, size_ - offset_);
    std::copy(data_ + offset_, data_ + offset_ + n, ptr);
    offset_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char*, size_t size) override { return static_cast<ssize_t>(size); }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = "127.0.0.1";
    port = 40000;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = "127.0.0.1";
    port = 8640;
  }
  socket_t socket() const override { return INVALID_SOCKET; }

 private:
  const char* data_;
  size_t size_;
  size_t offset_ = 0;
};

// sandswimd's server, its requests served from a stream instead of a socket.
class Harness final : public sandswim::GuardedHttpServer {
 public:
  bool Serve(httplib::Stream& stream) {
    bool closed = false;
    return process_request(stream, /*close_connection=*/false, closed, nullptr) && !closed;
  }
};

struct Daemon {
  std::string dir;
  std::unique_ptr<sandswim::Store> store;
  sandswim::FakeClock clock{1.8e9};
  std::unique_ptr<sandswim::LeaseQueue> leases;
  sandswim::Deps deps;
  std::unique_ptr<Harness> server;
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
  d->server = std::make_unique<Harness>();
  sandswim::RegisterRoutes(*d->server, d->deps);
  // A sweep of two runs and its bed, so that ids in paths find rows.
  const char* sweep = R"({"name": "fuzz", "scale": "smoke",
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
    "axes": [{"param": "Omega", "values": [-80, 80]}]})";
  std::string request = "POST /api/v1/sweeps HTTP/1.1\r\nHost: x\r\nContent-Type: application/json\r\nContent-Length: " +
                        std::to_string(std::char_traits<char>::length(sweep)) + "\r\n\r\n" + sweep;
  InputStream stream(reinterpret_cast<const uint8_t*>(request.data()), request.size());
  d->server->Serve(stream);
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
  InputStream stream(data, size);
  for (int i = 0; i < 4 && !stream.at_end(); ++i) {
    if (!daemon_now->server->Serve(stream)) break;
  }
  return 0;
}
