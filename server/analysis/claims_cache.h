// ClaimsCache: CheckClaims' answers (claim_check.h) kept per campaign run, so that asking again
// for a campaign run's verdicts (GET /api/v1/campaign-runs/{id}/claims: 194 ms for 58 runs, every
// time, issue #49) costs a map lookup while nothing changed.
//
// When an answer is evaluated again: a verdict reads the campaign's definition, the campaign run's
// sweeps, runs, results, failures and beds, and its rounds; an answer is kept only while no write
// transaction has committed since it was evaluated (Database::commits()). That is more often
// than needed (a heartbeat of another campaign's run ends it too) but never less: a verdict is
// never served from before a change that could alter it. Concurrent callers asking for the same
// campaign run while it is evaluated wait for that one evaluation.
//
// Errors (NotFound, a store error) are not kept. At most kMaxEntries campaign runs are kept; past
// it the cache is emptied (answers are cheap to make again once, costly to make per request).
//
// Thread safety: every member is safe from any thread. REQUIRES: `store` outlives the cache.
#ifndef SANDSWIM_SERVER_ANALYSIS_CLAIMS_CACHE_H_
#define SANDSWIM_SERVER_ANALYSIS_CLAIMS_CACHE_H_

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>

#include "core/status.h"
#include "server/analysis/claim_check.h"
#include "server/store/store.h"

namespace sandswim {

class ClaimsCache {
 public:
  static constexpr size_t kMaxEntries = 256;

  explicit ClaimsCache(Store* store);

  // CheckClaims(store, campaign_run_id), or the answer evaluated earlier while nothing was written since.
  Result<std::shared_ptr<const CampaignRunClaims>> Get(int64_t campaign_run_id);

  uint64_t evaluations() const { return evaluations_.load(); }  // CheckClaims calls made (tests, benchmarks)

 private:
  struct Entry {
    std::shared_ptr<const CampaignRunClaims> claims;  // null: none kept
    uint64_t commits = 0;                             // Database::commits() before the evaluation
    bool evaluating = false;
  };

  Store* store_;
  std::mutex mu_;
  std::condition_variable evaluated_;
  std::map<int64_t, Entry> entries_;  // guarded by mu_
  std::atomic<uint64_t> evaluations_{0};
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_CLAIMS_CACHE_H_
