// Snapshot: what `status` and `watch` look at, gathered from the daemon through DaemonClient.
//
// Targets: the CLI names a sweep by its id ("12") and a campaign run by its id prefixed "cr:"
// ("cr:7"), the form `submit CAMPAIGN` prints. `sweep:12` is accepted too.
//
// A campaign run's counts are those of its distinct runs (a run shared by two of its sweeps
// counts once), as the daemon reports them; its running and failed runs are gathered over its
// sweeps and de-duplicated by run id.
//
// Thread safety: free functions; the client is used from the calling thread only.
#ifndef SANDSWIM_CLI_SNAPSHOT_H_
#define SANDSWIM_CLI_SNAPSHOT_H_

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cli/client.h"
#include "cli/format.h"
#include "core/status.h"

namespace sandswim::cli {

struct Target {
  enum class Kind { kSweep, kCampaignRun };
  Kind kind = Kind::kSweep;
  int64_t id = 0;
  std::string ToString() const;  // "12" or "cr:7"
};

// "12", "sweep:12" -> a sweep; "cr:7" -> a campaign run. InvalidArgument naming `field` otherwise.
Result<Target> ParseTarget(const std::string& text, const std::string& field = "SWEEP");

// A run id ("12"); InvalidArgument naming `field` otherwise.
Result<int64_t> ParseId(const std::string& text, const std::string& field);

// Counts, runs in flight, failures and the daemon's ETA of a sweep or campaign run, from its own
// routes: 1 + 2 x its sweeps requests (runs in flight and failures by sweep), 2 more while runs
// wait for a bed.
Result<Snapshot> FetchSnapshot(DaemonClient& client, const Target& target);

// Why SnapshotFromBoard gave no snapshot: kForGood when the board will not show the target later
// either (older than every sweep or campaign run of its kind the board lists, or a board from
// before running runs named their sweeps); kThisRefresh when a later board may (newer than the
// board, which the daemon rebuilds at most once a tick; more runs in flight than the board lists;
// an unreadable board; a stale one: "stale": true, a board the daemon failed to rebuild, whose
// counts may be those of a target since finished).
enum class BoardMiss { kNone, kThisRefresh, kForGood };

// The target as the daemon's progress board (GET /api/v1/live) shows it: title, counts, the
// daemon's ETA and the runs in flight, grouped by sweep in the target's order as FetchSnapshot
// lists them (failures are not on the board: `failed` stays empty, the count is in `counts`).
// nullopt when the board does not show it (`miss`, when given, says whether it may later).
// `target_sweeps`, when given, receives the target's sweep ids in its order.
Result<std::optional<Snapshot>> SnapshotFromBoard(const nlohmann::json& board, const Target& target,
                                                  std::vector<int64_t>* target_sweeps = nullptr,
                                                  BoardMiss* miss = nullptr);

// What `watch` looks at each refresh, in one request (two more while runs wait for a bed): the
// board (SnapshotFromBoard) while `*board_usable`, else FetchSnapshot. A refresh the board cannot
// serve falls back to FetchSnapshot; it sets *board_usable false (FetchSnapshot from then on) only
// when the daemon has no board (Live() answers 404, or the 503 of a daemon without a live feed) or
// the board will never show the target (BoardMiss::kForGood). REQUIRES: board_usable != nullptr.
Result<Snapshot> FetchSnapshotFromBoard(DaemonClient& client, const Target& target, bool* board_usable);

// The results of a sweep or campaign run, as the daemon sends them: {"id", "results": [one row a
// run], "aggregates": [one a point, over its replicate beds]} ("aggregates" is [] from a daemon
// older than replicates).
Result<nlohmann::json> FetchResults(DaemonClient& client, const Target& target);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_SNAPSHOT_H_
