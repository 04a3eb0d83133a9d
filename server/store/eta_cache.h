// EtaCache: ReadEta's answers (cost_model.h) kept in memory, so that a client polling a sweep's or
// a campaign run's status, or the live board, costs a map lookup instead of a read of every
// unfinished run of the scope and of the cost model's rates (issue #49: 40 ms an answer, and
// growing with the runs, as soon as a campaign ran).
//
// When an answer is read again: an answer is kept while no write transaction has committed since
// it was read (Database::commits(): a grant, a heartbeat, a completion, a cancel, a submission,
// anything) and for at most max_age_s (the ETA also moves with the clock alone: a running job's
// elapsed time, which engines still count as heartbeating). Under a stream of writes (64 engines
// heartbeating, runs completing every second) an answer is read again at most every
// min_refresh_s, however many clients ask: the cost is bounded by the refresh rate, not by the
// request rate. So an answer is at most min_refresh_s behind a change and max_age_s behind the
// clock. While one caller reads a scope's answer again, others asking for it get the previous
// one rather than wait; a scope never read waits for its first read.
//
// The key is (scope, id, min_slots); `now` is the caller's wall clock (an injected Clock's Now).
// Errors are not kept: the next call reads again.
//
// Thread safety: every member is safe from any thread. REQUIRES: `store` outlives the cache.
#ifndef SANDSWIM_SERVER_STORE_ETA_CACHE_H_
#define SANDSWIM_SERVER_STORE_ETA_CACHE_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <tuple>

#include "core/cost.h"
#include "core/status.h"
#include "server/store/cost_model.h"
#include "server/store/store.h"

namespace sandswim {

// An answer is never older than this (s): the live board's tick (server/dashboard/live_feed.h).
inline constexpr double kEtaMaxAgeS = 1.0;
// After a write, an answer is read again once it is this old (s).
inline constexpr double kEtaMinRefreshS = 0.25;

class EtaCache {
 public:
  explicit EtaCache(Store* store, double max_age_s = kEtaMaxAgeS, double min_refresh_s = kEtaMinRefreshS);

  // ReadEta(store, scope, id, now, min_slots), or the answer read earlier for the same key while it
  // is fresh (see the top of this file).
  Result<std::optional<Eta>> Get(EtaScope scope, int64_t id, double now, int min_slots);

  uint64_t reads() const { return reads_.load(); }  // ReadEta calls made (tests, benchmarks)

 private:
  using Key = std::tuple<EtaScope, int64_t, int>;
  struct Entry {
    bool has = false;  // `eta` holds an answer
    std::optional<Eta> eta;
    double read_at = 0;      // the caller's `now` of the read
    uint64_t commits = 0;    // Database::commits() before the read
    bool reading = false;    // a caller is reading it again
  };
  bool Fresh(const Entry& e, double now, uint64_t commits) const;

  Store* store_;
  const double max_age_s_, min_refresh_s_;
  std::mutex mu_;
  std::condition_variable read_done_;
  std::map<Key, Entry> entries_;  // guarded by mu_
  std::atomic<uint64_t> reads_{0};
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_ETA_CACHE_H_
