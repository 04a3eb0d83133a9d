// PlotRenderer: who draws a Plot (server/analysis/figures.h) into SVG or PNG bytes.
//
// PLplot ends its process on an internal error (plexit() prints "*** PLPLOT ERROR, IMMEDIATE
// EXIT ***" and calls exit(1)) and keeps global state; a daemon that draws in its own process can
// be ended by one bad figure. So sandswimd draws nothing itself: SubprocessRenderer hands each
// plot to `sandswim-render` (server/render_main.cc, installed next to sandswimd) through a
// temporary JSON file, waits for it (at most `timeout_s`), and reads the image it wrote. A
// renderer that fails, dies on a signal or hangs costs that one figure, with an error saying what
// happened and what PLplot printed; the daemon goes on serving.
//
// InProcessRenderer draws in this process (RenderPlot): the renderer itself, and tests.
//
// Errors: InvalidArgument ("plot") for a plot RenderPlot would refuse, checked before any process
// is started; Internal for a renderer that failed or died (its exit, its last stderr lines);
// Unavailable when it cannot be started or ran out of time; IOError for the temporary files.
//
// Concurrency: SubprocessRenderer runs at most `max_running` renderers at once (46 parallel figure
// requests once started 43); a figure past them waits up to `wait_s` for one to finish, then is
// Unavailable ("retry shortly"; the route answers 503 with Retry-After). A figure drawn before is
// served from the cache (server/analysis/figures.h) without a renderer.
//
// Thread safety: both are safe from any thread; SubprocessRenderer draws several figures at once
// in separate processes.
#ifndef SANDSWIM_SERVER_ANALYSIS_PLOT_RENDERER_H_
#define SANDSWIM_SERVER_ANALYSIS_PLOT_RENDERER_H_

#include <condition_variable>
#include <mutex>
#include <string>

#include "core/status.h"
#include "platform/subprocess.h"
#include "server/analysis/figures.h"

namespace sandswim {

class PlotRenderer {
 public:
  virtual ~PlotRenderer() = default;
  virtual Result<std::string> Render(const Plot& plot, ImageFormat format) = 0;
};

class InProcessRenderer : public PlotRenderer {
 public:
  Result<std::string> Render(const Plot& plot, ImageFormat format) override { return RenderPlot(plot, format); }
};

class SubprocessRenderer : public PlotRenderer {
 public:
  // `program`: the path of sandswim-render. `processes` must outlive this. REQUIRES: max_running >= 1.
  SubprocessRenderer(Subprocesses* processes, std::string program, double timeout_s = 120, int max_running = 4,
                     double wait_s = 10);
  Result<std::string> Render(const Plot& plot, ImageFormat format) override;

  int running() const;       // renderers now running
  int most_running() const;  // the most that ever ran at once (for tests and benchmarks)

 private:
  Result<std::string> RenderNow(const Plot& plot, ImageFormat format);

  Subprocesses* processes_;
  std::string program_;
  double timeout_s_;
  const int max_running_;
  const double wait_s_;
  mutable std::mutex mu_;
  std::condition_variable freed_;
  int running_ = 0;
  int most_running_ = 0;
};

// The renderer's command line: `sandswim-render PLOT.json svg|png OUT`. Exit codes of
// sandswim-render: 0 drawn, 2 a bad command line or plot (stderr says which), 1 anything else,
// PLplot's own exit among them.
int RenderMain(int argc, const char* const* argv);

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_PLOT_RENDERER_H_
