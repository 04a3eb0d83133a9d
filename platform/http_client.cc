#include "platform/http_client.h"

#include "platform/http_status.h"

#include <cmath>

#include <httplib.h>
#include <nlohmann/json.hpp>

namespace sandswim {

Status StatusFromHttp(int http_status, const std::string& body, const std::string& what) {
  nlohmann::json problem = nlohmann::json::parse(body, nullptr, /*allow_exceptions=*/false);
  std::string detail, field, type;
  if (problem.is_object()) {
    if (auto t = problem.find("type"); t != problem.end() && t->is_string()) type = t->get<std::string>();
    if (auto d = problem.find("detail"); d != problem.end() && d->is_string()) detail = d->get<std::string>();
    if (auto f = problem.find("field"); f != problem.end() && f->is_string()) field = f->get<std::string>();
  }
  // The daemon's detail starts with its field ("Authorization: this daemon has a token ..."); the
  // Status keeps them apart, or a caller that prints field and reason says the field twice.
  if (!field.empty() && detail.size() > field.size() + 2 && detail.compare(0, field.size(), field) == 0 &&
      detail.compare(field.size(), 2, ": ") == 0) {
    detail.erase(0, field.size() + 2);
  }
  if (detail.empty()) {
    detail = "HTTP " + std::to_string(http_status) + " for " + what;
    if (!body.empty()) detail += ": " + body.substr(0, 300);
  }
  return Status(StatusCodeForAnswer(http_status, type), detail, field);
}

bool DaemonTrouble(const Status& status) { return HttpStatusFor(status.code()) >= 500; }

std::unique_ptr<httplib::Client> NewHttpClient(const ClientOptions& options) {
  auto client = std::make_unique<httplib::Client>(options.server);
  auto seconds = [](double s) { return static_cast<time_t>(s); };
  auto micros = [](double s) { return static_cast<time_t>(std::fmod(s, 1.0) * 1e6); };
  client->set_connection_timeout(seconds(options.connect_timeout_s), micros(options.connect_timeout_s));
  client->set_read_timeout(seconds(options.read_timeout_s), micros(options.read_timeout_s));
  client->set_write_timeout(seconds(options.read_timeout_s), micros(options.read_timeout_s));
  // Small requests go out at once (Nagle + the peer's delayed ACK cost ~40 ms per request).
  client->set_tcp_nodelay(true);
  if (!options.token.empty()) client->set_bearer_token_auth(options.token);
  ConfigureTls(*client, options.tls);
  return client;
}

}  // namespace sandswim
