#include "server/http/request_policy.h"

#include <arpa/inet.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>
#include <thread>

#include <spdlog/spdlog.h>

#include "core/text.h"
#include "platform/token.h"

namespace sandswim {
namespace {

std::string Lower(std::string_view s) {
  std::string out(s);
  for (char& ch : out) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return out;
}

bool IsIpAddress(const std::string& host) {
  in_addr v4{};
  in6_addr v6{};
  return inet_pton(AF_INET, host.c_str(), &v4) == 1 || inet_pton(AF_INET6, host.c_str(), &v6) == 1;
}

bool IsWildcard(const std::string& host) { return host.empty() || host == "0.0.0.0" || host == "::"; }

// "NAME[:PORT]" or "[V6][:PORT]" -> name (brackets removed, lower case) and port (`default_port`
// when absent); false when it does not parse.
bool SplitHostPort(std::string_view text, int default_port, std::string& name, int& port) {
  std::string_view host = text, port_text;
  if (!text.empty() && text.front() == '[') {
    size_t close = text.find(']');
    if (close == std::string_view::npos) return false;
    host = text.substr(1, close - 1);
    std::string_view rest = text.substr(close + 1);
    if (!rest.empty()) {
      if (rest.front() != ':') return false;
      port_text = rest.substr(1);
    }
  } else if (size_t colon = text.rfind(':'); colon != std::string_view::npos) {
    if (text.find(':') != colon) return false;  // an IPv6 address without brackets
    host = text.substr(0, colon);
    port_text = text.substr(colon + 1);
  }
  if (host.empty()) return false;
  port = default_port;
  if (!port_text.empty()) {
    auto [end, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
    if (ec != std::errc() || end != port_text.data() + port_text.size() || port < 1 || port > 65535) return false;
  }
  name = Lower(host);
  return true;
}

bool HostAllowedWithDefaultPort(const HostPolicy& policy, std::string_view host, int default_port) {
  std::string name;
  int port = 0;
  if (!SplitHostPort(host, default_port, name, port)) return false;
  for (const std::string& allowed : policy.allowed_names) {
    if (Lower(allowed) == name) return true;
  }
  if (policy.listen_port != 0 && port != policy.listen_port) return false;
  if (IsLoopbackHost(name)) return true;
  const std::string listen = Lower(policy.listen_host);
  if (IsWildcard(listen)) return IsIpAddress(name);
  return name == listen;
}

}  // namespace

bool HostAllowed(const HostPolicy& policy, std::string_view host) {
  if (host.empty()) return true;
  return HostAllowedWithDefaultPort(policy, host, 80);
}

std::optional<Status> CrossSiteRefusal(const HostPolicy& policy, std::string_view origin,
                                       std::string_view sec_fetch_site) {
  const std::string site = Lower(Trim(sec_fetch_site));
  if (site == "cross-site" || site == "same-site") {
    return Status(StatusCode::kPermissionDenied,
                  "the request comes from a web page of another origin (Sec-Fetch-Site: " + site +
                      "); sandswimd takes writes only from its own pages and from programs",
                  "Origin");
  }
  const std::string_view o = Trim(origin);
  if (o.empty()) return std::nullopt;
  auto refuse = [&o] {
    return Status(StatusCode::kPermissionDenied,
                  "the request comes from a web page of another origin (" + std::string(o) +
                      "); sandswimd takes writes only from its own pages and from programs",
                  "Origin");
  };
  const std::string lower = Lower(o);
  int default_port = 0;
  std::string_view authority;
  bool https = false;
  if (lower.rfind("http://", 0) == 0) {
    default_port = 80;
    authority = o.substr(7);
  } else if (lower.rfind("https://", 0) == 0) {
    default_port = 443;
    authority = o.substr(8);
    https = true;
  } else {
    return refuse();  // "null", file:, chrome-extension:, ...
  }
  // The daemon's own pages have its scheme; a proxy the operator named may end TLS for it.
  if (https != policy.tls && policy.allowed_names.empty()) return refuse();
  if (authority.empty() || authority.find('/') != std::string_view::npos) return refuse();
  if (!HostAllowedWithDefaultPort(policy, authority, default_port)) return refuse();
  return std::nullopt;
}

bool IsJsonMediaType(std::string_view content_type) {
  std::string_view type = content_type.substr(0, content_type.find(';'));
  return Lower(Trim(type)) == "application/json";
}

std::string RedactPaths(std::string_view text) {
  std::string out;
  size_t i = 0;
  while (i < text.size()) {
    if (std::isspace(static_cast<unsigned char>(text[i]))) {
      out += text[i++];
      continue;
    }
    size_t end = i;
    while (end < text.size() && !std::isspace(static_cast<unsigned char>(text[end]))) ++end;
    std::string_view word = text.substr(i, end - i);
    // Quotes and brackets around a path stay; what is inside them goes.
    size_t lead = 0;
    while (lead < word.size() && std::strchr("\"'([", word[lead]) != nullptr) ++lead;
    size_t trail = word.size();
    while (trail > lead && std::strchr("\"')],;:.", word[trail - 1]) != nullptr) --trail;
    std::string_view core = word.substr(lead, trail - lead);
    const bool api_path = core.rfind("/api/", 0) == 0 || core == "/healthz" || core == "/metrics";
    const bool url = core.find("://") != std::string_view::npos;
    if (core.find('/') != std::string_view::npos && !api_path && !url) {
      out += std::string(word.substr(0, lead)) + "(a path: see the daemon's log)" + std::string(word.substr(trail));
    } else {
      out += word;
    }
    i = end;
  }
  return out;
}

std::string ClientKey(const std::string& address, bool loopback_apart) {
  in_addr v4{};
  if (inet_pton(AF_INET, address.c_str(), &v4) == 1) {  // IPv4: a /32
    const bool loopback = (ntohl(v4.s_addr) >> 24) == 127;
    return loopback && !loopback_apart ? kLoopbackClient : address;
  }
  in6_addr v6{};
  if (inet_pton(AF_INET6, address.c_str(), &v6) != 1) return address;  // not an address
  if (IN6_IS_ADDR_V4MAPPED(&v6)) {
    char text[INET_ADDRSTRLEN];
    if (inet_ntop(AF_INET, &v6.s6_addr[12], text, sizeof text) != nullptr) return ClientKey(text, loopback_apart);
  }
  if (IN6_IS_ADDR_LOOPBACK(&v6)) return loopback_apart ? "::1" : kLoopbackClient;
  for (int i = 8; i < 16; ++i) v6.s6_addr[i] = 0;
  char text[INET6_ADDRSTRLEN];
  if (inet_ntop(AF_INET6, &v6, text, sizeof text) == nullptr) return address;
  return std::string(text) + "/64";
}

RefusalLog::RefusalLog(Clock* clock, double every_s, size_t max_entries, std::function<void(const std::string&)> log)
    : clock_(clock), every_s_(every_s), max_entries_(std::max<size_t>(1, max_entries)), log_(std::move(log)) {
  if (!log_) log_ = [](const std::string& line) { spdlog::warn("{}", line); };
}

void RefusalLog::Refused(const std::string& peer, const std::string& kind, const std::function<std::string()>& line) {
  int64_t left_out = 0;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const double now = clock_->Monotonic();
    const std::string key = kind + " " + peer;
    auto it = entries_.find(key);
    if (it == entries_.end()) {
      if (entries_.size() >= max_entries_) {
        for (auto e = entries_.begin(); e != entries_.end();) {
          e = now - e->second.last_log >= every_s_ ? entries_.erase(e) : std::next(e);
        }
        if (entries_.size() >= max_entries_) entries_.clear();  // a crowd of peers: each starts again
      }
      it = entries_.emplace(key, Entry{}).first;
    }
    Entry& e = it->second;
    if (now - e.last_log < every_s_) {
      ++e.unlogged;
      ++unlogged_total_;
      return;
    }
    left_out = e.unlogged;
    unlogged_total_ -= e.unlogged;
    e.unlogged = 0;
    e.last_log = now;
  }
  std::string text = line();
  if (left_out > 0) {
    text += " (and " + std::to_string(left_out) + " more such refusal(s) of " + peer + " since its last line; at most one line per " +
            std::to_string(static_cast<int>(every_s_)) + " s)";
  }
  log_(text);
}

int64_t RefusalLog::unlogged_total() const {
  std::lock_guard<std::mutex> lock(mu_);
  return unlogged_total_;
}

FailedAuthThrottle::FailedAuthThrottle(Clock* clock, Options options, std::function<void(double)> sleep,
                                       std::function<void(const std::string&)> log)
    : clock_(clock), options_(options), sleep_(std::move(sleep)), log_(std::move(log)) {
  if (!sleep_) sleep_ = [](double s) { std::this_thread::sleep_for(std::chrono::duration<double>(s)); };
  if (!log_) log_ = [](const std::string& line) { spdlog::warn("{}", line); };
}

FailedAuthThrottle::Verdict FailedAuthThrottle::Failed(const std::string& peer, const std::string& route) {
  double delay = 0;
  std::string line;
  {
    std::lock_guard<std::mutex> lock(mu_);
    const double now = clock_->Now();
    auto [it, fresh] = peers_.try_emplace(peer);
    Peer& p = it->second;
    if (fresh) {
      p.in_order = order_.insert(order_.end(), peer);
    } else {
      order_.splice(order_.end(), order_, p.in_order);  // now the most recent
    }
    if (p.failures > 0 && now - p.last_failure > options_.forget_after_s) p.failures = 0;
    ++p.failures;
    ++p.unlogged;
    p.last_failure = now;
    ++counts_.failures;
    ForgetQuiet(now);
    if (now - p.last_log >= options_.log_every_s) {
      std::ostringstream text;
      text << "refused " << p.unlogged << " request(s) with a wrong token from " << peer << " (last: " << route << "; "
           << p.failures << " failure(s) from it since it was last quiet for "
           << static_cast<int>(options_.forget_after_s) << " s); later failures are slowed, up to "
           << options_.max_delay_s << " s each";
      line = text.str();
      p.unlogged = 0;
      p.last_log = now;
    }
    const int64_t over = p.failures - options_.free_failures;
    if (over > 0) {
      delay = std::min(options_.max_delay_s, options_.first_delay_s * std::pow(2.0, static_cast<double>(over - 1)));
      if (p.sleeping || sleeping_ >= options_.max_sleeping) {
        ++counts_.busy;
        delay = -1;
      } else {
        p.sleeping = true;
        ++sleeping_;
        ++counts_.delayed;
        counts_.delay_s_total += delay;
      }
    }
  }
  if (!line.empty()) log_(line);
  if (delay < 0) return Verdict::kBusy;
  if (delay > 0) {
    sleep_(delay);
    std::lock_guard<std::mutex> lock(mu_);
    peers_[peer].sleeping = false;
    --sleeping_;
  }
  return Verdict::kDelayed;
}

void FailedAuthThrottle::ForgetQuiet(double now) {
  while (!order_.empty()) {
    auto it = peers_.find(order_.front());
    const bool quiet = now - it->second.last_failure > options_.forget_after_s;
    if ((!quiet && peers_.size() <= std::max<size_t>(1, options_.max_peers)) || it->second.sleeping) return;
    peers_.erase(it);
    order_.pop_front();
  }
}

FailedAuthThrottle::Counts FailedAuthThrottle::counts() const {
  std::lock_guard<std::mutex> lock(mu_);
  return counts_;
}

}  // namespace sandswim
