// Snapshot files: where the full-bed snapshots that runs hand in (core/snapshot.h) are kept under
// the daemon's data directory, and how they are read back and cleaned up. The lease queue
// (server/jobs/lease_queue.h PutRunSnapshot) writes them; the report (server/analysis/report.h) and the
// REST routes read them; the rows that record them are the store's (table snapshots).
//
// Thread safety: free functions over the file system; a file is written by renaming a complete
// temporary file into place, so a reader never sees half of one.
#ifndef SANDSWIM_SERVER_STORE_SNAPSHOT_FILES_H_
#define SANDSWIM_SERVER_STORE_SNAPSHOT_FILES_H_

#include <cstdint>
#include <string>
#include <vector>

#include "core/snapshot.h"
#include "core/status.h"

namespace sandswim {

// Where a run's snapshot `idx` is kept: DataDir::Snapshot (platform/data_dir.h),
// DATA/snapshots/run-RUN_ID/IDX.dump.
// A stored snapshot, read and parsed: IOError saying what to do when its file is missing,
// Corruption when it no longer parses.
Result<BedSnapshot> ReadStoredSnapshot(const std::string& data_dir, int64_t run_id, int idx);
// Removes the snapshot files of `run_id` whose idx is not in `keep` (the directory too when
// nothing is kept). What a completion did not list, a failed attempt left, or a run that never
// completed holds. Returns how many files it removed.
int RemoveSnapshotFiles(const std::string& data_dir, int64_t run_id, const std::vector<int>& keep);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_STORE_SNAPSHOT_FILES_H_
