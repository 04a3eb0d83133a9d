// bench_precision_coverage: whether a run ended by its precision target keeps its 95 % interval's
// coverage (core/precision.h), on synthetic trajectories with a known drift.
//
//   bench_precision_coverage [--seeds N] [--model correlated|independent]
//
// Each trajectory (tests/synthetic_trajectory.h: harmonics at f, 2f, 3f and a wandering term, so
// that each period's advance varies as in real runs) is followed as the worker follows a run: the
// growing trajectory is analysed every 10 ms of simulated time (workers/job_outcome.h FollowRun)
// until the rule says stop or the run reaches its maximum duration; the run is then analysed as
// the worker analyses a finished one (core/trajectory.h AnalyzeRun, with the engine's stop marker).
// Printed per case (per-period scatter of the block rates relative to the drift, target uz_rel):
// how often the stated 95 % interval holds the true drift, over all runs and over the runs that
// stopped for their target; the share that stopped early; the mean number of whole periods used;
// and how often the stated standard error, used as a fit weight, is at least the true spread
// (the ratio of the actual rms error to the rms stated error among the stopped runs).
// A program to run on demand: it asserts nothing.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "core/engine_log.h"
#include "core/precision.h"
#include "core/trajectory.h"
#include "tests/synthetic_trajectory.h"
#include "workers/job_outcome.h"

namespace sandswim {
namespace {

struct Tally {
  int runs = 0, covered = 0, stopped = 0, stopped_covered = 0, no_interval = 0;
  double blocks = 0;
  double stopped_sq_err = 0, stopped_sq_se = 0;
};

// Follows one run to its end and judges its final interval.
void FollowOne(const std::vector<SoSample>& all, double truth, const DriveInfo& drive, const PrecisionTarget& target,
               Tally* tally) {
  DriveStartMarker start;
  start.surface = 100;  // far away: the window never closes at a boundary here
  size_t n = 0;
  const size_t step = 10;  // samples (10 ms) between looks, as the worker's heartbeats look
  std::string reason = "duration";
  for (n = std::min<size_t>(step, all.size()); n < all.size(); n += step) {
    std::vector<SoSample> prefix(all.begin(), all.begin() + n);
    if (worker::FollowRun(prefix, drive, start, target) != StopVerdict::kContinue) {
      reason = "target";
      break;
    }
  }
  n = std::min(n, all.size());
  std::vector<SoSample> used(all.begin(), all.begin() + n);
  EngineLog log;
  log.drive_start = start;
  DriveStopMarker stop;
  stop.reason = reason;
  stop.step = used.back().step;
  stop.t = used.back().t;
  stop.z = used.back().z;
  log.drive_stop = stop;
  auto r = AnalyzeRun(used, RunInputsFrom(drive, log, target));
  ++tally->runs;
  if (!r.ok() || !r->uz || !r->uz_ci95 || !r->uz_stderr) {
    ++tally->no_interval;
    return;
  }
  const bool covered = std::fabs(*r->uz - truth) <= *r->uz_ci95;
  tally->covered += covered;
  tally->blocks += r->uz_blocks;
  if (reason == "target") {
    ++tally->stopped;
    tally->stopped_covered += covered;
    tally->stopped_sq_err += (*r->uz - truth) * (*r->uz - truth);
    tally->stopped_sq_se += *r->uz_stderr * *r->uz_stderr;
  }
}

}  // namespace
}  // namespace sandswim

int main(int argc, char** argv) {
  using namespace sandswim;
  int seeds = 2000;
  bool independent = false;  // --model independent: block rates independent of each other
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--seeds") == 0 && i + 1 < argc) seeds = std::atoi(argv[++i]);
    if (std::strcmp(argv[i], "--model") == 0 && i + 1 < argc) independent = std::strcmp(argv[++i], "independent") == 0;
  }

  const double f = 3, drift = 0.05, max_duration = 4;  // 12 periods: the transient and 11 blocks
  DriveInfo drive;
  drive.dt = 1e-5;
  drive.f = f;
  std::printf("precision-target stops, f = %g Hz, drift %g m/s, at most %g s, looks every 10 ms, %d seeds a case, "
              "%s block rates\n",
              f, drift, max_duration, seeds,
              independent ? "independent (white velocity noise)" : "correlated (velocity noise with 0.1 s memory)");
  std::printf("| per-period sd / U | uz_rel | coverage (all) | coverage (stopped) | stopped | periods | rms err / rms se (stopped) |\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  // v_noise_sd sets the wandering term's size; the per-period scatter it gives is measured below.
  // The velocity noise's size; the per-period scatter it gives is measured below. White noise
  // (phi = 0) makes the blocks' rates independent; phi = 0.99 a sample (0.1 s) correlates neighbours.
  const double phi = independent ? 0.0 : 0.99;
  for (double v_sd : independent ? std::vector<double>{0.18, 0.35} : std::vector<double>{0.015, 0.03}) {
    testing::SyntheticSo so;
    so.drift = drift;
    so.f = f;
    so.duration = max_duration;
    so.v_noise_sd = v_sd;
    so.v_noise_phi = phi;
    // The realised per-period scatter of the block rates, relative to the drift.
    double sum_sd = 0;
    const int probe = 200;
    for (int s = 0; s < probe; ++s) {
      auto samples = testing::MakeSyntheticSo(so, 900000 + s);
      const int blocks = static_cast<int>(std::floor((max_duration - 1 / f) * f + 1e-9));
      BlockRate b = MeanBlockRate(samples, 1 / f, 1 / f, blocks);
      sum_sd += *b.se * std::sqrt(static_cast<double>(blocks));
    }
    const double rel_sd = sum_sd / probe / drift;
    for (double rel : {0.1, 0.25, 0.5}) {
      PrecisionTarget target;
      target.uz_rel = rel;
      target.uz_abs = 0;
      target.min_periods = kMinPrecisionPeriods;
      target.max_duration_s = max_duration;
      Tally t;
      for (int s = 0; s < seeds; ++s) FollowOne(testing::MakeSyntheticSo(so, 1000 + s), drift, drive, target, &t);
      const int with = t.runs - t.no_interval;
      std::printf("| %.2f | %.2f | %.1f %% | %.1f %% (n = %d) | %.1f %% | %.1f | %.2f |\n", rel_sd, rel,
                  100.0 * t.covered / std::max(with, 1), 100.0 * t.stopped_covered / std::max(t.stopped, 1),
                  t.stopped, 100.0 * t.stopped / std::max(t.runs, 1), t.blocks / std::max(with, 1),
                  t.stopped ? std::sqrt(t.stopped_sq_err / t.stopped_sq_se) : 0.0);
    }
  }
  return 0;
}
