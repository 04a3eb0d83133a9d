#include "server/analysis/figure_cache.h"

#include <unistd.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <nlohmann/json.hpp>

#include "core/keys.h"
#include "server/analysis/plot_renderer.h"

namespace sandswim {

FigureCache::FigureCache(std::string dir, PlotRenderer* renderer) : dir_(std::move(dir)), renderer_(renderer) {}

std::string FigureCache::PathFor(const std::string& name, const Plot& plot, ImageFormat format) const {
  std::string hash = Sha256Hex(nlohmann::json(plot).dump() + "\n" + ImageExtension(format) + "\n" + FigureStyleVersion());
  return (std::filesystem::path(dir_) / (name + "-" + hash.substr(0, 16) + "." + ImageExtension(format))).string();
}

Result<std::string> FigureCache::Get(const std::string& name, const Plot& plot, ImageFormat format) {
  const std::string path = PathFor(name, plot, format);
  {
    std::ifstream in(path, std::ios::binary);
    if (in) {
      std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
      if (!bytes.empty()) return bytes;
    }
  }
  auto bytes = renderer_ != nullptr ? renderer_->Render(plot, format) : RenderPlot(plot, format);
  if (!bytes.ok()) return bytes.status();
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  if (ec) return Status::IOError("cannot create " + dir_ + ": " + ec.message());
  // Older figures of this name were drawn from older results: they go.
  const std::string prefix = name + "-";
  const std::string extension = std::string(".") + ImageExtension(format);
  for (const auto& entry : std::filesystem::directory_iterator(dir_, ec)) {
    std::string file = entry.path().filename().string();
    if (file.rfind(prefix, 0) == 0 && file.size() == prefix.size() + 16 + extension.size() &&
        file.compare(file.size() - extension.size(), extension.size(), extension) == 0 && entry.path() != path) {
      std::filesystem::remove(entry.path(), ec);
    }
  }
  static std::atomic<uint64_t> counter{0};
  std::string temp = path + ".tmp" + std::to_string(getpid()) + "-" + std::to_string(counter.fetch_add(1));
  {
    std::ofstream out(temp, std::ios::binary | std::ios::trunc);
    out.write(bytes->data(), static_cast<std::streamsize>(bytes->size()));
    out.close();  // a failure of the last flush counts too
    if (!out) {
      std::filesystem::remove(temp, ec);
      return Status::IOError("cannot write " + temp + " (disk full?)");
    }
  }
  std::filesystem::rename(temp, path, ec);
  if (ec) {
    std::filesystem::remove(temp, ec);
    return Status::IOError("cannot rename a figure into " + path);
  }
  return bytes;
}

}  // namespace sandswim
