// The daemon's data directory (sandswimd --data DATA): every path under it is spelled here and
// nowhere else, so its layout reads in one place and a data directory made by an earlier version
// keeps working (data_dir_test.cc pins each spelling):
//   DATA/token                            the bearer token made on the first start (platform/token.h)
//   DATA/tls/                             the self-signed certificate and key (platform/tls.h)
//   DATA/beds/KEY.restart                 a prepared bed's restart file, by bed key
//   DATA/snapshots/run-ID/IDX.dump        a run's full-bed snapshots
//   DATA/figures/                         the figure cache (server/analysis/figure_cache.h)
//   DATA/backups/                         online backups being written (scratch: cleared at start)
//   DATA/uploads/                         request bodies being received (scratch: cleared at start)
//   DATA/worker/                          the local workers' own directory (--local-workers)
// It lives in platform/, below the daemon's rooms, because the CLI (the token, the certificate)
// and the store room (snapshot files) need it as well as the HTTP routes and the lease queue.
//
// A DataDir is a value: it names paths and touches no file. An empty root spells paths relative
// to the working directory (a daemon without --data keeps no files: callers check empty()).
//
// Thread safety: immutable after construction.
#ifndef SANDSWIM_PLATFORM_DATA_DIR_H_
#define SANDSWIM_PLATFORM_DATA_DIR_H_

#include <cstdint>
#include <string>

namespace sandswim {

class DataDir {
 public:
  explicit DataDir(std::string root) : root_(std::move(root)) {}

  const std::string& root() const { return root_; }
  bool empty() const { return root_.empty(); }

  std::string Token() const;
  std::string Tls() const;
  std::string Beds() const;
  std::string BedRestart(const std::string& bed_key) const;
  std::string Snapshots() const;
  std::string RunSnapshots(int64_t run_id) const;
  std::string Snapshot(int64_t run_id, int idx) const;
  std::string Figures() const;
  std::string Backups() const;
  std::string Uploads() const;
  std::string Worker() const;

 private:
  std::string Under(const std::string& name) const;
  std::string root_;
};

}  // namespace sandswim

#endif  // SANDSWIM_PLATFORM_DATA_DIR_H_
