// The figure renderer in a process of its own: the real sandswim-render draws what RenderPlot
// draws in-process; a renderer that fails, dies or hangs costs one figure with a clear error.
#include "server/plot_renderer.h"

#include <stdlib.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>

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
