// The figure renderer in a process of its own: the real sandswim-render draws what RenderPlot
// draws in-process; a renderer that fails, dies or hangs costs one figure with a clear error.
#include "server/analysis/plot_renderer.h"

#include <stdlib.h>
#include <sys/stat.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace sandswim {
namespace {

using ::testing::HasSubstr;
using json = nlohmann::json;

Plot TwoSeries() {
  Plot p;
  p.title = "a title with Δz and #";
  p.x_label = "t (s)";
  p.y_label = "Δz (m)";
  Series a{"up", {0, 0.1, 0.2}, {0, 0.01, 0.02}, {}, false, false};
  Series b{"points", {0, 0.1, 0.2}, {0, -0.01, -0.02}, {0.001, 0.001, 0.002}, true, true};
  p.series = {a, b};
  return p;
}

class PlotRendererTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/sandswim-renderer-XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    unsetenv("TMPDIR");
    std::filesystem::remove_all(dir_);
  }
  // A stand-in renderer: a shell script with `body`.
  std::string Script(const std::string& name, const std::string& body) {
    const std::string path = dir_ + "/" + name;
    std::ofstream(path) << "#!/bin/sh\n" << body << "\n";
    chmod(path.c_str(), 0755);
    return path;
  }
  std::string dir_;
  PosixSubprocesses processes_;
};

TEST(PlotJsonTest, RoundTripsAndRefusesWhatIsNotAPlot) {
  const Plot plot = TwoSeries();
  auto back = PlotFromJson(json(plot));
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(json(*back), json(plot));
  for (const char* bad :
       {R"([])", R"({"title":"t","x_label":"x","y_label":"y"})",
        R"({"title":1,"x_label":"x","y_label":"y","series":[]})",
        R"({"title":"t","x_label":"x","y_label":"y","series":[{"label":"a","x":[1],"y":["2"],"y_err":[]}]})",
        R"({"title":"t","x_label":"x","y_label":"y","series":[{"x":[1],"y":[2],"y_err":[]}]})"}) {
    auto parsed = PlotFromJson(json::parse(bad));
    EXPECT_FALSE(parsed.ok()) << bad;
    EXPECT_EQ(parsed.status().field(), "plot") << bad;
  }
}

TEST_F(PlotRendererTest, TheRendererProcessDrawsWhatThisProcessDraws) {
  std::filesystem::create_directories(dir_ + "/tmp");
  setenv("TMPDIR", (dir_ + "/tmp").c_str(), 1);  // until TearDown
  SubprocessRenderer renderer(&processes_, SANDSWIM_RENDER_PATH);
  for (ImageFormat format : {ImageFormat::kSvg, ImageFormat::kPng}) {
    auto there = renderer.Render(TwoSeries(), format);
    ASSERT_TRUE(there.ok()) << there.status().ToString();
    auto here = RenderPlot(TwoSeries(), format);
    ASSERT_TRUE(here.ok());
    if (format == ImageFormat::kSvg) {
      EXPECT_EQ(*there, *here);
    } else {
      EXPECT_EQ(there->substr(1, 3), "PNG");
    }
  }
  // What RenderPlot refuses is refused before any process starts.
  Plot empty;
  EXPECT_EQ(renderer.Render(empty, ImageFormat::kSvg).status().field(), "plot");
  // No temporary file is left behind (this test's own temporary directory).
  EXPECT_TRUE(std::filesystem::is_empty(dir_ + "/tmp"));
}

TEST_F(PlotRendererTest, AFailedDeadOrHungRendererIsOneClearError) {
  // PLplot's own exit, as plexit() prints it.
  SubprocessRenderer plexit(&processes_, Script("plexit",
                                                "echo '*** PLPLOT ERROR, IMMEDIATE EXIT ***' >&2\n"
                                                "echo 'plwind: Invalid window limits' >&2\nexit 1"));
  auto failed = plexit.Render(TwoSeries(), ImageFormat::kSvg);
  ASSERT_FALSE(failed.ok());
  EXPECT_EQ(failed.status().code(), StatusCode::kInternal);
  EXPECT_THAT(failed.status().reason(), HasSubstr("failed (exit 1)"));
  EXPECT_THAT(failed.status().reason(), HasSubstr("plwind: Invalid window limits"));
  EXPECT_THAT(failed.status().reason(), HasSubstr("the daemon goes on"));

  SubprocessRenderer crash(&processes_, Script("crash", "kill -SEGV $$"));
  auto died = crash.Render(TwoSeries(), ImageFormat::kPng);
  ASSERT_FALSE(died.ok());
  EXPECT_THAT(died.status().reason(), HasSubstr("died on signal 11"));

  SubprocessRenderer hang(&processes_, Script("hang", "exec sleep 30"), /*timeout_s=*/0.5);
  auto hung = hang.Render(TwoSeries(), ImageFormat::kSvg);
  ASSERT_FALSE(hung.ok());
  EXPECT_EQ(hung.status().code(), StatusCode::kUnavailable);
  EXPECT_THAT(hung.status().reason(), HasSubstr("longer than 0.5 s"));

  SubprocessRenderer silent(&processes_, Script("silent", "exit 0"));
  EXPECT_EQ(silent.Render(TwoSeries(), ImageFormat::kSvg).status().code(), StatusCode::kIOError);

  SubprocessRenderer missing(&processes_, dir_ + "/no-such-renderer");
  auto absent = missing.Render(TwoSeries(), ImageFormat::kSvg);
  ASSERT_FALSE(absent.ok());
  EXPECT_THAT(absent.status().reason(), HasSubstr("sandswim-render"));
}

// A renderer that holds every figure until opened, counting how many it holds at once.
class GatedSubprocesses : public Subprocesses {
 public:
  Result<CommandOutput> Run(const std::vector<std::string>&, const EnvVars&, double) override {
    std::unique_lock<std::mutex> lock(mu_);
    ++holding_;
    changed_.notify_all();
    changed_.wait(lock, [this] { return open_; });
    --holding_;
    return CommandOutput{};  // drew nothing: the figure is an IOError, which is not under test
  }
  Result<pid_t> Spawn(const std::vector<std::string>&) override { return Status::Unavailable("not here"); }
  std::optional<int> Reap(pid_t) override { return 0; }
  void SignalGroup(pid_t, int) override {}
  void Pause(double) override {}

  void WaitHolding(int n) {
    std::unique_lock<std::mutex> lock(mu_);
    changed_.wait(lock, [&] { return holding_ >= n; });
  }
  void Open() {
    std::lock_guard<std::mutex> lock(mu_);
    open_ = true;
    changed_.notify_all();
  }

 private:
  std::mutex mu_;
  std::condition_variable changed_;
  int holding_ = 0;
  bool open_ = false;
};

// 10 figures asked at once of a renderer allowed 3: three renderers run, the other seven wait
// their 0.2 s and are told to retry, none started.
TEST_F(PlotRendererTest, AtMostMaxRunningRenderersRunAtOnce) {
  GatedSubprocesses gate;
  SubprocessRenderer renderer(&gate, "sandswim-render", /*timeout_s=*/60, /*max_running=*/3, /*wait_s=*/0.2);
  std::atomic<int> busy{0}, drawn_or_failed{0};
  std::vector<std::thread> askers;
  for (int i = 0; i < 10; ++i) {
    askers.emplace_back([&] {
      auto figure = renderer.Render(TwoSeries(), ImageFormat::kSvg);
      if (!figure.ok() && figure.status().code() == StatusCode::kUnavailable &&
          figure.status().reason().find("renderers are busy") != std::string::npos) {
        busy.fetch_add(1);
      } else {
        drawn_or_failed.fetch_add(1);
      }
    });
  }
  gate.WaitHolding(3);
  // The seven past the limit give up on their own while the three are held.
  for (int i = 0; i < 3000 && busy.load() + drawn_or_failed.load() < 7; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  gate.Open();
  for (std::thread& t : askers) t.join();
  EXPECT_EQ(renderer.most_running(), 3);
  EXPECT_EQ(busy.load(), 7);
  EXPECT_EQ(drawn_or_failed.load(), 3);
  EXPECT_EQ(renderer.running(), 0);
}

TEST_F(PlotRendererTest, TheRendererRefusesABadCommandLineOrPlot) {
  const std::string plot = dir_ + "/plot.json";
  std::ofstream(plot) << R"({"title":"t"})";
  auto run = processes_.Run({SANDSWIM_RENDER_PATH, plot, "svg", dir_ + "/out.svg"}, {}, 30);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->exit_code, 2);
  EXPECT_THAT(run->err, HasSubstr("x_label"));
  run = processes_.Run({SANDSWIM_RENDER_PATH, plot, "gif", dir_ + "/out.gif"}, {}, 30);
  ASSERT_TRUE(run.ok());
  EXPECT_EQ(run->exit_code, 2);
  EXPECT_THAT(run->err, HasSubstr("svg or png"));
}

}  // namespace
}  // namespace sandswim
