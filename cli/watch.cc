#include "cli/watch.h"

#include <algorithm>

namespace sandswim::cli {

Result<Snapshot> Watch(DaemonClient& client, const Target& target, const WatchOptions& options, const WatchClock& clock,
                       std::ostream& out) {
  RenderOptions render;
  render.color = options.color;
  int frame_lines = 0;    // tty: lines of the frame on screen
  std::string last_line;  // piped: the last line written
  double last_line_at = -1e300;
  std::optional<int64_t> timed_done;  // the done count the cached wall times belong to
  std::vector<double> done_wall_s;

  while (true) {
    // The wall times only change when runs finish: fetch them only then.
    Snapshot s;
    {
      auto probe = FetchSnapshot(client, target, SnapshotOptions{/*done_timings=*/false});
      if (!probe.ok()) return probe.status();
      s = std::move(*probe);
      if (!timed_done || *timed_done != s.counts.done) {
        auto full = FetchSnapshot(client, target, SnapshotOptions{/*done_timings=*/true});
        if (!full.ok()) return full.status();
        s = std::move(*full);
        done_wall_s = s.done_wall_s;
        timed_done = s.counts.done;
      } else {
        s.done_wall_s = done_wall_s;
      }
    }
    bool finished = s.counts.finished();
    double now = clock.now();
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
    if (finished) return s;
    clock.sleep(options.interval_s);
  }
}

}  // namespace sandswim::cli
