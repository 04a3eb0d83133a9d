// A campaign of two sweeps (an Ω sweep and the ±Ω baseline, sharing two runs) is submitted and
// "run" through the real lease queue with synthetic results; then the analysis, the HTML report
// (every internal link resolves, nothing is fetched from outside) and the REST routes of
// figures, fits and reports (real httplib server on an ephemeral port).
#include "server/analysis/report.h"

#include <stdlib.h>

#include <cmath>
#include <filesystem>
#include <regex>
#include <set>
#include <thread>

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <httplib.h>

#include "core/keys.h"
#include "core/text.h"
#include "platform/clock.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/claims_cache.h"
#include "server/jobs/lease_queue.h"
#include "server/jobs/rounds.h"
#include "server/http/loopback_server_test_util.h"
#include "server/analysis/plot_renderer.h"
#include "server/http/routes.h"
#include "server/jobs/submission.h"
#include "server/store/campaigns.h"
#include "server/store/rounds.h"
#include "server/store/temp_store_test_util.h"

namespace sandswim {
namespace {

using json = nlohmann::json;
using ::testing::HasSubstr;

constexpr char kReportEngine[] = "LIGGGHTS (Version test)";

const char* kCampaign = R"({"name": "tiny", "description": "two sweeps for the report test", "scale": "smoke",
  "drift_tolerance_mps": 0.001,
  "sweeps": [
    {"name": "omega", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -10, "duration_s": 0.3},
     "axes": [{"param": "Omega", "values": [-10, -20, -40, -80, 10, 20, 40, 80]}]},
    {"name": "baseline", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
     "axes": [{"param": "Omega", "values": [-80, 80]}]}]})";

// U_z of eq. 8 with C1 = 0.02 / 0.01 m/s and C2 = 0.03 s/rad, plus a small deterministic wobble.
double SyntheticUz(double omega) {
  double w = std::fabs(omega);
  double wobble = 1e-4 * std::sin(w);
  return omega < 0 ? 0.02 * (1 - std::exp(-0.03 * w)) + wobble : -0.01 * (1 - std::exp(-0.03 * w)) + wobble;
}

class ReportTest : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_TRUE(store_);
    dir_ = store_.dir().string();
    leases_ = std::make_unique<LeaseQueue>(store_.get(), &clock_, LeaseQueueOptions{});
    clock_.Set(1.7e9);
    StoredCampaign campaign;
    campaign.name = "tiny";
    campaign.definition = json::parse(kCampaign);
    ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
    SubmitRequest request;
    request.campaign = "tiny";
    auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
    ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
    ASSERT_TRUE(submitted->campaign_run_id.has_value());
    campaign_run_ = *submitted->campaign_run_id;
    sweeps_ = submitted->sweep_ids;
    ASSERT_EQ(sweeps_.size(), 2u);
  }

  void TearDown() override {
    StopServer();
    leases_.reset();
  }

  bool inconclusive_ = false;  // RunAll's results: inconclusive (one period) instead
  bool no_period_ = false;     // ... and with no whole period: no U_z at all
  int fail_omega_ = 0;         // RunAll fails the runs of this Omega (0: none) as deck errors

  // Prepares the bed and completes up to `runs` runs with synthetic results.
  void RunAll(int runs = 1000) {
    for (int done = 0; done < runs;) {
      auto grant = leases_->Lease(api::LeaseRequest{"test:1", "test", 1});
      ASSERT_TRUE(grant.ok()) << grant.status().ToString();
      if (!grant->has_value()) return;
      const api::LeaseGrant& g = **grant;
      api::Completion c;
      c.ok = true;
      c.execution.engine_version = kReportEngine;
      if (g.kind == api::JobKind::kBed) {
        const std::string restart = "a bed";
        ASSERT_TRUE(leases_->PutBedRestart(g.token, restart, Sha256Hex(restart), dir_ + "/data").ok());
        c.bed_result = api::BedResult{3700, 0.0,          0.22,         true,         1e-4,        Sha256Hex(restart),
                                      5,    std::nullopt, std::nullopt, std::nullopt, std::nullopt};
      } else {
        auto run = store_->GetRun(g.id);
        ASSERT_TRUE(run.ok());
        const double omega = run->summary.point.Omega;
        api::RunResult r;
        r.uz = SyntheticUz(omega);
        r.uz_stderr = 2e-4;
        r.uz_ci95 = 3.18 * 2e-4;
        r.uz_blocks = 4;
        r.block_s = 1.0 / 3;
        r.block_kind = "period";
        r.conclusive = true;
        if (inconclusive_) {  // one period, as every smoke run of paper-58 today
          r.uz_stderr.reset();
          r.uz_ci95.reset();
          r.uz_blocks = 1;
          r.conclusive = false;
          r.inconclusive_reason = "the steady window holds 1 whole period, fewer than 2";
        }
        if (no_period_) {
          r.uz.reset();
          r.uz_blocks = 0;
          r.inconclusive_reason = "the steady window holds no whole period";
        }
        r.stop_reason = "duration";
        c.result = r;
        api::Trajectory t;
        for (int i = 0; i <= 30; ++i) {
          double time = i * 0.01;
          t.t.push_back(time);
          t.x.push_back(1e-4 * i);
          t.y.push_back(0);
          t.z.push_back(*r.uz * time + 0.002 * std::sin(2 * M_PI * 3 * time));
        }
        c.trajectory = t;
        if (fail_omega_ != 0 && omega == fail_omega_) {
          c = api::Completion();
          c.execution.engine_version = kReportEngine;
          c.failure = api::Failure{"deck_error", "ERROR: a test failure"};
        }
        ++done;
      }
      auto reply = leases_->Complete(g.token, c);
      ASSERT_TRUE(reply.ok()) << reply.status().ToString();
    }
  }

  void StartServer() {
    deps_.store = store_.get();
    deps_.leases = leases_.get();
    deps_.clock = &clock_;
    deps_.data_dir = dir_ + "/data";
    deps_.engine_version = kReportEngine;
    server_ = std::make_unique<LoopbackServer>(deps_);
    client_ = &server_->client();
  }

  void StopServer() {
    server_.reset();
    client_ = nullptr;
  }

  std::string dir_;
  FakeClock clock_;
  testing::TempStore store_{"report", "test.db"};
  std::unique_ptr<LeaseQueue> leases_;
  int64_t campaign_run_ = 0;
  std::vector<int64_t> sweeps_;
  Deps deps_;
  std::unique_ptr<LoopbackServer> server_;
  httplib::Client* client_ = nullptr;
};

TEST_F(ReportTest, AnalyzeSweepFitsTheFinishedRuns) {
  auto before = AnalyzeSweep(*store_, sweeps_[0]);
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  EXPECT_TRUE(before->samples.empty());
  EXPECT_EQ(before->fits.choice.kind, FitKind::kSaturation);  // decided by the points, before any result
  RunAll();
  auto a = AnalyzeSweep(*store_, sweeps_[0]);
  ASSERT_TRUE(a.ok());
  EXPECT_EQ(a->samples.size(), 8u);
  EXPECT_EQ(a->runs.size(), 8u);
  ASSERT_EQ(a->fits.branches.size(), 2u);
  ASSERT_TRUE(a->fits.branches[0].saturation.has_value()) << a->fits.branches[0].error;
  EXPECT_NEAR(a->fits.branches[0].saturation->c1, 0.02, 3 * a->fits.branches[0].saturation->c1_stderr + 1e-3);
  EXPECT_EQ(a->fits.branches[1].sign_matches_paper, true);
  EXPECT_EQ(SweepTrajectoriesFigure(*a).series.size(), 8u);
  EXPECT_EQ(SweepUzFigure(*a).series.size(), 6u);  // two branches, each with its curve and band
  EXPECT_EQ(AnalyzeSweep(*store_, 999).status().code(), StatusCode::kNotFound);
}

// Inconclusive runs are shown (their one-period rate, not fitted) and the fit says it has none.
TEST_F(ReportTest, InconclusiveRunsAreShownButNotFitted) {
  inconclusive_ = true;
  RunAll();
  auto a = AnalyzeSweep(*store_, sweeps_[0]);
  ASSERT_TRUE(a.ok());
  EXPECT_TRUE(a->fits.branches.empty());
  EXPECT_EQ(a->fits.left_out.size(), 8u);
  Plot uz = SweepUzFigure(*a);
  ASSERT_EQ(uz.series.size(), 1u);
  EXPECT_EQ(uz.series[0].label, "inconclusive (not fitted)");
  EXPECT_EQ(uz.series[0].x.size(), 8u);
  FigureCache figures(dir_ + "/figures");
  auto html = CampaignReport(*store_, figures, campaign_run_, 1.7e9);
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  EXPECT_NE(html->find("no conclusive runs: 8 finished run(s) left out as inconclusive"), std::string::npos);
  EXPECT_NE(html->find("inconclusive (≈0.0"), std::string::npos);
}

// Finished runs none of which has a U_z (no whole period): the report is still made and says why
// it has no U_z figure; no empty plot is rendered.
TEST_F(ReportTest, ASweepWithNoUzHasNoUzFigureAndSaysWhy) {
  inconclusive_ = no_period_ = true;
  RunAll();
  auto a = AnalyzeSweep(*store_, sweeps_[0]);
  ASSERT_TRUE(a.ok());
  EXPECT_NE(NoUzToPlot(*a).find("no U_z to plot"), std::string::npos) << NoUzToPlot(*a);
  FigureCache figures(dir_ + "/figures");
  auto html = CampaignReport(*store_, figures, campaign_run_, 1.7e9);
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  EXPECT_NE(html->find("no U_z to plot: none of its 8 finished run(s)"), std::string::npos);
  EXPECT_NE(html->find("inconclusive (no whole period)"), std::string::npos);
  StartServer();
  const std::string sweep = "/api/v1/sweeps/" + std::to_string(sweeps_[0]);
  auto uz = client_->Get((sweep + "/uz.svg").c_str());
  ASSERT_TRUE(uz);
  EXPECT_EQ(uz->status, 422);
  EXPECT_THAT(uz->body, HasSubstr("no U_z to plot"));
  auto trajectories = client_->Get((sweep + "/trajectories.svg").c_str());
  EXPECT_EQ(trajectories->status, 200);
}

TEST_F(ReportTest, TheReportIsSelfContainedAndEveryLinkResolves) {
  RunAll();
  auto drift = ReportFinishedCampaignRuns(*store_, clock_.Now());
  ASSERT_TRUE(drift.ok()) << drift.status().ToString();
  ASSERT_EQ(drift->size(), 1u);
  FigureCache figures(dir_ + "/data/figures");
  auto html = CampaignReport(*store_, figures, campaign_run_, clock_.Now());
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  std::set<std::string> ids;
  static const std::regex kId(R"re(\sid="([^"]+)")re");
  for (auto it = std::sregex_iterator(html->begin(), html->end(), kId); it != std::sregex_iterator(); ++it) {
    EXPECT_TRUE(ids.insert((*it)[1].str()).second) << "duplicate id " << (*it)[1].str();
  }
  static const std::regex kHref(R"re(href="([^"]*)")re");
  int links = 0;
  for (auto it = std::sregex_iterator(html->begin(), html->end(), kHref); it != std::sregex_iterator(); ++it) {
    std::string target = (*it)[1].str();
    ASSERT_FALSE(target.empty());
    ASSERT_EQ(target[0], '#') << "a link leaves the page: " << target;
    EXPECT_TRUE(ids.count(target.substr(1))) << "no element for " << target;
    ++links;
  }
  // Contents 5, fit rows 3 (2 branches + the baseline's "none"), "top" 3, run rows 8 + 2, drift rows 8.
  EXPECT_EQ(links, 29);
  // The first section: the claims (this campaign states none, and says so).
  EXPECT_LT(html->find("id=\"claims\""), html->find("id=\"fits\""));
  EXPECT_THAT(*html, HasSubstr("The campaign states no claims"));
  EXPECT_THAT(*html, HasSubstr((*drift)[0].summary.substr(0, 20)));
  EXPECT_THAT(*html, ::testing::Not(HasSubstr(" src=")));              // nothing loaded from elsewhere
  EXPECT_THAT(*html, ::testing::Not(HasSubstr("could not be made")));  // every part was made
  EXPECT_THAT(*html, ::testing::Not(HasSubstr("<?xml")));              // SVGs inlined without their prolog
  // Both sweeps, each run's figure once (2 shared runs), and the sweeps' figures: the omega sweep's
  // Δz(t) of the rising and of the sinking branch (the paper's panels a and b) and U_z; the
  // baseline pair's Δz(t) on one plot (Fig. 4) and U_z.
  EXPECT_TRUE(ids.count("sweep-" + std::to_string(sweeps_[0])));
  EXPECT_TRUE(ids.count("sweep-" + std::to_string(sweeps_[1])));
  size_t svgs = 0;
  for (size_t at = html->find("<svg"); at != std::string::npos; at = html->find("<svg", at + 1)) ++svgs;
  EXPECT_EQ(svgs, 8u + 3 + 2);
  for (const char* branch : {"-rising-", "-sinking-"})  // each figure's ids carry its own prefix
    EXPECT_THAT(*html, HasSubstr("fig-sweep-" + std::to_string(sweeps_[0]) + "-trajectories" + branch)) << branch;
  EXPECT_THAT(*html, HasSubstr("C1 = "));
  EXPECT_THAT(*html, HasSubstr("id=\"drift\""));
  EXPECT_EQ(CampaignReport(*store_, figures, 999, 0).status().code(), StatusCode::kNotFound);
}

// A campaign run on replicate beds: the drift section lists each point's mean over its beds, with
// how many beds it rests on, beside the per-run rows.
TEST_F(ReportTest, AReplicatedCampaignsDriftSectionListsEachPointsMeanOverItsBeds) {
  StoredCampaign campaign;
  campaign.name = "tiny-replicated";
  campaign.definition = json::parse(R"({"name": "tiny-replicated", "description": "a pair on two beds",
    "scale": "smoke", "replicates": 2,
    "sweeps": [{"name": "pair", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
                "axes": [{"param": "Omega", "values": [-80, 80]}]}]})");
  ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
  SubmitRequest request;
  request.campaign = "tiny-replicated";
  auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  RunAll();
  auto drift = ReportFinishedCampaignRuns(*store_, clock_.Now());
  ASSERT_TRUE(drift.ok()) << drift.status().ToString();
  FigureCache figures(dir_ + "/data/figures");
  auto html = CampaignReport(*store_, figures, *submitted->campaign_run_id, clock_.Now());
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  EXPECT_THAT(*html, HasSubstr("Each point over its replicate beds"));
  EXPECT_THAT(*html, HasSubstr(" (2/2)"));           // the mean rests on both beds
  EXPECT_THAT(*html, HasSubstr("no earlier mean"));  // the campaign's first run
  // A point whose runs all failed has no mean, and says why (not "inconclusive").
  fail_omega_ = 80;
  request.force = true;  // run everything again
  auto rerun = Submit(*store_, request, kReportEngine, clock_.Now() + 60);
  ASSERT_TRUE(rerun.ok()) << rerun.status().ToString();
  RunAll();
  ASSERT_TRUE(ReportFinishedCampaignRuns(*store_, clock_.Now() + 120).ok());
  auto failed = CampaignReport(*store_, figures, *rerun->campaign_run_id, clock_.Now() + 120);
  ASSERT_TRUE(failed.ok()) << failed.status().ToString();
  EXPECT_THAT(*failed, HasSubstr("no mean: 2 failed"));
  EXPECT_THAT(*failed, HasSubstr(" (2/2)"));  // the other point, on both beds
  // The fixture's campaign, on one bed, has no such table.
  auto single = CampaignReport(*store_, figures, campaign_run_, clock_.Now());
  ASSERT_TRUE(single.ok());
  EXPECT_THAT(*single, ::testing::Not(HasSubstr("Each point over its replicate beds")));
}

// A plotting library's error in the renderer process costs the figure, not the daemon: the route
// answers a problem+json saying what happened, and the daemon goes on serving (figures included,
// once the renderer works again).
TEST_F(ReportTest, ARendererThatDiesIsAClearErrorAndTheDaemonKeepsServing) {
  RunAll();
  const std::string script = dir_ + "/dying-renderer";
  std::ofstream(script) << "#!/bin/sh\necho '*** PLPLOT ERROR, IMMEDIATE EXIT ***' >&2\nkill -ABRT $$\n";
  std::filesystem::permissions(script, std::filesystem::perms::owner_all);
  PosixSubprocesses processes;
  SubprocessRenderer dying(&processes, script);
  deps_.renderer = &dying;
  StartServer();
  auto runs = store_->SweepResults(sweeps_[0]);
  ASSERT_TRUE(runs.ok());
  const std::string figure = "/api/v1/runs/" + std::to_string(runs->front().run_id) + "/trajectory.svg";
  auto r = client_->Get(figure.c_str());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 500);
  EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json");
  EXPECT_THAT(json::parse(r->body)["detail"].get<std::string>(), HasSubstr("died on signal 6"));
  EXPECT_THAT(r->body, HasSubstr("PLPLOT ERROR"));
  EXPECT_EQ(client_->Get("/healthz")->status, 200);
  EXPECT_EQ(client_->Get(("/api/v1/sweeps/" + std::to_string(sweeps_[0])).c_str())->status, 200);
  // The report is still made: every figure says in its place that it was not drawn, and why.
  auto report = client_->Get(("/api/v1/campaign-runs/" + std::to_string(campaign_run_) + "/report").c_str());
  ASSERT_TRUE(report);
  EXPECT_EQ(report->status, 200) << report->body;
  EXPECT_THAT(report->body, HasSubstr("part(s) of this report could not be made"));
  EXPECT_THAT(report->body, HasSubstr("figure not drawn: "));
  EXPECT_THAT(report->body, HasSubstr("died on signal 6"));
  EXPECT_THAT(report->body, HasSubstr("id=\"claims\""));
  StopServer();

  SubprocessRenderer real(&processes, SANDSWIM_RENDER_PATH);
  deps_.renderer = &real;
  StartServer();
  r = client_->Get(figure.c_str());
  ASSERT_TRUE(r);
  EXPECT_EQ(r->status, 200) << r->body;
  EXPECT_THAT(r->body, HasSubstr("<svg"));
}

TEST_F(ReportTest, RoutesServeFiguresFitsAndReportsWithTheirTypes) {
  RunAll();
  StartServer();
  const std::string sweep = "/api/v1/sweeps/" + std::to_string(sweeps_[0]);
  auto runs = store_->SweepResults(sweeps_[0]);
  ASSERT_TRUE(runs.ok());
  const std::string run = "/api/v1/runs/" + std::to_string(runs->front().run_id);
  const std::pair<std::string, std::string> ok[] = {
      {run + "/trajectory.svg", "image/svg+xml"},
      {run + "/trajectory.png", "image/png"},
      {sweep + "/trajectories.svg", "image/svg+xml"},
      {sweep + "/trajectories.png", "image/png"},
      {sweep + "/uz.svg", "image/svg+xml"},
      {sweep + "/uz.png", "image/png"},
      {sweep + "/fits", "application/json"},
      {"/api/v1/campaign-runs/" + std::to_string(campaign_run_) + "/report", "text/html; charset=utf-8"},
      {"/api/v1/campaigns/tiny/report", "text/html; charset=utf-8"},
      {"/api/v1/campaigns/tiny/report?scale=smoke", "text/html; charset=utf-8"},
  };
  for (const auto& [path, type] : ok) {
    auto r = client_->Get(path.c_str());
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, 200) << path << ": " << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), type) << path;
    EXPECT_FALSE(r->body.empty()) << path;
  }
  // One branch's runs (the paper's panels a and b): the omega sweep's four at Omega < 0.
  {
    auto a = AnalyzeSweep(*store_, sweeps_[0]);
    ASSERT_TRUE(a.ok());
    EXPECT_EQ(TrajectoryBranches(*a), (std::vector<std::string>{"rising", "sinking"}));
    auto pair = AnalyzeSweep(*store_, sweeps_[1]);
    ASSERT_TRUE(pair.ok());
    EXPECT_EQ(TrajectoryBranches(*pair), (std::vector<std::string>{""}));  // the baseline pair stays together
    Plot rising = SweepTrajectoriesFigure(*a, "rising");
    ASSERT_EQ(rising.series.size(), 4u);
    for (const Series& s : rising.series) EXPECT_THAT(s.label, HasSubstr("Ω = -")) << s.label;
    EXPECT_EQ(SweepTrajectoriesFigure(*a, "sinking").series.size(), 4u);
    EXPECT_EQ(SweepTrajectoriesFigure(*a).series.size(), 8u);
    auto r = client_->Get((sweep + "/trajectories.svg?branch=rising").c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 200) << r->body;
    r = client_->Get((sweep + "/trajectories.svg?branch=up").c_str());
    EXPECT_EQ(r->status, 400);
    EXPECT_EQ(json::parse(r->body)["field"], "branch");
  }
  json fits = json::parse(client_->Get((sweep + "/fits").c_str())->body);
  EXPECT_EQ(fits["kind"], "saturation");
  EXPECT_EQ(fits["finished_runs"], 8);
  EXPECT_TRUE(fits["branches"][0]["saturation"].contains("C1_stderr"));
  // The figures were written next to the results.
  EXPECT_TRUE(std::filesystem::exists(dir_ + "/data/figures"));

  const std::pair<std::string, int> bad[] = {
      {"/api/v1/runs/999/trajectory.svg", 404},
      {"/api/v1/sweeps/999/uz.png", 404},
      {"/api/v1/sweeps/999/trajectories.svg", 404},
      {"/api/v1/sweeps/999/fits", 404},
      {"/api/v1/campaign-runs/999/report", 404},
      {"/api/v1/campaigns/nothing/report", 404},
      {"/api/v1/campaigns/tiny/report?scale=huge", 400},
      {"/api/v1/sweeps/99999999999999999999999/fits", 400},
      {"/api/v1/runs/1/trajectory.gif", 404},
  };
  for (const auto& [path, status] : bad) {
    auto r = client_->Get(path.c_str());
    ASSERT_TRUE(r) << path;
    EXPECT_EQ(r->status, status) << path << ": " << r->body;
    EXPECT_EQ(r->get_header_value("Content-Type"), "application/problem+json") << path;
  }
}

TEST_F(ReportTest, NothingFinishedIsUnprocessableNotAnError) {
  StartServer();
  const std::string sweep = "/api/v1/sweeps/" + std::to_string(sweeps_[0]);
  for (const std::string& path : {sweep + "/uz.svg", sweep + "/trajectories.png"}) {
    auto r = client_->Get(path.c_str());
    ASSERT_TRUE(r);
    EXPECT_EQ(r->status, 422) << path;
    EXPECT_THAT(r->body, HasSubstr("no finished run"));
  }
  auto fits = client_->Get((sweep + "/fits").c_str());
  ASSERT_EQ(fits->status, 200);
  EXPECT_EQ(json::parse(fits->body)["finished_runs"], 0);
  auto report = client_->Get(("/api/v1/campaign-runs/" + std::to_string(campaign_run_) + "/report").c_str());
  EXPECT_EQ(report->status, 200);
  EXPECT_THAT(report->body, HasSubstr("nothing finished yet"));
}

// A campaign that states claims: the report's first section lists every claim with its verdict,
// the numbers behind it and the paper's, and GET /campaign-runs/{id}/claims answers the same
// verdicts (the fixture's runs follow eq. 8 with clear signs, four points a branch; its bed holds
// 3,700 grains).
TEST_F(ReportTest, TheReportOpensWithEveryClaimAndTheRouteAnswersTheirVerdicts) {
  StoredCampaign campaign;
  campaign.name = "tiny-claims";
  json definition = json::parse(kCampaign);
  definition["name"] = "tiny-claims";
  definition["claims"] = json::parse(R"([
    {"id": "F1", "title": "Omega < 0 rises, Omega > 0 sinks", "source": "Sec. 3.2, Fig. 4",
     "paper": {"text": "rose with negative Omega, sank with positive", "Omega_rad_s": [-80, 80]},
     "rule": {"kind": "sign", "sweeps": ["baseline", "omega"], "expect": "against_Omega"}},
    {"id": "F2", "title": "saturates", "source": "Fig. 6, eq. 8", "paper": {"text": "eq. 8 fits well"},
     "rule": {"kind": "saturation", "sweep": "omega", "reached_fraction": 0.5, "min_points": 4}},
    {"id": "F6", "title": "8e5 grains", "source": "Sec. 2.3", "paper": {"text": "a bed of 8*10^5 particles"},
     "rule": {"kind": "grain_count", "paper_grains": 800000, "paper_bed_m3": 0.5}}])");
  campaign.definition = definition;
  ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
  SubmitRequest request;
  request.campaign = "tiny-claims";
  auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  const int64_t id = *submitted->campaign_run_id;

  // Nothing finished: every claim is inconclusive, none decided from nothing.
  auto before = CheckClaims(*store_, id);
  ASSERT_TRUE(before.ok()) << before.status().ToString();
  ASSERT_EQ(before->verdicts.size(), 3u);
  for (const ClaimVerdict& v : before->verdicts) EXPECT_EQ(v.verdict, Verdict::kInconclusive) << v.claim.id;

  RunAll();
  FigureCache figures(dir_ + "/data/figures");
  auto html = CampaignReport(*store_, figures, id, clock_.Now());
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  const size_t claims_at = html->find("id=\"claims\"");
  ASSERT_NE(claims_at, std::string::npos);
  EXPECT_LT(claims_at, html->find("<nav>"));
  for (const char* claim : {"F1", "F2", "F6"}) {
    const size_t row = html->find(std::string("id=\"claim-") + claim + "\"");
    ASSERT_NE(row, std::string::npos) << claim;
    EXPECT_LT(row, html->find("id=\"fits\"")) << claim;
  }
  EXPECT_THAT(*html, HasSubstr("rose with negative Omega, sank with positive"));  // the paper's, beside
  EXPECT_THAT(*html, HasSubstr("C1 = "));

  StartServer();
  auto r = client_->Get(("/api/v1/campaign-runs/" + std::to_string(id) + "/claims").c_str());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  json reply = json::parse(r->body);
  EXPECT_EQ(reply["claims_source"], "stored");
  ASSERT_EQ(reply["claims"].size(), 3u);
  EXPECT_EQ(reply["claims"][0]["id"], "F1");
  EXPECT_EQ(reply["claims"][0]["verdict"], "holds") << reply["claims"][0]["reason"];
  // Each verdict names its scale.
  EXPECT_EQ(reply["claims"][0]["verdict_text"], "holds at " + reply["scale"].get<std::string>());
  // Four points a branch show growth, but a change of slope (the growth flattening) needs five:
  // too little to decide, never a verdict from it.
  EXPECT_EQ(reply["claims"][1]["verdict"], "inconclusive") << reply["claims"][1]["reason"];
  EXPECT_THAT(reply["claims"][1]["reason"].get<std::string>(), HasSubstr("needs 5"));
  EXPECT_EQ(reply["claims"][1]["parts"][0]["verdict"], "holds") << reply["claims"][1]["parts"][0]["reason"];
  EXPECT_EQ(reply["claims"][2]["verdict"], "differs") << reply["claims"][2]["reason"];
  EXPECT_EQ(reply["counts"]["holds"], 1);
  // A campaign of one's own has no calibration: its verdicts say so and how to calibrate, and
  // quote no other design's rates.
  EXPECT_EQ(reply["design"]["campaign"], "tiny-claims");
  for (const json& claim : reply["claims"]) {
    ASSERT_TRUE(claim.contains("rates")) << claim.dump();
    EXPECT_EQ(claim["rates"]["calibrated"], false);
    EXPECT_FALSE(claim["rates"].contains("power"));
    EXPECT_THAT(claim["rates"]["text"].get<std::string>(), HasSubstr("not calibrated at this design"));
    EXPECT_THAT(claim["rates"]["advice"].get<std::string>(), HasSubstr("bench_claims_calibration"));
    EXPECT_TRUE(claim["parts"][0].contains("rates"));
  }
  EXPECT_THAT(*html, HasSubstr("not calibrated at this design"));

  // A new version without claims changes nothing for this run: its claims are those of the
  // definition it recorded when it was submitted (before, the campaign's current ones).
  StoredCampaign edited = campaign;
  edited.definition.erase("claims");
  ASSERT_TRUE(PutCampaign(*store_, edited).ok());
  auto after_edit = CheckClaims(*store_, id);
  ASSERT_TRUE(after_edit.ok()) << after_edit.status().ToString();
  EXPECT_EQ(after_edit->claims_source, "stored");
  ASSERT_EQ(after_edit->verdicts.size(), 3u);
  EXPECT_EQ(after_edit->verdicts[0].verdict, Verdict::kHolds);

  // The fixture's campaign states none: an empty list.
  auto none = client_->Get(("/api/v1/campaign-runs/" + std::to_string(campaign_run_) + "/claims").c_str());
  ASSERT_EQ(none->status, 200);
  EXPECT_TRUE(json::parse(none->body)["claims"].empty());
  EXPECT_EQ(json::parse(none->body)["claims_source"], "none");
  EXPECT_EQ(client_->Get("/api/v1/campaign-runs/999/claims")->status, 404);
}

// An adaptive campaign run (the daemon's rounds, server/jobs/rounds.h) shows each claim as the
// look that decided it froze it -- in GET .../claims and in the report -- and an open claim as
// inconclusive until a look decides it. A frozen verdict that the current evaluation reads
// otherwise keeps the frozen one, says what the runs now read, and shows none of their numbers.
// Every verdict is quoted the adaptive procedure's rates, never a single-look table's.
TEST_F(ReportTest, AnAdaptiveRunShowsEachClaimAsItsDecidingLookFrozeIt) {
  StoredCampaign campaign;
  campaign.name = "tiny-rounds";
  json definition = json::parse(kCampaign);
  definition["name"] = "tiny-rounds";
  definition.erase("drift_tolerance_mps");
  definition["claims"] = json::parse(R"([
    {"id": "F1", "title": "Omega < 0 rises, Omega > 0 sinks", "source": "Sec. 3.2", "paper": {"text": "signs"},
     "rule": {"kind": "sign", "sweeps": ["baseline", "omega"], "expect": "against_Omega"}},
    {"id": "F2", "title": "saturates", "source": "Fig. 6", "paper": {"text": "eq. 8 fits well"},
     "rule": {"kind": "saturation", "sweep": "omega", "reached_fraction": 0.5, "min_points": 4}}])");
  definition["adaptive"] = {{"budget_core_h", 1000}};  // max_rounds: the default
  campaign.definition = definition;
  ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
  SubmitRequest request;
  request.campaign = "tiny-rounds";
  auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  const int64_t id = *submitted->campaign_run_id;
  RunAll();
  StartServer();
  const std::string path = "/api/v1/campaign-runs/" + std::to_string(id) + "/claims";

  // Round 1's runs are done, its look not taken: F1 reads holds, and is not decided yet.
  json reply = json::parse(client_->Get(path.c_str())->body);
  ASSERT_EQ(reply["claims"].size(), 2u);
  EXPECT_EQ(reply["claims"][0]["verdict"], "inconclusive") << reply["claims"][0].dump();
  EXPECT_EQ(reply["claims"][0]["current_verdict"], "holds");
  EXPECT_THAT(reply["claims"][0]["reason"].get<std::string>(),
              HasSubstr("reads holds with the runs so far; only the look after a round decides (the next look: "
                        "after round 1)"));
  EXPECT_EQ(reply["counts"]["holds"], 0);
  EXPECT_EQ(reply["counts"]["inconclusive"], 2);

  // The daemon's look after round 1: F1 is decided and frozen there, F2 (growth shown, its
  // flattening not: "needs 5") stays open; no action can add the points it needs, so the rounds stop.
  RoundDriverOptions options;
  options.engine_version = kReportEngine;
  RoundDriver driver(store_.get(), &LookAtClaims, options);
  auto step = driver.Step(id, clock_.Now());
  ASSERT_TRUE(step.ok()) << step.status().ToString();
  ASSERT_TRUE(step->has_value());
  auto frozen = rounds::FrozenVerdicts(*store_, id);
  ASSERT_TRUE(frozen.ok());
  ASSERT_EQ(frozen->count("F1"), 1u);
  ASSERT_EQ(frozen->count("F2"), 0u) << (*step)->text;
  EXPECT_EQ(frozen->at("F1").round, 1);

  auto r = client_->Get(path.c_str());
  ASSERT_TRUE(r);
  ASSERT_EQ(r->status, 200) << r->body;
  reply = json::parse(r->body);
  EXPECT_EQ(reply["adaptive"], true);
  EXPECT_THAT(reply["design_text"].get<std::string>(), HasSubstr("tiny-rounds at smoke, adaptive: in rounds (1 round so far), beds vary by point (1 bed a point so far)"));
  EXPECT_EQ(reply["design"]["adaptive"], true);
  ASSERT_EQ(reply["claims"].size(), 2u);
  const json& f1 = reply["claims"][0];
  EXPECT_EQ(f1["verdict"], "holds") << f1.dump();
  EXPECT_EQ(f1["current_verdict"], "holds");
  EXPECT_EQ(f1["frozen_at_round"], 1);
  EXPECT_TRUE(f1["frozen_at"].is_number());
  EXPECT_EQ(f1["verdict_text"], "holds at smoke (frozen at round 1)");
  // Agreeing with the look that froze it: the numbers behind it stay, said to be the current
  // evaluation's, not that look's.
  EXPECT_FALSE(f1["parts"].empty());
  EXPECT_THAT(f1["reason"].get<std::string>(),
              HasSubstr("holds since the look after round 1 (frozen there); what follows is the current evaluation "
                        "with round 1's runs, not the numbers of that look"));
  // The single-look tables are not its rates: the procedure's are bench_adaptive's, said so.
  for (const json& v : reply["claims"]) {
    EXPECT_EQ(v["rates"]["calibrated"], false) << v.dump();
    EXPECT_EQ(v["rates"]["text"], kAdaptiveRatesText);
    EXPECT_FALSE(v["rates"].contains("false_holds"));
    for (const json& p : v["parts"]) EXPECT_EQ(p["rates"]["text"], kAdaptiveRatesText) << p.dump();
  }
  const json& f2 = reply["claims"][1];
  EXPECT_EQ(f2["verdict"], "inconclusive");
  EXPECT_EQ(f2["current_verdict"], "inconclusive");
  EXPECT_TRUE(f2["frozen_at_round"].is_null());
  EXPECT_EQ(f2["verdict_text"], "inconclusive at smoke");
  EXPECT_THAT(f2["reason"].get<std::string>(), HasSubstr("needs 5"));  // the current evaluation

  // The same campaign's points submitted again (the fixture's campaign, forced) run the runs this
  // campaign run shares with it again, and Omega = 80's fail this time: F1 with every run now reads
  // inconclusive, which does not undo the verdict its deciding look froze.
  SubmitRequest again;
  again.campaign = "tiny";
  again.force = true;
  auto resubmitted = Submit(*store_, again, kReportEngine, clock_.Now());
  ASSERT_TRUE(resubmitted.ok()) << resubmitted.status().ToString();
  ASSERT_GT(resubmitted->runs_requeued, 0);
  fail_omega_ = 80;
  RunAll();
  reply = json::parse(client_->Get(path.c_str())->body);
  const json& f1_now = reply["claims"][0];
  EXPECT_EQ(f1_now["verdict"], "holds") << f1_now.dump();
  EXPECT_EQ(f1_now["current_verdict"], "inconclusive");
  EXPECT_EQ(f1_now["verdict_text"], "holds at smoke (frozen at round 1)");
  EXPECT_THAT(f1_now["reason"].get<std::string>(),
              HasSubstr("decided (holds) at the look after round 1 and frozen there; with round 1's runs it now "
                        "reads inconclusive, which does not count (frozen)"));
  EXPECT_THAT(f1_now["reason"].get<std::string>(), ::testing::Not(HasSubstr("deck_error")));
  EXPECT_TRUE(f1_now["parts"].empty());
  EXPECT_TRUE(f1_now["missing"].empty());
  EXPECT_EQ(f1_now["rates"]["text"], kAdaptiveRatesText);
  EXPECT_EQ(reply["counts"]["holds"], 1);
  EXPECT_EQ(reply["counts"]["differs"], 0);
  EXPECT_EQ(reply["counts"]["inconclusive"], 1);

  // The report says the same.
  FigureCache figures(dir_ + "/data/figures");
  auto html = CampaignReport(*store_, figures, id, clock_.Now());
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  const size_t f1_row = html->find("id=\"claim-F1\""), f2_row = html->find("id=\"claim-F2\"");
  ASSERT_NE(f1_row, std::string::npos);
  ASSERT_NE(f2_row, std::string::npos);
  const std::string f1_html = html->substr(f1_row, f2_row - f1_row);
  const std::string f2_html = html->substr(f2_row, html->find("</tr>", f2_row) - f2_row);
  const std::string frozen_1 = " at smoke <small class=\"frozen\">(frozen at round 1)";
  EXPECT_THAT(f1_html, HasSubstr("<span class=\"holds\">holds</span>" + frozen_1));
  EXPECT_THAT(f1_html, HasSubstr("it now reads inconclusive, which does not count (frozen)"));
  EXPECT_THAT(f1_html, HasSubstr("not the single-look tables"));
  EXPECT_THAT(f2_html, HasSubstr("<span class=\"inconclusive\">inconclusive</span> at smoke<"));
  EXPECT_THAT(f2_html, HasSubstr("needs 5"));
  EXPECT_THAT(*html, HasSubstr("This campaign ran in rounds"));
  EXPECT_THAT(*html, ::testing::Not(HasSubstr("(the rounds: below)")));
  // Its rounds follow the claims, one row a round as GET /api/v1/campaign-runs/{id} has them.
  const std::string run_path = "/api/v1/campaign-runs/" + std::to_string(id);
  const json run = json::parse(client_->Get(run_path.c_str())->body);
  EXPECT_EQ(run["adaptive"]["max_rounds"], AdaptiveSettings().max_rounds);  // the default, served
  const json rounds = run["rounds"];
  ASSERT_EQ(rounds.size(), 1u);
  const size_t section = html->find("<h2 id=\"rounds\">");
  ASSERT_NE(section, std::string::npos);
  EXPECT_LT(f2_row, section);
  EXPECT_LT(section, html->find("<nav>"));
  EXPECT_THAT(*html, HasSubstr("<a href=\"#rounds\">Rounds</a>"));
  EXPECT_THAT(*html, HasSubstr("at most " + std::to_string(AdaptiveSettings().max_rounds) + " rounds."));
  for (const json& r : rounds) {
    const std::string id_attr = "<tr id=\"round-" + std::to_string(r["round"].get<int>()) + "\">";
    const size_t at = html->find(id_attr);
    ASSERT_NE(at, std::string::npos) << id_attr;
    const std::string row = html->substr(at, html->find("</tr>", at) - at);
    EXPECT_THAT(row, HasSubstr(Num(r["core_h_planned"].get<double>(), 3)));
    EXPECT_EQ(row.find("<li>") == std::string::npos, r["actions"].empty()) << row;
  }
  const std::string first = html->substr(html->find("<tr id=\"round-1\">"));
  EXPECT_THAT(first.substr(0, first.find("</tr>")), HasSubstr("every declared point once"));
  // After round 1's look, F1 frozen there, F2 open; no action could decide F2, so they stopped.
  EXPECT_THAT(first.substr(0, first.find("</tr>")), HasSubstr("F1 holds (frozen at round 1)"));
  EXPECT_THAT(first.substr(0, first.find("</tr>")), HasSubstr("F2 inconclusive"));
  ASSERT_TRUE(rounds.back()["stop_reason"].is_string()) << rounds.dump();
  EXPECT_THAT(*html, HasSubstr("<p id=\"rounds-stop\"><b>Stopped after round 1:</b> "));

  // Rounds that cannot be read cost their section (and the claims, which read them), never the report.
  ASSERT_TRUE(store_->db()
                  .Write([](Transaction& t) { return t.Exec("ALTER TABLE campaign_rounds RENAME TO campaign_rounds_gone"); })
                  .ok());
  auto broken = CampaignReport(*store_, figures, id, clock_.Now());
  ASSERT_TRUE(broken.ok()) << broken.status().ToString();
  const size_t gone = broken->find("<h2 id=\"rounds\">");
  ASSERT_NE(gone, std::string::npos);
  EXPECT_THAT(broken->substr(gone, 300), HasSubstr("the rounds could not be read"));
  EXPECT_THAT(broken->substr(0, broken->find("<h2")), HasSubstr("the rounds could not be read"));  // the problems
  ASSERT_TRUE(store_->db()
                  .Write([](Transaction& t) { return t.Exec("ALTER TABLE campaign_rounds_gone RENAME TO campaign_rounds"); })
                  .ok());

  // A fixed-design run is unchanged: its current verdicts, no frozen fields.
  auto fixed = client_->Get(("/api/v1/campaign-runs/" + std::to_string(campaign_run_) + "/claims").c_str());
  ASSERT_EQ(fixed->status, 200);
  EXPECT_EQ(json::parse(fixed->body)["adaptive"], false);
  auto fixed_html = CampaignReport(*store_, figures, campaign_run_, clock_.Now());
  ASSERT_TRUE(fixed_html.ok());
  EXPECT_EQ(fixed_html->find("id=\"rounds\""), std::string::npos);
}

// paper-58 recorded in the store before its file stated claims: the built-in file's claims, said so.
TEST_F(ReportTest, AStoredBuiltinCampaignWithoutClaimsTakesTheBuiltinOnes) {
  auto builtin = BuiltinCampaignDefinition("paper-58");
  ASSERT_TRUE(builtin.ok());
  StoredCampaign campaign;
  campaign.name = "paper-58";
  campaign.definition = *builtin;
  campaign.definition.erase("claims");
  ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
  SubmitRequest request;
  request.campaign = "paper-58";
  request.scale = "smoke";
  auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  auto claims = CheckClaims(*store_, *submitted->campaign_run_id);
  ASSERT_TRUE(claims.ok()) << claims.status().ToString();
  EXPECT_EQ(claims->claims_source, "builtin");
  EXPECT_THAT(claims->note, HasSubstr("predates claims"));
  ASSERT_EQ(claims->verdicts.size(), 6u);
  for (const ClaimVerdict& v : claims->verdicts) EXPECT_EQ(v.verdict, Verdict::kInconclusive) << v.claim.id;
}

// Drive modes: a one-point sweep has no U_z figure (its points share one value of what it would be
// plotted against), and the report draws every mode's Δx(t) and Δz(t) side by side (Fig. 2).
TEST_F(ReportTest, ModesAreDrawnSideBySideAndAOnePointSweepHasNoUzFigure) {
  StoredCampaign campaign;
  campaign.name = "modes";
  campaign.definition =
      json::parse(R"({"name": "modes", "description": "modes and a pair", "scale": "smoke", "sweeps": [
    {"name": "modes.vibration", "base": {"mode": "vibration", "A": 0.03, "f": 3, "duration_s": 0.3}},
    {"name": "modes.rotation-x", "base": {"mode": "rotation", "omega": 80, "axis": "x", "duration_s": 0.3}},
    {"name": "baseline", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3},
     "axes": [{"param": "Omega", "values": [-80, 80]}]}]})");
  ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
  SubmitRequest request;
  request.campaign = "modes";
  auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  RunAll();

  std::vector<SweepAnalysis> analyses;
  for (int64_t id : submitted->sweep_ids) {
    auto a = AnalyzeSweep(*store_, id);
    ASSERT_TRUE(a.ok());
    analyses.push_back(*a);
  }
  EXPECT_THAT(NoUzToPlot(analyses[0]), HasSubstr("share one value"));
  EXPECT_THAT(NoUzToPlot(analyses[1]), HasSubstr("share one value"));
  EXPECT_EQ(NoUzToPlot(analyses[2]), "");  // the baseline pair: two values of Omega
  auto cr = store_->GetCampaignRun(*submitted->campaign_run_id);
  ASSERT_TRUE(cr.ok());
  auto modes = ModesFigure(*cr, analyses, Coordinate::kZ);
  ASSERT_TRUE(modes.has_value());
  ASSERT_EQ(modes->series.size(), 2u);  // the two modes, not the oscillatory pair
  EXPECT_THAT(modes->series[0].label, HasSubstr("vibration"));
  EXPECT_THAT(modes->series[1].label, HasSubstr("rotation"));
  EXPECT_FALSE(ModesFigure(*store_->GetCampaignRun(campaign_run_), {}, Coordinate::kX).has_value());

  FigureCache figures(dir_ + "/data/figures");
  auto html = CampaignReport(*store_, figures, *submitted->campaign_run_id, clock_.Now());
  ASSERT_TRUE(html.ok()) << html.status().ToString();
  for (const char* id : {"id=\"modes\"", "fig-modes-x", "fig-modes-z", "href=\"#modes\""})
    EXPECT_THAT(*html, HasSubstr(id));
  // The modes' figure draws two series: the first two colours, not a third.
  const size_t at = html->find("fig-modes-z");
  const std::string svg = html->substr(at, html->find("</svg>", at) - at);
  EXPECT_THAT(svg, HasSubstr(SeriesColor(0)));
  EXPECT_THAT(svg, HasSubstr(SeriesColor(1)));
  EXPECT_THAT(svg, ::testing::Not(HasSubstr(SeriesColor(2))));
  EXPECT_THAT(*html, HasSubstr("share one value of Omega"));
  // The one-point sweep's U_z route says why there is no figure.
  StartServer();
  auto uz = client_->Get(("/api/v1/sweeps/" + std::to_string(submitted->sweep_ids[0]) + "/uz.svg").c_str());
  EXPECT_EQ(uz->status, 422);
  EXPECT_THAT(uz->body, HasSubstr("share one value"));
}

// New results are never answered with an older figure.
TEST_F(ReportTest, AFigureFollowsNewResults) {
  RunAll(3);
  StartServer();
  const std::string path = "/api/v1/sweeps/" + std::to_string(sweeps_[0]) + "/uz.svg";
  auto first = client_->Get(path.c_str());
  ASSERT_EQ(first->status, 200);
  EXPECT_EQ(client_->Get(path.c_str())->body, first->body);
  RunAll(1);
  auto second = client_->Get(path.c_str());
  ASSERT_EQ(second->status, 200);
  EXPECT_NE(second->body, first->body);
}

// ClaimsCache (server/analysis/claims_cache.h): a campaign run's verdicts are evaluated once while
// nothing is written, and again after any write, so a result of its runs is in the next answer.
TEST_F(ReportTest, ClaimsCacheKeepsAnAnswerUntilAWriteAndShowsEveryResult) {
  StoredCampaign campaign;
  campaign.name = "cached-claims";
  json definition = json::parse(kCampaign);
  definition["name"] = "cached-claims";
  definition["claims"] = json::parse(R"([
    {"id": "F1", "title": "Omega < 0 rises, Omega > 0 sinks", "source": "Sec. 3.2, Fig. 4",
     "paper": {"text": "rose with negative Omega, sank with positive"},
     "rule": {"kind": "sign", "sweeps": ["baseline", "omega"], "expect": "against_Omega"}}])");
  campaign.definition = definition;
  ASSERT_TRUE(PutCampaign(*store_, campaign).ok());
  SubmitRequest request;
  request.campaign = "cached-claims";
  auto submitted = Submit(*store_, request, kReportEngine, clock_.Now());
  ASSERT_TRUE(submitted.ok()) << submitted.status().ToString();
  const int64_t id = *submitted->campaign_run_id;
  auto direct = [&] {
    auto claims = CheckClaims(*store_, id);
    EXPECT_TRUE(claims.ok()) << claims.status().ToString();
    return claims.ok() ? CampaignRunClaimsToJson(*claims) : json();
  };

  ClaimsCache cache(store_.get());
  auto first = cache.Get(id);
  ASSERT_TRUE(first.ok()) << first.status().ToString();
  EXPECT_EQ((*first)->verdicts.at(0).verdict, Verdict::kInconclusive);  // nothing run yet
  auto again = cache.Get(id);
  ASSERT_TRUE(again.ok());
  EXPECT_EQ(again->get(), first->get());  // the same answer, not evaluated again
  EXPECT_EQ(cache.evaluations(), 1u);

  // Each completion is a write: after every one, the cache answers what an evaluation answers.
  for (int step = 0; step < 40; ++step) {
    RunAll(1);
    auto now = cache.Get(id);
    ASSERT_TRUE(now.ok()) << now.status().ToString();
    ASSERT_EQ(CampaignRunClaimsToJson(**now), direct()) << "after completion " << step;
  }
  RunAll();
  auto done = cache.Get(id);
  ASSERT_TRUE(done.ok());
  EXPECT_EQ((*done)->verdicts.at(0).verdict, Verdict::kHolds) << (*done)->verdicts.at(0).reason;
  const uint64_t evaluations = cache.evaluations();
  EXPECT_EQ(cache.Get(id)->get(), done->get());
  EXPECT_EQ(cache.evaluations(), evaluations);

  // An unknown campaign run: NotFound, and not kept.
  EXPECT_EQ(cache.Get(id + 1000).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(cache.Get(id + 1000).status().code(), StatusCode::kNotFound);
  EXPECT_EQ(cache.evaluations(), evaluations + 2);
}

}  // namespace
}  // namespace sandswim
