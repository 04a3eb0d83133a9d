// Watch: follows a sweep or campaign run until nothing is queued or running, showing progress.
//
// On a terminal (WatchOptions::tty) each poll redraws one frame in place: the cursor moves back
// up over the previous frame (ANSI "ESC[nF"), the rest of the screen is cleared ("ESC[J") and the
// new frame (RenderWatchFrame) is written. When piped, it writes RenderWatchLine() lines: only
// when the line changed, at most one every `line_interval_s`, and always the final one.
//
// Each refresh reads the daemon's progress board (GET /api/v1/live, the dashboard's; an unchanged
// one is a 304): one request whatever the number of runs, two more while runs wait for a bed. A
// refresh the board cannot serve reads the target's own routes; a target the board will never
// show (older than its newest sweeps) is followed through them from then on (snapshot.h
// FetchSnapshotFromBoard). The ETA is the daemon's. When the target ends with failed runs, they
// are listed after the last frame or line (RenderFailures), read once from the target's routes
// when the board gave the count only.
//
// A daemon that cannot be reached (connection refused or reset, a timeout, a 502-504: kUnavailable)
// after the first frame costs those refreshes only: the last frame stays, "daemon unreachable since
// HH:MM:SS UTC; retrying" is said once (a line on `notices` when piped, a line under the frame on a
// terminal), and the watch carries on when the daemon answers again. Only after
// WatchOptions::give_up_after_s of it does the watch end, with an error that says what to do. A
// daemon unreachable at the first refresh ends the watch at once (most likely a wrong address).
//
// Time is the injected clock's (platform/clock.h): its monotonic time spaces the piped lines,
// times the give-up deadline and its sleep the refreshes, so tests run on a FakeClock without
// waiting; its wall time is the "since" said.
//
// Thread safety: call from one thread.
#ifndef SANDSWIM_CLI_WATCH_H_
#define SANDSWIM_CLI_WATCH_H_

#include <functional>
#include <ostream>

#include "cli/client.h"
#include "cli/format.h"
#include "cli/snapshot.h"
#include "core/status.h"
#include "platform/clock.h"

namespace sandswim::cli {

struct WatchOptions {
  bool tty = false;
  bool color = false;
  double interval_s = 1.0;       // between polls
  double line_interval_s = 5.0;  // piped: at most one line this often
  double give_up_after_s = 600;  // a daemon unreachable this long (monotonic s) ends the watch
  std::ostream* notices = nullptr;  // piped: where "daemon unreachable" is said (nullptr: `out`)
};

// Follows `target` until it is finished; returns the last snapshot, its failures listed (the
// caller decides the exit code from its counts). Errors from the daemon before the target has
// finished end the watch, except an unreachable daemon after the first frame (above), which ends
// it only after options.give_up_after_s.
Result<Snapshot> Watch(DaemonClient& client, const Target& target, const WatchOptions& options, Clock& clock,
                       std::ostream& out);

}  // namespace sandswim::cli

#endif  // SANDSWIM_CLI_WATCH_H_
