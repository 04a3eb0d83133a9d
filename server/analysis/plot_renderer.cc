#include "server/analysis/plot_renderer.h"

#include <stdlib.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <sstream>
#include <utility>

#include "core/text.h"

namespace sandswim {
namespace {

// A temporary file of our own, removed when this goes out of scope.
class TempFile {
 public:
  static Result<TempFile> Make(const std::string& stem) {
    std::string pattern = (std::filesystem::temp_directory_path() / (stem + "-XXXXXX")).string();
    int fd = mkstemp(pattern.data());
    if (fd < 0) return Status::IOError("cannot make a temporary file " + pattern + " for a figure (disk full?)");
    close(fd);
    return TempFile(std::move(pattern));
  }
  TempFile(TempFile&& other) noexcept : path_(std::move(other.path_)) { other.path_.clear(); }
  TempFile(const TempFile&) = delete;
  TempFile& operator=(const TempFile&) = delete;
  ~TempFile() {
    if (path_.empty()) return;
    std::error_code ec;
    std::filesystem::remove(path_, ec);
  }
  const std::string& path() const { return path_; }

 private:
  explicit TempFile(std::string path) : path_(std::move(path)) {}
  std::string path_;
};

// The last `n` non-empty lines of `text`, joined by " / ".
std::string LastNonEmptyLines(const std::string& text, size_t n) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) {
    std::string trimmed(Trim(line));
    if (!trimmed.empty()) lines.push_back(std::move(trimmed));
  }
  std::string out;
  for (size_t i = lines.size() > n ? lines.size() - n : 0; i < lines.size(); ++i)
    out += (out.empty() ? "" : " / ") + lines[i];
  return out;
}

std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

}  // namespace

SubprocessRenderer::SubprocessRenderer(Subprocesses* processes, std::string program, double timeout_s,
                                       int max_running, double wait_s)
    : processes_(processes),
      program_(std::move(program)),
      timeout_s_(timeout_s),
      max_running_(std::max(1, max_running)),
      wait_s_(wait_s) {}

int SubprocessRenderer::running() const {
  std::lock_guard<std::mutex> lock(mu_);
  return running_;
}

int SubprocessRenderer::most_running() const {
  std::lock_guard<std::mutex> lock(mu_);
  return most_running_;
}

Result<std::string> SubprocessRenderer::Render(const Plot& plot, ImageFormat format) {
  SANDSWIM_RETURN_IF_ERROR(CheckPlot(plot));
  {
    std::unique_lock<std::mutex> lock(mu_);
    if (!freed_.wait_for(lock, std::chrono::duration<double>(wait_s_), [this] { return running_ < max_running_; })) {
      return Status::Unavailable("all " + std::to_string(max_running_) + " figure renderers are busy and none was free in " +
                                 Num(wait_s_, 3) + " s: retry shortly");
    }
    ++running_;
    most_running_ = std::max(most_running_, running_);
  }
  Result<std::string> drawn = RenderNow(plot, format);
  {
    std::lock_guard<std::mutex> lock(mu_);
    --running_;
  }
  freed_.notify_one();
  return drawn;
}

Result<std::string> SubprocessRenderer::RenderNow(const Plot& plot, ImageFormat format) {
  Result<TempFile> input = TempFile::Make("sandswim-plot");
  if (!input.ok()) return input.status();
  Result<TempFile> output = TempFile::Make("sandswim-figure");
  if (!output.ok()) return output.status();
  {
    std::ofstream out(input->path(), std::ios::binary | std::ios::trunc);
    out << nlohmann::json(plot).dump();
    out.close();  // a failure of the last flush counts too
    if (!out) return Status::IOError("cannot write " + input->path() + " for the figure renderer (disk full?)");
  }
  Result<CommandOutput> run =
      processes_->Run({program_, input->path(), ImageExtension(format), output->path()}, {}, timeout_s_);
  if (!run.ok()) {
    return Status::Unavailable("cannot start the figure renderer " + program_ + " (" + run.status().reason() +
                               "): install sandswim-render next to sandswimd (cmake --build build)");
  }
  const std::string said = LastNonEmptyLines(run->err, 3);
  if (run->timed_out) {
    return Status::Unavailable("the figure renderer took longer than " + Num(timeout_s_, 4) +
                               " s and was stopped; the daemon goes on" + (said.empty() ? "" : ": " + said));
  }
  if (run->exit_code != 0) {
    const std::string how = run->exit_code > 128 ? "died on signal " + std::to_string(run->exit_code - 128)
                                                 : "failed (exit " + std::to_string(run->exit_code) + ")";
    return Status::Internal("the figure renderer " + how + " drawing \"" + plot.title +
                            "\"; the daemon goes on without this figure" + (said.empty() ? "" : ". It said: " + said));
  }
  std::string bytes = ReadAll(output->path());
  if (bytes.empty()) return Status::IOError("the figure renderer wrote nothing to " + output->path() + " (disk full?)");
  return bytes;
}

int RenderMain(int argc, const char* const* argv) {
  const char* usage = "usage: sandswim-render PLOT.json svg|png OUT (draws a sandswimd plot with PLplot)";
  if (argc != 4) {
    std::cerr << usage << "\n";
    return 2;
  }
  const std::string format_name = argv[2];
  if (format_name != "svg" && format_name != "png") {
    std::cerr << "sandswim-render: format must be svg or png, got \"" << format_name << "\"\n" << usage << "\n";
    return 2;
  }
  const ImageFormat format = format_name == "svg" ? ImageFormat::kSvg : ImageFormat::kPng;
  const std::string text = ReadAll(argv[1]);
  nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  Result<Plot> plot = PlotFromJson(j);
  if (!plot.ok()) {
    std::cerr << "sandswim-render: " << argv[1] << ": " << plot.status().ToString() << "\n";
    return 2;
  }
  Status drawn = DrawPlotToFile(*plot, format, argv[3]);
  if (!drawn.ok()) {
    std::cerr << "sandswim-render: " << drawn.ToString() << "\n";
    return drawn.code() == StatusCode::kInvalidArgument ? 2 : 1;
  }
  return 0;
}

}  // namespace sandswim
