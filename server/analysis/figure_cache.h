// FigureCache keeps rendered figures next to the results, under DATA_DIR/figures, named
// NAME-HASH.EXT where HASH is the SHA-256 of the plot's data, its format and the style version:
// new results make a new plot, hence a new name, so a stale figure is never served. Writing a new
// figure removes the older ones of the same NAME. Files are written to a temporary name and
// renamed, so a reader never sees half a figure.
//
// Thread safety: FigureCache is thread-safe (two threads may render the same figure at once; both
// write the same bytes).
#ifndef SANDSWIM_SERVER_ANALYSIS_FIGURE_CACHE_H_
#define SANDSWIM_SERVER_ANALYSIS_FIGURE_CACHE_H_

#include <string>

#include "core/status.h"
#include "server/analysis/figures.h"

namespace sandswim {

class PlotRenderer;

class FigureCache {
 public:
  // `dir`: where figures live (created on first write), e.g. DATA_DIR/figures. `renderer` draws
  // what is not there yet (must outlive this); nullptr: RenderPlot in this process (tests).
  explicit FigureCache(std::string dir, PlotRenderer* renderer = nullptr);

  // The figure `name` (e.g. "run-12-trajectory") of `plot`: read from the file when one for this
  // exact plot exists, else rendered and written.
  Result<std::string> Get(const std::string& name, const Plot& plot, ImageFormat format);

  // The file Get() reads or writes for this plot.
  std::string PathFor(const std::string& name, const Plot& plot, ImageFormat format) const;

 private:
  std::string dir_;
  PlotRenderer* renderer_;
};

}  // namespace sandswim

#endif  // SANDSWIM_SERVER_ANALYSIS_FIGURE_CACHE_H_
