#include "server/store/eta_cache.h"

#include <iterator>
#include <utility>

namespace sandswim {
namespace {

// Past this many scopes, those not asked for within a max age are dropped at the next read.
constexpr size_t kMaxEntries = 1024;

}  // namespace

EtaCache::EtaCache(Store* store, double max_age_s, double min_refresh_s)
    : store_(store), max_age_s_(max_age_s), min_refresh_s_(min_refresh_s) {}

bool EtaCache::Fresh(const Entry& e, double now, uint64_t commits) const {
  const double age = now - e.read_at;
  if (!e.has || age < 0 || age >= max_age_s_) return false;  // a clock set back reads again
  return commits == e.commits || age < min_refresh_s_;
}

Result<std::optional<Eta>> EtaCache::Get(EtaScope scope, int64_t id, double now, int min_slots) {
  const Key key{scope, id, min_slots};
  // Read before the store is: a commit that lands during the read makes the answer stale.
  const uint64_t commits = store_->db().commits();
  {
    std::unique_lock<std::mutex> lock(mu_);
    while (true) {
      Entry& e = entries_[key];  // looked up again after a wait: another read may have dropped it
      if (Fresh(e, now, commits)) return e.eta;
      if (!e.reading) {
        e.reading = true;
        break;
      }
      if (e.has) return e.eta;  // another caller reads it again: the previous answer meanwhile
      read_done_.wait(lock);
    }
    if (entries_.size() > kMaxEntries) {
      for (auto it = entries_.begin(); it != entries_.end();) {
        const bool idle = !it->second.reading && now - it->second.read_at >= max_age_s_;
        it = idle ? entries_.erase(it) : std::next(it);
      }
    }
  }
  reads_.fetch_add(1);
  Result<std::optional<Eta>> eta = ReadEta(*store_, scope, id, now, min_slots);
  std::lock_guard<std::mutex> lock(mu_);
  Entry& e = entries_[key];
  e.reading = false;
  if (eta.ok()) {
    e.has = true;
    e.eta = *eta;
    e.read_at = now;
    e.commits = commits;
  }
  read_done_.notify_all();
  return eta;
}

}  // namespace sandswim
