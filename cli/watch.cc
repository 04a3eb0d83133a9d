#include "cli/watch.h"

#include <algorithm>

namespace sandswim::cli {

Result<Snapshot> Watch(DaemonClient& client, const Target& target, const WatchOptions& options, Clock& clock,
                       std::ostream& out) {
  RenderOptions render;
  render.color = options.color;
  int frame_lines = 0;    // tty: lines of the frame on screen
  std::string last_line;  // piped: the last line written
  double last_line_at = -1e300;
  bool board_usable = true;  // the daemon's progress board shows the target

  while (true) {
    auto fetched = FetchSnapshotFromBoard(client, target, &board_usable);
    if (!fetched.ok()) return fetched.status();
    Snapshot s = std::move(*fetched);
    bool finished = s.counts.finished();
    double now = clock.Monotonic();
    if (options.tty) {
      std::string frame = RenderWatchFrame(s, render);
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
