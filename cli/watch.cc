#include "cli/watch.h"

#include <algorithm>
#include <cmath>
#include <ctime>
#include <string>

namespace sandswim::cli {
namespace {

// "07:21:05 UTC": when the daemon stopped answering.
std::string ClockTime(double epoch_s) {
  const std::time_t t = static_cast<std::time_t>(std::floor(epoch_s));
  std::tm tm{};
  gmtime_r(&t, &tm);
  char text[16];
  std::strftime(text, sizeof text, "%H:%M:%S", &tm);
  return std::string(text) + " UTC";
}

// A refresh that did not reach the daemon (refused, reset, timed out, a proxy's 502-504), as
// opposed to an answer that says no (a 4xx, a 500): a restarting daemon's, worth waiting out.
bool Unreachable(const Status& s) { return s.code() == StatusCode::kUnavailable; }

}  // namespace

Result<Snapshot> Watch(DaemonClient& client, const Target& target, const WatchOptions& options, Clock& clock,
                       std::ostream& out) {
  RenderOptions render;
  render.color = options.color;
  int frame_lines = 0;    // tty: lines of the frame on screen
  std::string last_line;  // piped: the last line written
  double last_line_at = -1e300;
  bool board_usable = true;  // the daemon's progress board shows the target
  bool shown = false;         // a frame or line was written: an unreachable daemon is waited out
  std::string frame;          // tty: the frame on screen
  bool unreachable = false;      // the last refresh did not reach the daemon
  double unreachable_since = 0;  // monotonic, from the first refresh that did not
  double unreachable_since_wall = 0;
  std::ostream& notices = options.notices != nullptr ? *options.notices : out;

  while (true) {
    auto fetched = FetchSnapshotFromBoard(client, target, &board_usable);
    if (!fetched.ok()) {
      if (!shown || !Unreachable(fetched.status())) return fetched.status();
      // Skipped: the last frame stays; said once, when the daemon stops answering.
      const double now = clock.Monotonic();
      if (!unreachable) {
        unreachable = true;
        unreachable_since = now;
        unreachable_since_wall = clock.Now();
        const std::string said = "daemon unreachable since " + ClockTime(unreachable_since_wall) + "; retrying";
        if (options.tty) {
          if (frame_lines > 0) out << "\x1b[" << frame_lines << "F\x1b[J";
          out << frame << said << "\n" << std::flush;
          frame_lines = static_cast<int>(std::count(frame.begin(), frame.end(), '\n')) + 1;
        } else {
          notices << said << "\n" << std::flush;
        }
      }
      if (now - unreachable_since >= options.give_up_after_s) {
        return Status::Unavailable("gave up on " + target.ToString() + ": the daemon has not answered since " +
                                   ClockTime(unreachable_since_wall) + " (" +
                                   std::to_string(static_cast<long long>(now - unreachable_since)) +
                                   " s; last: " + fetched.status().reason() + "). " + target.ToString() +
                                   " goes on without the watch: once the daemon runs again, `sandswim watch " +
                                   target.ToString() + "` follows it again (--give-up-after S waits longer)");
      }
      clock.SleepFor(options.interval_s);
      continue;
    }
    if (unreachable) {
      if (!options.tty) notices << "daemon answers again\n" << std::flush;
      unreachable = false;
    }
    shown = true;
    Snapshot s = std::move(*fetched);
    bool finished = s.counts.finished();
    double now = clock.Monotonic();
    if (options.tty) {
      frame = RenderWatchFrame(s, render);
      if (frame_lines > 0) out << "\x1b[" << frame_lines << "F\x1b[J";
      out << frame << std::flush;
      frame_lines = static_cast<int>(std::count(frame.begin(), frame.end(), '\n'));
    } else {
      std::string line = RenderWatchLine(s);
      if (line != last_line && (finished || now - last_line_at >= options.line_interval_s)) {
        out << line << "\n" << std::flush;
        last_line = line;
        last_line_at = now;
      }
    }
    if (finished) {
      // The board counts failures but does not list them: they are read once, at the end, and
      // listed after the last frame or line. The target has finished either way: a failure to
      // read them is said, not made the watch's.
      if (s.counts.failed > 0 && s.failed.empty()) {
        Result<Snapshot> named = FetchSnapshot(client, target);
        if (named.ok()) {
          s.failed = std::move(named->failed);
        } else {
          out << "(its " << s.counts.failed << " failed run(s) could not be listed: " << named.status().ToString()
              << "; `sandswim status " << target.ToString() << "` lists them)\n";
        }
      }
      out << RenderFailures(s.failed, render) << std::flush;
      return s;
    }
    clock.SleepFor(options.interval_s);
  }
}

}  // namespace sandswim::cli
