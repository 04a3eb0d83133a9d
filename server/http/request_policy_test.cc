#include "server/http/request_policy.h"

#include <string>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

HostPolicy Loopback() { return HostPolicy{"127.0.0.1", 8640, {}}; }

TEST(HostAllowedTest, LoopbackNamesWithTheListenPort) {
  const HostPolicy p = Loopback();
  for (const char* host : {"127.0.0.1:8640", "localhost:8640", "LOCALHOST:8640", "[::1]:8640", "127.0.0.2:8640"}) {
    EXPECT_TRUE(HostAllowed(p, host)) << host;
  }
  // Another port, no port (80), or any other name: not this daemon.
  for (const char* host :
       {"127.0.0.1:9999", "localhost", "evil.example", "evil.example:8640", "127.0.0.1.evil.example:8640",
        "localhost.:8640", "[::1]", "::1:8640", "127.0.0.1:", "127.0.0.1:x", "[::1"}) {
    EXPECT_FALSE(HostAllowed(p, host)) << host;
  }
  EXPECT_TRUE(HostAllowed(p, "")) << "no Host header: not a browser";
}

TEST(HostAllowedTest, TheListenAddressOperatorNamesAndWildcards) {
  HostPolicy p{"10.1.2.3", 8640, {"login1", "Sandswim.Example.org"}};
  EXPECT_TRUE(HostAllowed(p, "10.1.2.3:8640"));
  EXPECT_FALSE(HostAllowed(p, "10.1.2.4:8640"));
  EXPECT_TRUE(HostAllowed(p, "login1:8640"));
  EXPECT_TRUE(HostAllowed(p, "sandswim.example.org")) << "behind a proxy on its own port";
  EXPECT_TRUE(HostAllowed(p, "sandswim.example.org:443"));
  EXPECT_FALSE(HostAllowed(p, "login2:8640"));
  // Listening on every address: any address literal (no name can be rebound to one), no names.
  HostPolicy any{"0.0.0.0", 8640, {}};
  EXPECT_TRUE(HostAllowed(any, "192.168.1.4:8640"));
  EXPECT_TRUE(HostAllowed(any, "[fe80::1]:8640"));
  EXPECT_FALSE(HostAllowed(any, "myhost:8640"));
  // Port not known yet: any port.
  EXPECT_TRUE(HostAllowed(HostPolicy{"127.0.0.1", 0, {}}, "127.0.0.1:5555"));
}

TEST(CrossSiteRefusalTest, ProgramsAndTheDaemonsOwnPagesMayWrite) {
  const HostPolicy p = Loopback();
  EXPECT_FALSE(CrossSiteRefusal(p, "", ""));  // the CLI, a worker, curl
  EXPECT_FALSE(CrossSiteRefusal(p, "http://127.0.0.1:8640", "same-origin"));
  EXPECT_FALSE(CrossSiteRefusal(p, "http://localhost:8640", ""));
  EXPECT_FALSE(CrossSiteRefusal(p, "", "none"));  // typed into the address bar
}

TEST(CrossSiteRefusalTest, PagesOfOtherOriginsMayNot) {
  const HostPolicy p = Loopback();
  for (const char* origin : {"http://127.0.0.1:9999", "http://evil.example", "https://evil.example:8640", "null",
                             "file://", "http://127.0.0.1:8640/path", "chrome-extension://abc", "http://"}) {
    auto refused = CrossSiteRefusal(p, origin, "");
    ASSERT_TRUE(refused) << origin;
    EXPECT_EQ(refused->code(), StatusCode::kPermissionDenied);
    EXPECT_EQ(refused->field(), "Origin");
  }
  // Sec-Fetch-Site alone says so (another port of 127.0.0.1 is the same site, another origin).
  EXPECT_TRUE(CrossSiteRefusal(p, "", "cross-site"));
  EXPECT_TRUE(CrossSiteRefusal(p, "", "same-site"));
  EXPECT_TRUE(CrossSiteRefusal(p, "http://127.0.0.1:8640", "Cross-Site"));
}

// An origin of the daemon's host and port with the other scheme is another origin.
TEST(CrossSiteRefusalTest, TheOriginsSchemeIsTheDaemonsOwn) {
  HostPolicy p = Loopback();
  EXPECT_TRUE(CrossSiteRefusal(p, "https://127.0.0.1:8640", ""));
  p.tls = true;
  EXPECT_FALSE(CrossSiteRefusal(p, "https://127.0.0.1:8640", ""));
  EXPECT_TRUE(CrossSiteRefusal(p, "http://127.0.0.1:8640", ""));
  // Behind a proxy the operator named, the proxy may end TLS: either scheme.
  p.tls = false;
  p.allowed_names = {"sandswim.lab.example"};
  EXPECT_FALSE(CrossSiteRefusal(p, "https://sandswim.lab.example", ""));
}

// Per-client limits count an IPv4 address, or an IPv6 /64, as one client.
TEST(ClientKeyTest, EveryLoopbackAddressIsOneClientUnlessTheOperatorSetsThemApart) {
  for (const char* local : {"127.0.0.1", "127.0.0.2", "127.255.255.254", "127.1.2.3", "::1", "::ffff:127.0.0.9"}) {
    EXPECT_EQ(ClientKey(local), kLoopbackClient) << local;
  }
  EXPECT_EQ(ClientKey("127.0.0.2", /*loopback_apart=*/true), "127.0.0.2");
  EXPECT_EQ(ClientKey("::ffff:127.0.0.9", true), "127.0.0.9");
  EXPECT_EQ(ClientKey("::1", true), "::1");
  EXPECT_NE(ClientKey("127.0.0.1", true), ClientKey("127.0.0.2", true));
  for (const char* other : {"128.0.0.1", "126.255.255.255", "10.0.0.127", "::2", "::ffff:10.0.0.1"}) {
    EXPECT_NE(ClientKey(other), kLoopbackClient) << other;
  }
}

TEST(ClientKeyTest, IPv4ByAddressIPv6ByItsSlash64) {
  EXPECT_EQ(ClientKey("127.0.0.1", true), "127.0.0.1");
  EXPECT_EQ(ClientKey("10.1.2.3"), "10.1.2.3");
  EXPECT_EQ(ClientKey("::ffff:10.1.2.3"), "10.1.2.3");
  EXPECT_EQ(ClientKey("2001:db8:1:2:aaaa:bbbb:cccc:dddd"), "2001:db8:1:2::/64");
  EXPECT_EQ(ClientKey("2001:db8:1:2::99"), ClientKey("2001:db8:1:2:ffff::1"));
  EXPECT_NE(ClientKey("2001:db8:1:2::1"), ClientKey("2001:db8:1:3::1"));
  EXPECT_EQ(ClientKey("?"), "?");
}

TEST(IsJsonMediaTypeTest, OnlyApplicationJson) {
  EXPECT_TRUE(IsJsonMediaType("application/json"));
  EXPECT_TRUE(IsJsonMediaType("Application/JSON; charset=utf-8"));
  EXPECT_TRUE(IsJsonMediaType(" application/json ;charset=UTF-8"));
  for (const char* t : {"", "text/plain", "application/x-www-form-urlencoded", "multipart/form-data; boundary=x",
                        "application/jsonp", "text/json", "application/json-seq"}) {
    EXPECT_FALSE(IsJsonMediaType(t)) << t;
  }
}

TEST(RedactPathsTest, FilePathsGoApiPathsStay) {
  EXPECT_EQ(RedactPaths("bed 3's restart file /var/lib/sandswim/data/beds/3/bed.restart is missing"),
            "bed 3's restart file (a path: see the daemon's log) is missing");
  EXPECT_EQ(RedactPaths("cannot write \"./var/data/uploads/x.part\": disk full"),
            "cannot write \"(a path: see the daemon's log)\": disk full");
  EXPECT_EQ(RedactPaths("no route GET /nope (see /api/v1/openapi.json)"),
            "no route GET (a path: see the daemon's log) (see /api/v1/openapi.json)");
  EXPECT_EQ(RedactPaths("the database is locked"), "the database is locked");
  EXPECT_THAT(RedactPaths("see http://127.0.0.1:8640/healthz"), HasSubstr("http://127.0.0.1:8640/healthz"));
}

// A throttle on a fake clock whose sleeps are recorded, not slept.
class FailedAuthThrottleTest : public ::testing::Test {
 protected:
  FailedAuthThrottle Make(FailedAuthThrottle::Options options = {}) {
    return FailedAuthThrottle(
        &clock_, options, [this](double s) { slept_.push_back(s); },
        [this](const std::string& l) { log_.push_back(l); });
  }
  FakeClock clock_;
  std::vector<double> slept_;
  std::vector<std::string> log_;
};

TEST_F(FailedAuthThrottleTest, FirstFailuresAreFreeThenEachWaitsLongerUpToTheCap) {
  FailedAuthThrottle t = Make({});
  for (int i = 0; i < 9; ++i)
    EXPECT_EQ(t.Failed("127.0.0.1", "POST /api/v1/sweeps"), FailedAuthThrottle::Verdict::kDelayed);
  EXPECT_EQ(slept_, (std::vector<double>{0.25, 0.5, 1, 2, 2, 2}));
  EXPECT_EQ(t.counts().failures, 9);
  EXPECT_EQ(t.counts().delayed, 6);
  EXPECT_DOUBLE_EQ(t.counts().delay_s_total, 7.75);
  // Another peer starts free.
  t.Failed("10.0.0.7", "GET /api/v1/runs");
  EXPECT_EQ(slept_.size(), 6u);
  // A peer quiet for longer than forget_after_s starts again.
  clock_.Advance(601);
  t.Failed("127.0.0.1", "POST /api/v1/sweeps");
  EXPECT_EQ(slept_.size(), 6u);
}

TEST_F(FailedAuthThrottleTest, LogsAtMostOneLinePerPeerPerIntervalWithTheCount) {
  FailedAuthThrottle t = Make({});
  for (int i = 0; i < 5; ++i) t.Failed("127.0.0.1", "POST /api/v1/sweeps");
  ASSERT_EQ(log_.size(), 1u);
  EXPECT_THAT(log_[0], HasSubstr("refused 1 request(s) with a wrong token from 127.0.0.1"));
  EXPECT_THAT(log_[0], HasSubstr("POST /api/v1/sweeps"));
  clock_.Advance(10);
  t.Failed("127.0.0.1", "GET /api/v1/runs");
  ASSERT_EQ(log_.size(), 2u);
  EXPECT_THAT(log_[1], HasSubstr("refused 5 request(s)"));  // the 4 unlogged and this one
  EXPECT_THAT(log_[1], HasSubstr("GET /api/v1/runs"));
  t.Failed("10.0.0.7", "GET /api/v1/runs");
  EXPECT_EQ(log_.size(), 3u) << "another peer has a line of its own";
}

// A network of guessers cannot grow the throttle's memory: past max_peers the peer quiet longest
// is forgotten (it starts again, free), while the busiest keeps its count.
TEST_F(FailedAuthThrottleTest, RemembersAtMostMaxPeersForgettingTheQuietestFirst) {
  FailedAuthThrottle::Options options;
  options.free_failures = 1;
  options.max_peers = 3;
  FailedAuthThrottle t = Make(options);
  t.Failed("busy", "x");
  for (int i = 0; i < 50; ++i) {
    clock_.Advance(1);
    t.Failed("10.0.0." + std::to_string(i), "x");
    t.Failed("busy", "x");  // the most recent each time: never forgotten
  }
  const size_t slept_before = slept_.size();
  EXPECT_EQ(slept_before, 50u) << "busy's failures after its first free one are each delayed";
  t.Failed("10.0.0.0", "x");  // forgotten long ago: its first failure again, free
  EXPECT_EQ(slept_.size(), slept_before);
  t.Failed("10.0.0.49", "x");  // still remembered: its second failure waits
  EXPECT_EQ(slept_.size(), slept_before + 1);
}

// Delays hold threads: one per peer and max_sleeping in all; past that, 429 at once.
TEST_F(FailedAuthThrottleTest, ABusyPeerOrAFullPoolIsAnsweredAtOnce) {
  FailedAuthThrottle::Options options;
  options.free_failures = 0;
  options.max_sleeping = 2;
  FailedAuthThrottle* throttle = nullptr;
  std::vector<FailedAuthThrottle::Verdict> inner;
  // While a sleep of peer A is in progress, more failures arrive (from inside the sleep).
  int depth = 0;
  FailedAuthThrottle t(
      &clock_, options,
      [&](double) {
        if (depth++ > 0) return;
        inner.push_back(throttle->Failed("A", "x"));  // A already waits: busy
        inner.push_back(throttle->Failed("B", "x"));  // B waits in the second slot (recursing here)
      },
      [](const std::string&) {});
  throttle = &t;
  EXPECT_EQ(t.Failed("A", "x"), FailedAuthThrottle::Verdict::kDelayed);
  ASSERT_EQ(inner.size(), 2u);
  EXPECT_EQ(inner[0], FailedAuthThrottle::Verdict::kBusy);
  EXPECT_EQ(inner[1], FailedAuthThrottle::Verdict::kDelayed);
  EXPECT_EQ(t.counts().busy, 1);
  // All slots free again afterwards.
  EXPECT_EQ(t.Failed("A", "x"), FailedAuthThrottle::Verdict::kDelayed);
  EXPECT_EQ(t.Failed("C", "x"), FailedAuthThrottle::Verdict::kDelayed);
}

TEST_F(FailedAuthThrottleTest, TheGlobalCapHolds) {
  FailedAuthThrottle::Options options;
  options.free_failures = 0;
  options.max_sleeping = 1;
  FailedAuthThrottle* throttle = nullptr;
  FailedAuthThrottle::Verdict other = FailedAuthThrottle::Verdict::kDelayed;
  bool nested = false;
  FailedAuthThrottle t(
      &clock_, options,
      [&](double) {
        if (nested) return;
        nested = true;
        other = throttle->Failed("B", "x");  // another peer, but no free slot
      },
      [](const std::string&) {});
  throttle = &t;
  t.Failed("A", "x");
  EXPECT_EQ(other, FailedAuthThrottle::Verdict::kBusy);
}

// 4,786 refusals in 5 s once made as many log lines: now one per peer and kind per interval, the
// next saying how many were left out.
TEST(RefusalLogTest, OneLinePerPeerAndKindPerIntervalWithACount) {
  FakeClock clock;
  std::vector<std::string> lines;
  RefusalLog log(&clock, /*every_s=*/10, /*max_entries=*/4, [&](const std::string& l) { lines.push_back(l); });
  int built = 0;
  for (int i = 0; i < 1000; ++i) {
    log.Refused("loopback", "host", [&] {
      ++built;
      return std::string("refused a Host");
    });
  }
  log.Refused("loopback", "cross-site", [] { return std::string("refused a cross-site write"); });
  log.Refused("10.0.0.9", "host", [] { return std::string("refused another's Host"); });
  ASSERT_EQ(lines.size(), 3u);
  EXPECT_EQ(built, 1) << "a line was built for a refusal that was not logged";
  EXPECT_EQ(log.unlogged_total(), 999);
  clock.Advance(10);
  log.Refused("loopback", "host", [] { return std::string("refused a Host"); });
  ASSERT_EQ(lines.size(), 4u);
  EXPECT_EQ(lines[3], "refused a Host (and 999 more such refusal(s) of loopback since its last line; at most one "
                      "line per 10 s)");
  EXPECT_EQ(log.unlogged_total(), 0);
  // Past max_entries, the quiet pairs are forgotten: memory stays bounded however many peers come.
  for (int i = 0; i < 100; ++i) log.Refused("10.1.0." + std::to_string(i), "slow", [] { return std::string("x"); });
  EXPECT_EQ(lines.size(), 104u);
}

}  // namespace
}  // namespace sandswim
