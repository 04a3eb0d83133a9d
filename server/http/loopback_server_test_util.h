// LoopbackServer (tests only): the routes of RegisterRoutes served for real -- the daemon's server
// on 127.0.0.1 and an ephemeral port, its accept loop in a thread of the test -- with a client.
// Requests sent right after construction queue on the bound socket until the loop accepts them.
// The destructor stops the server and joins its thread.
//
// Ownership: keeps a copy of `deps`; what its pointers name (store, queue, clock) must outlive it.
#ifndef SANDSWIM_SERVER_HTTP_LOOPBACK_SERVER_TEST_UTIL_H_
#define SANDSWIM_SERVER_HTTP_LOOPBACK_SERVER_TEST_UTIL_H_

#include <httplib.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <thread>

#include "server/http/guarded_http_server.h"
#include "server/http/routes.h"

namespace sandswim {

class LoopbackServer {
 public:
  explicit LoopbackServer(const Deps& deps) : deps_(deps), server_(LimitsOf(deps)) {
    RegisterRoutes(server_, deps_);
    port_ = server_.bind_to_any_port("127.0.0.1");
    if (port_ <= 0) throw std::runtime_error("LoopbackServer: cannot bind 127.0.0.1");
    deps_.host_policy.listen_host = "127.0.0.1";  // as ApiServer::Bind does, before the loop runs
    deps_.host_policy.listen_port = port_;
    thread_ = std::thread([this] { server_.listen_after_bind(); });
    client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
  }
  ~LoopbackServer() {
    // stop() before the loop runs would be lost; a loop that never starts is not waited for long.
    for (int i = 0; i < 5000 && !server_.is_running(); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    server_.stop();
    thread_.join();
  }
  LoopbackServer(const LoopbackServer&) = delete;
  LoopbackServer& operator=(const LoopbackServer&) = delete;

  int port() const { return port_; }
  httplib::Client& client() { return *client_; }

 private:
  // The daemon's limits, counting loopback clients as the deps say (as ApiServer makes them agree).
  static ConnectionLimits LimitsOf(const Deps& deps) {
    ConnectionLimits limits;
    limits.loopback_clients_apart = deps.loopback_clients_apart;
    return limits;
  }
  Deps deps_;
  GuardedHttpServer server_;  // as the daemon serves
  int port_ = 0;
  std::thread thread_;
  std::unique_ptr<httplib::Client> client_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_HTTP_LOOPBACK_SERVER_TEST_UTIL_H_
