#include "server/analysis/claims_cache.h"

#include <iterator>
#include <utility>

namespace sandswim {

ClaimsCache::ClaimsCache(Store* store) : store_(store) {}

Result<std::shared_ptr<const CampaignRunClaims>> ClaimsCache::Get(int64_t campaign_run_id) {
  // Read before the store is: a commit that lands during the evaluation makes its answer stale.
  const uint64_t commits = store_->db().commits();
  {
    std::unique_lock<std::mutex> lock(mu_);
    while (true) {
      Entry& e = entries_[campaign_run_id];  // looked up again after a wait
      if (e.claims && e.commits == commits) return e.claims;
      if (!e.evaluating) {
        e.evaluating = true;
        break;
      }
      evaluated_.wait(lock);
    }
  }
  evaluations_.fetch_add(1);
  Result<CampaignRunClaims> claims = CheckClaims(*store_, campaign_run_id);
  std::lock_guard<std::mutex> lock(mu_);
  Entry& e = entries_[campaign_run_id];
  e.evaluating = false;
  evaluated_.notify_all();
  if (!claims.ok()) {
    e.claims = nullptr;
    return claims.status();
  }
  auto shared = std::make_shared<const CampaignRunClaims>(std::move(claims).value());
  if (entries_.size() > kMaxEntries) {
    for (auto it = entries_.begin(); it != entries_.end();) {
      it = it->second.evaluating || it->first == campaign_run_id ? std::next(it) : entries_.erase(it);
    }
  }
  e.claims = shared;
  e.commits = commits;
  return std::shared_ptr<const CampaignRunClaims>(shared);
}

}  // namespace sandswim
