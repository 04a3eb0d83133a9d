// Request policy: what sandswimd asks of a request before its route runs, apart from comparing the
// token (routes.cc does that and applies these rules to the HTTP library's requests). Pure rules on
// header values, so they are tested without a server:
//  - Host: the Host header must name this daemon (HostAllowed), else 421. A page on a name that an
//    attacker's DNS later points at 127.0.0.1 (DNS rebinding) sends its own name as Host.
//  - Writes from web pages of other sites (CrossSiteRefusal): a request that changes state is
//    refused (403) when its Origin is not one of the daemon's own origins or Sec-Fetch-Site says
//    another site. Programs (the CLI, workers, curl) send neither header and are not affected.
//  - JSON writes say they are JSON (IsJsonMediaType), else 415: a browser sends such a request to
//    another origin only after a CORS preflight, which the daemon never approves, and an HTML form
//    cannot send it at all.
//  - Failed token attempts are logged and slowed (FailedAuthThrottle); other refusals (a foreign
//    Host, a cross-site write, a slow or oversized head) are logged at most once per peer and
//    interval, with a count (RefusalLog).
//  - What a 5xx may tell a client: no file paths (RedactPaths); the log keeps them.
//
// Thread safety: the free functions are pure; FailedAuthThrottle and RefusalLog are safe from any thread.
#ifndef SANDSWIM_SERVER_REQUEST_POLICY_H_
#define SANDSWIM_SERVER_REQUEST_POLICY_H_

#include <cstdint>
#include <functional>
#include <list>
#include <map>
#include <unordered_map>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "core/status.h"
#include "platform/clock.h"

namespace sandswim {

// Which Host header values name this daemon.
struct HostPolicy {
  std::string listen_host;                 // the address it listens on: "127.0.0.1", "::1", "0.0.0.0", a name
  int listen_port = 0;                     // 0: not known (a server registered before it bound): any port
  std::vector<std::string> allowed_names;  // --allow-host NAME (any port: a proxy may listen on its own)
  bool tls = false;                        // it serves HTTPS: its own pages' origins are https://
};

// True when `host` (a Host header value: "NAME", "NAME:PORT", "[V6]:PORT") is, with the listen
// port (80 when the header names none):
//  - localhost or a loopback address (127.0.0.0/8, ::1);
//  - the listen address itself; when that is a wildcard (0.0.0.0, ::), any IP address: a browser
//    sends an address only when its page's URL names one, and no attacker's name can rebind to it;
//  - or, on any port, a name the operator allowed.
// An absent (empty) Host header is allowed: no browser sends a request without one.
bool HostAllowed(const HostPolicy& policy, std::string_view host);

// Why a request that changes state must be refused as coming from a web page of another site, or
// nullopt. Refused: Sec-Fetch-Site "cross-site" or "same-site" (another origin on this site, e.g.
// another port of 127.0.0.1); an Origin of "null" (sandboxed frames, file: pages); any other Origin
// that is not SCHEME://HOST with HostAllowed(HOST) and SCHEME the daemon's own (https with
// `tls`, else http; either when the operator named hosts, since a proxy may end TLS in front).
// Neither header present (a program): allowed.
std::optional<Status> CrossSiteRefusal(const HostPolicy& policy, std::string_view origin,
                                       std::string_view sec_fetch_site);

// The client a peer address counts as, for per-client limits: an IPv4 address itself (/32; an
// IPv4-mapped IPv6 address as IPv4), an IPv6 address's /64 ("2001:db8:1:2::/64": one host or
// one site is usually given a /64 whole, and picks addresses in it at will). Anything else as it is.
// Every loopback address (127.0.0.0/8, ::1, ::ffff:127.x.y.z) is one client, "loopback": a local
// user may connect from any of 16 million of them; with `loopback_apart` (sandswimd
// --http-loopback-clients-apart: local clients that stand for other hosts, such as a proxy that
// binds its client's address) each counts by itself.
inline constexpr const char* kLoopbackClient = "loopback";
std::string ClientKey(const std::string& address, bool loopback_apart = false);

// "application/json", with or without parameters (charset=utf-8), in any case.
bool IsJsonMediaType(std::string_view content_type);

// `text` with every file path (a word holding '/' that is not an API path or a URL) replaced by
// "(a path: see the daemon's log)".
std::string RedactPaths(std::string_view text);

// Refusals logged per peer (a ClientKey) and kind ("host", "cross-site", "slow head"): the first
// is logged as it comes; later ones of that peer and kind within `every_s` of the last line are
// counted, and the next line after the interval says how many were left out. A peer refused
// thousands of times a second (a foreign page looping posts, a crowd of slow clients) costs the
// log a line per interval and kind. At most `max_entries` peer-and-kind pairs are remembered; past
// them the pairs quiet for an interval are forgotten (or all, when none is).
class RefusalLog {
 public:
  // `log` is injectable for tests (default: spdlog warns).
  explicit RefusalLog(Clock* clock, double every_s = 10, size_t max_entries = 4096,
                      std::function<void(const std::string&)> log = {});

  // One refusal of `peer`; `line` says what was refused and why (built only when logged, so pass
  // a function for a costly one).
  void Refused(const std::string& peer, const std::string& kind, const std::function<std::string()>& line);

  int64_t unlogged_total() const;  // refusals counted and not (yet) logged

 private:
  struct Entry {
    double last_log = -1e300;
    int64_t unlogged = 0;
  };
  Clock* clock_;
  double every_s_;
  size_t max_entries_;
  std::function<void(const std::string&)> log_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, Entry> entries_;  // by kind + " " + peer
  int64_t unlogged_total_ = 0;
};

// Failed token attempts per peer address: logged, at most one line per peer every `log_every_s`
// (peer, count, the last route), and slowed. A peer's first `free_failures` failures (typos, a
// stale token) are answered at once; each later one waits first_delay_s, doubling per failure up to
// max_delay_s, before its 401. A peer forgotten after `forget_after_s` without a failure starts
// again. A correct token is never delayed, whatever the peer did before (so a guesser on the same
// address cannot lock out the workers or the CLI).
//
// Bounded memory: at most `max_peers` peers are remembered (the one quiet longest forgotten first),
// kept in order of their last failure so that no failure scans them all.
//
// Bounded threads: a delay holds the request's thread, so at most one request per peer and
// `max_sleeping` in all wait at once; a failed attempt that finds no free slot is answered at once
// with 429 (kBusy) and Retry-After, not with 401. A guesser is thus slowed to a few attempts a
// second per connection it waits on; what stops it is the token's 256 bits.
class FailedAuthThrottle {
 public:
  struct Options {
    int free_failures = 3;
    double first_delay_s = 0.25;
    double max_delay_s = 2;
    int max_sleeping = 4;
    double forget_after_s = 600;
    double log_every_s = 10;
    size_t max_peers = 4096;  // peers remembered; past them the one quiet longest is forgotten
  };
  enum class Verdict { kDelayed, kBusy };
  struct Counts {
    int64_t failures = 0;
    int64_t delayed = 0;       // answered after a delay
    double delay_s_total = 0;  // the delays' sum
    int64_t busy = 0;          // answered 429 at once: no free slot
  };

  // `sleep` and `log` are injectable for tests (default: this thread sleeps; spdlog warns).
  FailedAuthThrottle(Clock* clock, Options options, std::function<void(double)> sleep = {},
                     std::function<void(const std::string&)> log = {});

  // Records a failed attempt of `peer` on `route` ("POST /api/v1/sweeps"), logs it when due, and
  // waits out the peer's delay when a slot is free. kBusy: no slot, answer 429 now.
  Verdict Failed(const std::string& peer, const std::string& route);

  Counts counts() const;

 private:
  struct Peer {
    int64_t failures = 0;  // since it was last forgotten
    double last_failure = 0;
    int64_t unlogged = 0;
    double last_log = -1e300;
    bool sleeping = false;
    std::list<std::string>::iterator in_order;
  };
  // Forgets the peers quiet for forget_after_s, and the quietest past max_peers: from the front of
  // order_, so a failure costs O(1) however many peers a network has.
  void ForgetQuiet(double now);

  Clock* clock_;
  Options options_;
  std::function<void(double)> sleep_;
  std::function<void(const std::string&)> log_;
  mutable std::mutex mu_;
  std::unordered_map<std::string, Peer> peers_;
  std::list<std::string> order_;  // peers by their last failure, the longest quiet first
  int sleeping_ = 0;
  Counts counts_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_REQUEST_POLICY_H_
