// Routes of figures (SVG or PNG by extension), fits, reports (server/analysis/report.h) and the
// bed snapshots runs hand in (core/snapshot.h; the paper's Fig. 5).
#include "server/http/call.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <algorithm>
#include <atomic>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <set>
#include <sstream>
#include <utility>
#include <httplib.h>
#include <openssl/crypto.h>
#include <spdlog/spdlog.h>
#include "core/branch.h"
#include "core/aggregate.h"
#include "core/result_table.h"
#include "core/snapshot.h"
#include "core/sweep.h"
#include "core/text.h"
#include "core/trajectory.h"
#include "platform/data_dir.h"
#include "platform/http_status.h"
#include "server/store/campaigns.h"
#include "server/store/cost_model.h"
#include "server/analysis/claim_check.h"
#include "server/analysis/drift_report.h"
#include "server/dashboard/dashboard_files.h"
#include "server/analysis/figures.h"
#include "server/http/guarded_http_server.h"
#include "server/http/routes.h"
#include "server/dashboard/live_feed.h"
#include "server/analysis/report.h"
#include "server/store/schema_files.h"
#include "server/jobs/submission.h"
#include "server/http/result_rows.h"

namespace sandswim {
namespace routes {
namespace {

// ---- Figures, fits and reports (server/analysis/figures.h, server/analysis/report.h) ----------------------------

// Figures live next to the results, keyed by their data (FigureCache): never stale.
FigureCache FiguresOf(const Deps& deps) {
  return FigureCache(DataDir(deps.data_dir).Figures(), deps.renderer);
}

// The HTML report and SVG figures are documents of their own, made by the daemon: inline styles
// (the report's <style>, PLplot's style attributes) and inline images, but no script at all.
constexpr const char* kDocumentCsp =
    "default-src 'none'; style-src 'unsafe-inline'; img-src 'self' data:; frame-ancestors 'none'";

void SendFigure(Call& c, const std::string& name, const Plot& plot, ImageFormat format) {
  auto bytes = FiguresOf(c.deps).Get(name, plot, format);
  if (!bytes.ok()) return Fail(c, bytes.status());
  c.res.status = 200;
  c.res.set_header("Content-Security-Policy", kDocumentCsp);
  c.res.set_content(*bytes, ImageContentType(format));
}

template <ImageFormat kFormat>
void GetRunFigure(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto plot = RunFigure(*c.deps.store, *id);
  if (!plot.ok()) return Fail(c, plot.status());
  SendFigure(c, RunFigureName(*id), *plot, kFormat);
}

Result<SweepAnalysis> FinishedSweep(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return id.status();
  auto analysis = AnalyzeSweep(*c.deps.store, *id);
  if (!analysis.ok()) return analysis.status();
  if (analysis->samples.empty()) {
    return Status::FailedPrecondition("id",
                                      "sweep " + std::to_string(*id) + " has no finished run yet: nothing to plot");
  }
  return analysis;
}

template <ImageFormat kFormat>
void GetSweepTrajectoriesFigure(Call& c) {
  auto a = FinishedSweep(c);
  if (!a.ok()) return Fail(c, a.status());
  if (a->runs.empty())
    return Fail(c, Status::FailedPrecondition("id", "no finished run of this sweep has a trajectory"));
  // ?branch=rising|sinking: the runs of one branch (the paper's panels a and b).
  const std::string branch = c.req.has_param("branch") ? c.req.get_param_value("branch") : "";
  if (c.req.has_param("branch") && !ParseBranch(branch))
    return Fail(c, Status::InvalidArgument("branch", "must be rising (Omega < 0) or sinking (Omega > 0)"));
  Plot plot = SweepTrajectoriesFigure(*a, branch);
  if (plot.series.empty()) {
    return Fail(c, Status::FailedPrecondition("branch", "no finished run of the " + branch + " branch of sweep " +
                                                            std::to_string(a->info.id) + " has a trajectory"));
  }
  SendFigure(c, SweepTrajectoriesName(a->info.id, branch), plot, kFormat);
}

// The drive modes side by side (the paper's Fig. 2): ?coordinate=z (default) or x.
template <ImageFormat kFormat>
void GetCampaignRunModesFigure(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  const std::string coordinate = c.req.has_param("coordinate") ? c.req.get_param_value("coordinate") : "z";
  if (coordinate != "x" && coordinate != "z")
    return Fail(c, Status::InvalidArgument("coordinate", "must be x or z (the SO's displacement drawn against t)"));
  auto cr = c.deps.store->GetCampaignRun(*id);
  if (!cr.ok()) return Fail(c, cr.status());
  auto analyses = AnalyzeCampaignRun(*c.deps.store, *cr);
  if (!analyses.ok()) return Fail(c, analyses.status());
  std::optional<Plot> modes = ModesFigure(*cr, *analyses, coordinate == "x" ? Coordinate::kX : Coordinate::kZ);
  if (!modes) {
    return Fail(c, Status::FailedPrecondition("id", "campaign run " + std::to_string(*id) +
                                                        " has no finished run of a drive other than the oscillatory "
                                                        "one (vibration, rotation or both) yet"));
  }
  SendFigure(c, ModesFigureName(*id, coordinate == "x" ? Coordinate::kX : Coordinate::kZ), *modes, kFormat);
}

template <ImageFormat kFormat>
void GetSweepUzFigure(Call& c) {
  auto a = FinishedSweep(c);
  if (!a.ok()) return Fail(c, a.status());
  if (std::string why = NoUzToPlot(*a); !why.empty()) {
    return Fail(c, Status::FailedPrecondition("id", "sweep " + std::to_string(a->info.id) + ": " + why));
  }
  SendFigure(c, SweepUzName(a->info.id), SweepUzFigure(*a), kFormat);
}

void GetSweepFits(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  auto a = AnalyzeSweep(*c.deps.store, *id);
  if (!a.ok()) return Fail(c, a.status());
  json reply = a->fits;
  reply["sweep_id"] = *id;
  reply["finished_runs"] = a->samples.size();
  SendJson(c, 200, reply);
}

void SendReport(Call& c, int64_t campaign_run_id) {
  FigureCache figures = FiguresOf(c.deps);
  auto html = CampaignReport(*c.deps.store, figures, campaign_run_id, c.deps.clock->Now(), c.deps.data_dir);
  if (!html.ok()) return Fail(c, html.status());
  c.res.status = 200;
  c.res.set_header("Content-Security-Policy", kDocumentCsp);
  c.res.set_content(*html, "text/html; charset=utf-8");
}

void GetCampaignRunReport(Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return Fail(c, id.status());
  SendReport(c, *id);
}

// The report of a campaign's latest run (?scale= narrows it to one scale).
void GetCampaignReport(Call& c) {
  const std::string name = c.req.matches[1].str();
  const std::string scale = c.req.has_param("scale") ? c.req.get_param_value("scale") : "";
  if (c.req.has_param("scale") && FindScale(scale) == nullptr) {
    return Fail(c, Status::InvalidArgument("scale", "unknown scale \"" + scale + "\" (paper, mini, smoke)"));
  }
  auto runs = c.deps.store->ListCampaignRuns(name, 1000);
  if (!runs.ok()) return Fail(c, runs.status());
  for (const CampaignRunInfo& run : *runs) {
    if (scale.empty() || run.scale == scale) return SendReport(c, run.id);
  }
  return Fail(c, Status::NotFound("no run of campaign '" + name + "'" + (scale.empty() ? "" : " at scale " + scale) +
                                  " yet: submit it first (sandswim submit " + name + ")"));
}

// ---- Snapshots of the bed (core/snapshot.h; the paper's Fig. 5) --------------------------------

struct FoundSnapshot {
  int64_t run_id = 0;
  Point point;
  api::Snapshot meta;
  std::string path;
};

// The run's snapshot named by the path ({id}, {n}); NotFound saying which it has.
Result<FoundSnapshot> FindSnapshot(const Call& c) {
  auto id = PathId(c);
  if (!id.ok()) return id.status();
  auto n = ParseInt(c.req.matches[2].str(), "n", 0, 1000);
  if (!n.ok()) return n.status();
  auto run = c.deps.store->GetRun(*id, Store::Deck::kLeftOut);
  if (!run.ok()) return run.status();
  const std::vector<api::Snapshot>& snapshots = run->snapshots;
  for (const api::Snapshot& s : snapshots) {
    if (s.idx == *n) return FoundSnapshot{*id, run->summary.point, s, DataDir(c.deps.data_dir).Snapshot(*id, s.idx)};
  }
  return Status::NotFound("run " + std::to_string(*id) + " has no snapshot " + std::to_string(*n) + " (it has " +
                          std::to_string(snapshots.size()) +
                          "; a run takes snapshots when its sweep asks for them: \"snapshots\": [0, 0.5, 1])");
}

// The snapshot as the engine wrote it (dump custom: id type x y z vx vy vz radius).
void GetSnapshotDump(Call& c) {
  auto found = FindSnapshot(c);
  if (!found.ok()) return Fail(c, found.status());
  auto file = std::make_shared<std::ifstream>(found->path, std::ios::binary);
  std::error_code ec;
  auto size = std::filesystem::file_size(found->path, ec);
  if (!*file || ec) return Fail(c, Status::IOError("snapshot file " + found->path + " is missing"));
  c.res.status = 200;
  c.res.set_header("Content-Disposition", "attachment; filename=\"run-" + std::to_string(found->run_id) +
                                              "-snapshot-" + std::to_string(found->meta.idx) + ".dump\"");
  SendFile(c, file, static_cast<size_t>(size), "text/plain; charset=utf-8");
}

// The snapshot as a legacy VTK file, which ParaView opens directly.
void GetSnapshotVtk(Call& c) {
  auto found = FindSnapshot(c);
  if (!found.ok()) return Fail(c, found.status());
  auto snapshot = ReadStoredSnapshot(c.deps.data_dir, found->run_id, found->meta.idx);
  if (!snapshot.ok()) return Fail(c, snapshot.status());
  const std::string title = "sandswim run " + std::to_string(found->run_id) + " snapshot " +
                            std::to_string(found->meta.idx) + " t = " + Num(found->meta.t_s, 4) + " s";
  c.res.status = 200;
  c.res.set_header("Content-Disposition", "attachment; filename=\"run-" + std::to_string(found->run_id) +
                                              "-snapshot-" + std::to_string(found->meta.idx) + ".vtk\"");
  c.res.set_content(BedSnapshotVtk(*snapshot, title), "application/octet-stream");
}

// The y-z slice through the SO (server/analysis/figures.h SnapshotSlicePlot).
template <ImageFormat kFormat>
void GetSnapshotSlice(Call& c) {
  auto found = FindSnapshot(c);
  if (!found.ok()) return Fail(c, found.status());
  auto snapshot = ReadStoredSnapshot(c.deps.data_dir, found->run_id, found->meta.idx);
  if (!snapshot.ok()) return Fail(c, snapshot.status());
  const Plot plot = SnapshotSlicePlot(found->run_id, found->point, found->meta, SliceThroughSo(*snapshot));
  SendFigure(c, "run-" + std::to_string(found->run_id) + "-snapshot-" + std::to_string(found->meta.idx) + "-slice",
             plot, kFormat);
}

}  // namespace

const std::vector<Route>& FiguresRoutes() {
  // clang-format off: one route a line, in columns, as the table in routes.cc reads.
  static const std::vector<Route> kTable = {
    // method  path                                   access            body                handler
    {"GET",  "/api/v1/runs/{id}/snapshots/{n}.dump",  Access::kRead,   BodyKind::kNone,    GetSnapshotDump},
    {"GET",  "/api/v1/runs/{id}/snapshots/{n}.vtk",   Access::kRead,   BodyKind::kNone,    GetSnapshotVtk},
    {"GET",  "/api/v1/runs/{id}/snapshots/{n}/slice.svg", Access::kRead, BodyKind::kNone,  GetSnapshotSlice<ImageFormat::kSvg>},
    {"GET",  "/api/v1/runs/{id}/snapshots/{n}/slice.png", Access::kRead, BodyKind::kNone,  GetSnapshotSlice<ImageFormat::kPng>},
    {"GET",  "/api/v1/runs/{id}/trajectory.svg",      Access::kRead,   BodyKind::kNone,    GetRunFigure<ImageFormat::kSvg>},
    {"GET",  "/api/v1/runs/{id}/trajectory.png",      Access::kRead,   BodyKind::kNone,    GetRunFigure<ImageFormat::kPng>},
    {"GET",  "/api/v1/sweeps/{id}/trajectories.svg",  Access::kRead,   BodyKind::kNone,    GetSweepTrajectoriesFigure<ImageFormat::kSvg>},
    {"GET",  "/api/v1/sweeps/{id}/trajectories.png",  Access::kRead,   BodyKind::kNone,    GetSweepTrajectoriesFigure<ImageFormat::kPng>},
    {"GET",  "/api/v1/sweeps/{id}/uz.svg",            Access::kRead,   BodyKind::kNone,    GetSweepUzFigure<ImageFormat::kSvg>},
    {"GET",  "/api/v1/sweeps/{id}/uz.png",            Access::kRead,   BodyKind::kNone,    GetSweepUzFigure<ImageFormat::kPng>},
    {"GET",  "/api/v1/sweeps/{id}/fits",              Access::kRead,   BodyKind::kNone,    GetSweepFits},
    {"GET",  "/api/v1/campaign-runs/{id}/modes.svg",  Access::kRead,   BodyKind::kNone,    GetCampaignRunModesFigure<ImageFormat::kSvg>},
    {"GET",  "/api/v1/campaign-runs/{id}/modes.png",  Access::kRead,   BodyKind::kNone,    GetCampaignRunModesFigure<ImageFormat::kPng>},
    {"GET",  "/api/v1/campaign-runs/{id}/report",     Access::kRead,   BodyKind::kNone,    GetCampaignRunReport},
    {"GET",  "/api/v1/campaigns/{name}/report",       Access::kRead,   BodyKind::kNone,    GetCampaignReport},
  };
  // clang-format on
  return kTable;
}

}  // namespace routes

}  // namespace sandswim
