#include "core/trajectory.h"
#include "core/text.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>

#include <gsl/gsl_cdf.h>

namespace sandswim {
namespace {

constexpr double kPi = 3.14159265358979323846;

bool ToDouble(std::string_view tok, double* out) {
  tok = Trim(tok);
  if (tok.empty()) return false;
  auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), *out);
  return ec == std::errc() && p == tok.data() + tok.size() && std::isfinite(*out);
}

// Value after `prefix` on the first line that starts with it, e.g. "variable f equal ".
std::optional<double> LineValue(std::string_view deck, std::string_view prefix) {
  size_t pos = 0;
  while (pos < deck.size()) {
    size_t nl = deck.find('\n', pos);
    std::string_view line = deck.substr(pos, nl == std::string_view::npos ? std::string_view::npos : nl - pos);
    pos = nl == std::string_view::npos ? deck.size() : nl + 1;
    if (line.substr(0, prefix.size()) == prefix) {
      double v;
      if (ToDouble(line.substr(prefix.size()), &v)) return v;
      return std::nullopt;
    }
  }
  return std::nullopt;
}

// Least squares of z (or `coord`) = c0 + c1 (t - tm) + sum_{h=1..3} a_h sin(2 pi h f t) + b_h cos(2 pi h f t)
// over [i0, i1); returns the amplitude at f, sqrt(a_1^2 + b_1^2), or nullopt when the samples
// cannot resolve the harmonics. The harmonics 2f and 3f are in the model so that they do not leak
// into the amplitude at f.
std::optional<double> OscillationAmplitude(const std::vector<SoSample>& s, size_t i0, size_t i1, double f,
                                           double SoSample::*coord = &SoSample::z) {
  constexpr int k = 8;
  if (i1 - i0 < 4 * k) return std::nullopt;
  const double n = static_cast<double>(i1 - i0);
  double tm = 0;
  for (size_t i = i0; i < i1; ++i) tm += s[i].t;
  tm /= n;
  double m[k][k + 1] = {};  // [X'X | X'z], reduced to [I | coef]
  auto basis = [&](const SoSample& p, double* x) {
    x[0] = 1;
    x[1] = p.t - tm;
    for (int h = 1; h <= 3; ++h) {
      double w = 2 * kPi * h * f * p.t;
      x[2 * h] = std::sin(w);
      x[2 * h + 1] = std::cos(w);
    }
  };
  for (size_t i = i0; i < i1; ++i) {
    double x[k];
    basis(s[i], x);
    for (int a = 0; a < k; ++a) {
      m[a][k] += x[a] * (s[i].*coord);
      for (int b = 0; b < k; ++b) m[a][b] += x[a] * x[b];
    }
  }
  double scale[k];
  for (int a = 0; a < k; ++a) scale[a] = m[a][a];
  for (int c = 0; c < k; ++c) {
    int p = c;
    for (int r = c + 1; r < k; ++r) {
      if (std::fabs(m[r][c]) > std::fabs(m[p][c])) p = r;
    }
    if (std::fabs(m[p][c]) < 1e-9 * std::max(scale[c], 1e-300)) return std::nullopt;
    for (int j = 0; j <= k; ++j) std::swap(m[c][j], m[p][j]);
    double d = m[c][c];
    for (int j = 0; j <= k; ++j) m[c][j] /= d;
    for (int r = 0; r < k; ++r) {
      if (r == c) continue;
      double q = m[r][c];
      for (int j = 0; j <= k; ++j) m[r][j] -= q * m[c][j];
    }
  }
  return std::hypot(m[2][k], m[3][k]);
}

// z at time t, linearly interpolated between the samples around it.
// REQUIRES: samples ascending in t, samples.front().t <= t <= samples.back().t.
double ZAt(const std::vector<SoSample>& s, double t) {
  auto it = std::lower_bound(s.begin(), s.end(), t, [](const SoSample& p, double v) { return p.t < v; });
  if (it == s.end()) return s.back().z;
  if (it == s.begin() || it->t == t) return it->z;
  const SoSample& b = *it;
  const SoSample& a = *(it - 1);
  return a.z + (b.z - a.z) * (t - a.t) / (b.t - a.t);
}

// Forward: defined with the public functions below.
void TestTrend(const std::vector<SoSample>& samples, const WindowRule& rule, api::RunResult* r);

}  // namespace

Result<double> ReadTimeStep(std::string_view deck) {
  auto dt = LineValue(deck, "timestep");
  if (!dt || !(*dt > 0) || !std::isfinite(*dt))
    return Status::InvalidArgument("deck", "the deck has no 'timestep <dt>' line with dt > 0");
  return *dt;
}

Result<DriveInfo> ReadDriveInfo(std::string_view deck) {
  DriveInfo info;
  Result<double> dt = ReadTimeStep(deck);
  if (!dt.ok()) return dt.status();
  info.dt = *dt;
  // Every drive deck states f (0 for constant rotation): a deck without it is not one of ours, and
  // guessing "no period" would analyse a vibrating run with the wrong blocks.
  auto f = LineValue(deck, "variable f equal ");
  if (!f)
    return Status::InvalidArgument("deck", "the deck has no 'variable f equal <Hz>' line (0 for constant rotation)");
  info.f = *f;
  info.A = LineValue(deck, "variable A equal ").value_or(0.0);
  if (!(info.f >= 0) || !std::isfinite(info.f))
    return Status::InvalidArgument("deck", "'variable f equal' is not a finite f >= 0");
  // "fix floor all wall/gran model ... primitive type 1 zplane Z"
  size_t at = deck.find("\nfix floor ");
  if (at != std::string_view::npos) {
    std::string_view line = deck.substr(at + 1, deck.find('\n', at + 1) - at - 1);
    size_t z = line.find(" zplane ");
    double v;
    if (z != std::string_view::npos && ToDouble(line.substr(z + 8), &v)) info.z_floor = v;
  }
  // "variable top_gap equal v_so_z+R-v_z_surface": the SO's radius R (a deck without it, Table 1's).
  const std::string_view gap = "\nvariable top_gap equal v_so_z+";
  at = deck.find(gap);
  if (at != std::string_view::npos) {
    std::string_view rest = deck.substr(at + gap.size());
    double v;
    if (ToDouble(rest.substr(0, rest.find('-')), &v) && v > 0) info.so_radius = v;
  }
  return info;
}

void SoSampleSink::OnFrame(const DumpFrameView& f) {
  if (!status_.ok()) return;
  if (f.columns_serial == 0 || f.columns_serial != serial_) {
    cx_ = f.Column("x");
    cy_ = f.Column("y");
    cz_ = f.Column("z");
    cid_ = f.Column("id");
    crad_ = f.Column("radius");
    if (crad_ < 0) crad_ = f.Column("diameter");
    serial_ = f.columns_serial;
  }
  if (cx_ < 0 || cy_ < 0 || cz_ < 0) {
    status_ = Status::Corruption("dump frame at step " + std::to_string(f.step) + " lacks column x, y or z");
    return;
  }
  if (f.atoms < 1) {
    status_ = Status::Corruption("dump frame at step " + std::to_string(f.step) + " has no atom");
    return;
  }
  if (!samples_.empty() && f.step <= samples_.back().step) {
    status_ = Status::Corruption("dump steps do not rise: " + std::to_string(samples_.back().step) + " then " +
                                 std::to_string(f.step));
    return;
  }
  const int64_t row = SoRow(f);
  if (row < 0) return;
  SoSample s;
  s.step = f.step;
  s.t = static_cast<double>(f.step) * dt_;
  s.x = f.At(row, cx_);
  s.y = f.At(row, cy_);
  s.z = f.At(row, cz_);
  if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z)) {
    status_ = Status::Corruption("dump frame at step " + std::to_string(f.step) + " has a non-finite position");
    return;
  }
  samples_.push_back(s);
}

int64_t SoSampleSink::SoRow(const DumpFrameView& f) {
  const std::string at = "dump frame at step " + std::to_string(f.step);
  if (!id_ && f.atoms == 1) return 0;
  if (!id_) {
    // The largest particle of this (the first) frame is the SO from now on.
    if (crad_ < 0) {
      status_ = Status::Corruption(at + " has " + std::to_string(f.atoms) +
                                   " atoms and no radius or diameter column to tell the SO by: give the SO's id");
      return -1;
    }
    if (cid_ < 0) {
      status_ =
          Status::Corruption(at + " has " + std::to_string(f.atoms) + " atoms and no id column to follow the SO by");
      return -1;
    }
    int64_t best = 0;
    for (int64_t i = 1; i < f.atoms; ++i) {
      if (f.At(i, crad_) > f.At(best, crad_)) best = i;
    }
    id_ = static_cast<int64_t>(std::llround(f.At(best, cid_)));
    return best;
  }
  if (cid_ < 0) {
    if (f.atoms == 1) return 0;
    status_ = Status::Corruption(at + " has no id column to find atom " + std::to_string(*id_) + " by");
    return -1;
  }
  for (int64_t i = 0; i < f.atoms; ++i) {
    if (std::llround(f.At(i, cid_)) == *id_) return i;
  }
  status_ = Status::Corruption(at + " has no atom with id " + std::to_string(*id_));
  return -1;
}

Result<std::vector<SoSample>> SoSampleSink::Take() {
  if (!status_.ok()) return status_;
  return std::move(samples_);
}

Result<std::vector<SoSample>> SamplesFromDump(std::string_view text, double dt, SoSelector so) {
  SoSampleSink sink(dt, so);
  if (Status s = ReadDump(text, sink); !s.ok()) return s;
  return sink.Take();
}

double StudentT95(int dof) { return gsl_cdf_tdist_Pinv(0.975, std::max(dof, 1)); }

double TransientS(const WindowRule& rule, double block_s) {
  // Whole blocks, so that the window's z_k are read at the drive's phase at t = 0 (the tolerance
  // keeps a transient_s that is a whole number of blocks, as 1 / f may not be exact).
  const double blocks = std::ceil(rule.transient_s / block_s - 1e-9);
  return std::max(blocks, rule.transient_blocks) * block_s;
}

namespace {

// The rates of `blocks` whole blocks of block_s from t0: (z(t0 + (k+1) T) - z(t0 + k T)) / T.
std::vector<double> BlockRates(const std::vector<SoSample>& samples, double t0, double block_s, int blocks) {
  std::vector<double> rates;
  rates.reserve(blocks);
  double z_prev = ZAt(samples, t0);
  for (int k = 1; k <= blocks; ++k) {
    double z = ZAt(samples, t0 + k * block_s);
    rates.push_back((z - z_prev) / block_s);
    z_prev = z;
  }
  return rates;
}

}  // namespace

std::optional<Trend> BlockRateTrend(const std::vector<SoSample>& samples, double t0, double block_s, int blocks) {
  if (blocks < 3) return std::nullopt;
  const std::vector<double> r = BlockRates(samples, t0, block_s, blocks);
  const double n = blocks;
  // Block k's mid time is t0 + (k + 1/2) T; the slope does not depend on the origin.
  const double tm = (n - 1) / 2 * block_s;
  double rm = 0, rmax = 0;
  for (double v : r) {
    rm += v;
    rmax = std::max(rmax, std::fabs(v));
  }
  rm /= n;
  double sxx = 0, sxy = 0;
  for (int k = 0; k < blocks; ++k) {
    const double dt = k * block_s - tm;
    sxx += dt * dt;
    sxy += dt * (r[k] - rm);
  }
  Trend out;
  out.slope = sxy / sxx;
  double ss = 0;
  for (int k = 0; k < blocks; ++k) {
    const double e = r[k] - rm - out.slope * (k * block_s - tm);
    ss += e * e;
  }
  const double s = std::sqrt(ss / (n - 2));
  // Rates that agree to rounding (a trajectory with no scatter): no trend unless the slope is
  // beyond rounding too, else a ratio of two rounding errors would decide.
  const double rounding = 1e-9 * std::max(rmax, 1e-12);
  if (s <= rounding) {
    out.slope_se = 0;
    out.p = std::fabs(out.slope) * (n - 1) * block_s <= rounding ? 1.0 : 0.0;
    return out;
  }
  out.slope_se = s / std::sqrt(sxx);
  const double t = std::fabs(out.slope) / out.slope_se;
  out.p = 2 * gsl_cdf_tdist_Q(t, n - 2);
  return out;
}

BlockRate MeanBlockRate(const std::vector<SoSample>& samples, double t0, double block_s, int blocks,
                        int min_blocks_for_error) {
  BlockRate out;
  out.blocks = blocks;
  out.t0 = t0;
  out.t1 = t0 + blocks * block_s;
  const std::vector<double> rates = BlockRates(samples, t0, block_s, blocks);
  double mean = 0;
  for (double r : rates) mean += r;
  mean /= blocks;
  out.rate = mean;
  if (blocks >= std::max(min_blocks_for_error, 2)) {
    double ss = 0;
    for (double r : rates) ss += (r - mean) * (r - mean);
    out.se = std::sqrt(ss / (blocks - 1) / blocks);
    out.ci95 = StudentT95(blocks - 1) * *out.se;
  }
  return out;
}

Result<api::RunResult> AnalyzeTrajectory(const std::vector<SoSample>& samples, double f, BedBounds bounds,
                                         const std::optional<DriveStartMarker>& start,
                                         const std::optional<DriveStopMarker>& stop, const WindowRule& rule) {
  if (samples.size() < 3) {
    return Status::FailedPrecondition(
        "trajectory", "the SO dump has " + std::to_string(samples.size()) + " frames; at least 3 are needed");
  }
  if (!std::isfinite(f) || f < 0) return Status::InvalidArgument("f", "the drive frequency must be finite and >= 0 Hz");
  const SoSample& first = samples.front();
  const SoSample& last = samples.back();
  if (!bounds.surface && start) bounds.surface = start->surface;
  // A block shorter than the dump's mean sample interval has no samples of its own (and a huge f
  // would ask for billions of blocks): the frequency or the dump is wrong.
  const double sample_interval = (last.t - first.t) / static_cast<double>(samples.size() - 1);
  if (f > 0 && 1.0 / f < sample_interval) {
    return Status::InvalidArgument("f", "a period of " + Num(1.0 / f, 3) + " s (f = " + Num(f, 3) +
                                            " Hz) is shorter than the dump's sample interval of " +
                                            Num(sample_interval, 3) + " s: check f, or dump the SO more often");
  }

  api::RunResult r;
  r.block_s = f > 0 ? 1.0 / f : rule.undriven_block_s;
  r.block_kind = f > 0 ? "period" : "block";
  const double transient = TransientS(rule, r.block_s);
  r.window_t0 = first.t + transient;

  // The last moment the SO keeps its clearance from the surface and the floor.
  // It ends at the last sample that keeps it (the first sample inside is already under the
  // boundary's influence).
  double t_end = last.t;
  r.window_end = "run_end";
  const double reach = bounds.so_radius + rule.clearance_m;
  double t_kept = first.t;
  for (const SoSample& p : samples) {
    const bool near_surface = bounds.surface && p.z > *bounds.surface - reach;
    const bool near_floor = bounds.floor && p.z < *bounds.floor + reach;
    if (near_surface || near_floor) {
      t_end = t_kept;
      r.window_end = near_surface ? "surface" : "floor";
      break;
    }
    t_kept = p.t;
  }
  // Whole blocks only; the tolerance lets a window that ends on its last sample keep that block.
  const double span = t_end - r.window_t0;
  r.uz_blocks = span > 0 ? static_cast<int>(std::floor(span / r.block_s + 1e-6)) : 0;
  if (r.uz_blocks >= 1) {
    BlockRate b = MeanBlockRate(samples, r.window_t0, r.block_s, r.uz_blocks, rule.min_blocks_for_error);
    r.uz = b.rate;
    r.uz_stderr = b.se;
    r.uz_ci95 = b.ci95;
    r.window_t1 = b.t1;
  } else {
    r.window_t1 = r.window_t0;
  }
  const std::string& what = r.block_kind;
  const std::string whole = std::to_string(r.uz_blocks) + " whole " + what + (r.uz_blocks == 1 ? "" : "s") + " of " +
                            Num(r.block_s, 3) + " s";
  const std::string ended = r.window_end == "run_end"
                                ? "the run ended"
                                : "the SO came within " + Num(rule.clearance_m, 3) + " m of the " +
                                      (r.window_end == "surface" ? std::string("bed surface") : std::string("floor")) +
                                      " at t = " + Num(t_end, 3) + " s";
  if (!r.uz_stderr) {
    r.uz_stderr_note = "the window holds " + whole + "; an error needs at least " +
                       std::to_string(rule.min_blocks_for_error) + " (" + ended + ")";
  }
  r.conclusive = r.uz_blocks >= rule.min_periods;
  if (!r.conclusive) {
    r.inconclusive_reason = "the steady window after the " + Num(transient, 3) +
                            " s transient holds " + whole + ", fewer than " + std::to_string(rule.min_periods) + " (" +
                            ended + ")";
  }
  if (f > 0 && r.uz_blocks >= 1) {
    size_t i0 = 0;
    while (i0 < samples.size() && samples[i0].t < r.window_t0 - 1e-9) ++i0;
    size_t i1 = i0;
    while (i1 < samples.size() && samples[i1].t <= r.window_t1 + 1e-9) ++i1;
    r.z_osc_amplitude = OscillationAmplitude(samples, i0, i1, f).value_or(0.0);
    r.x_osc_amplitude = OscillationAmplitude(samples, i0, i1, f, &SoSample::x);
  }
  TestTrend(samples, rule, &r);

  r.dz = last.z - first.z;
  r.dz_rate = last.t > first.t ? r.dz / (last.t - first.t) : 0;
  r.x_drift = last.x - first.x;
  r.z0 = first.z;
  r.sim_time_s = last.t;
  r.steps = last.step;
  r.stop_reason = "duration";
  if (stop) {
    r.stop_reason = stop->reason;
    r.broke_surface = stop->reason == "surface";  // the SO's top reached the surface
    r.near_floor = stop->reason == "floor";
    r.steps = stop->step;
    r.sim_time_s = stop->t;
  }
  if (start) r.grains = start->grains;
  return r;
}

namespace {

// The trend test of the blocks r's U_z rests on, into r's trend_* fields.
void TestTrend(const std::vector<SoSample>& samples, const WindowRule& rule, api::RunResult* r) {
  r->trend_slope.reset();
  r->trend_slope_se.reset();
  r->trend_p.reset();
  r->trending = false;
  r->trend_note.clear();
  std::optional<Trend> trend;
  if (r->uz_blocks >= std::max(rule.min_blocks_for_trend, 3))
    trend = BlockRateTrend(samples, r->window_t0, r->block_s, r->uz_blocks);
  if (!trend) {
    const std::string noun = r->block_kind.empty() ? std::string("period") : r->block_kind;
    r->trend_note = "the window holds " + std::to_string(r->uz_blocks) + " whole " + noun +
                    (r->uz_blocks == 1 ? "" : "s") + "; a trend test needs at least " +
                    std::to_string(std::max(rule.min_blocks_for_trend, 3));
    return;
  }
  r->trend_slope = trend->slope;
  r->trend_slope_se = trend->slope_se;
  r->trend_p = trend->p;
  r->trending = trend->p < rule.trend_alpha;
}

}  // namespace

RunInputs RunInputsFrom(const DriveInfo& drive, const EngineLog& log, const std::optional<PrecisionTarget>& precision) {
  RunInputs in;
  in.precision = precision;
  in.f = drive.f;
  if (drive.dt > 0) in.dt = drive.dt;
  in.bounds.floor = drive.z_floor;
  in.bounds.so_radius = drive.so_radius;
  in.start = log.drive_start;
  in.stop = log.drive_stop;
  if (in.start) in.bounds.surface = in.start->surface;
  return in;
}

Result<api::RunResult> AnalyzeRun(const std::vector<SoSample>& samples, const RunInputs& in, const WindowRule& rule) {
  auto r = AnalyzeTrajectory(samples, in.f, in.bounds, in.start, in.stop, rule);
  if (!r.ok()) return r;
  std::optional<StopPlan> plan;
  if (in.precision && r->stop_reason == "target") plan = PlanStop(samples, *r, *in.precision);
  if (plan && r->uz_blocks - plan->pilot_blocks >= rule.min_blocks_for_error) {
    // Ended by its two-stage rule (core/precision.h): U_z, its error and its interval from the
    // blocks after the pilot alone, which the stop was not chosen on.
    const int m = r->uz_blocks - plan->pilot_blocks;
    const double t0 = r->window_t0 + plan->pilot_blocks * r->block_s;
    const BlockRate after = MeanBlockRate(samples, t0, r->block_s, m, rule.min_blocks_for_error);
    r->uz = after.rate;
    r->uz_stderr = after.se;
    r->uz_ci95 = after.ci95;
    r->uz_stderr_note.clear();
    r->uz_blocks = m;
    r->window_t0 = t0;
    r->precision_met = r->uz_ci95 && *r->uz_ci95 <= plan->half_width;  // the half-width the pilot asked
    TestTrend(samples, rule, &*r);  // on the blocks U_z now rests on
  } else {
    plan.reset();  // not ended by the rule as it stands: no two-stage numbers to state
    if (in.precision) r->precision_met = TargetMet(*r, *in.precision);
  }
  r->stop_note = DescribeStop(*r, in.precision, plan);
  return r;
}

namespace {

// v with `digits` significant digits.
std::string Round(double v, int digits) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*g", std::max(digits, 1), v);
  return buf;
}

}  // namespace

std::string WithError(double v, double err) {
  // An error below 1e-12 of the value is rounding noise (a trajectory with no scatter at all, as
  // a stand-in engine writes): shown as 0 rather than as twenty digits.
  if (!(err > 1e-12 * std::fabs(v))) return Round(v, 3) + " ± 0";
  const int exponent = static_cast<int>(std::floor(std::log10(err))) - 1;  // place of err's 2nd digit
  char vb[48], eb[48];
  if (exponent < 0) {
    std::snprintf(vb, sizeof vb, "%.*f", -exponent, v);
    std::snprintf(eb, sizeof eb, "%.*f", -exponent, err);
  } else {
    const double q = std::pow(10.0, exponent);
    std::snprintf(vb, sizeof vb, "%.0f", std::round(v / q) * q);
    std::snprintf(eb, sizeof eb, "%.0f", std::round(err / q) * q);
  }
  return std::string(vb) + " ± " + eb;
}

std::string DescribeUz(const api::RunResult& r, bool with_units) {
  const std::string units = with_units ? " m/s" : "";
  const std::string noun = r.block_kind.empty() ? std::string("period") : r.block_kind;
  const std::string what = std::to_string(r.uz_blocks) + " " + noun + (r.uz_blocks == 1 ? "" : "s");
  std::string out;
  if (r.analysis < 2) {
    out = "old estimator";
    if (r.uz) out += " (" + Round(*r.uz, 1) + units + ")";
    return out;
  }
  // A result of an older analysis whose numbers stand (analysis 2 or 3: a one-period transient) says so.
  const std::string older = r.analysis < api::kAnalysisVersion ? " (analysis " + std::to_string(r.analysis) + ")" : "";
  if (!older.empty()) {
    api::RunResult now = r;
    now.analysis = api::kAnalysisVersion;
    return DescribeUz(now, with_units) + older;
  }
  if (!r.conclusive) {
    if (!r.uz) return "inconclusive (no whole " + noun + ")";
    return "inconclusive (≈" + Round(*r.uz, 1) + units + ", " + what + ")";
  }
  if (!r.uz) return "inconclusive";
  if (!r.uz_stderr) return "≈" + Round(*r.uz, 2) + units + ", no error: " + what;
  return WithError(*r.uz, *r.uz_stderr) + units + ", " + what;
}

api::Trajectory Downsample(const std::vector<SoSample>& samples, size_t max_points) {
  api::Trajectory out;
  if (samples.empty() || max_points == 0) return out;
  const size_t n = samples.size();
  const size_t m = std::min(n, std::max<size_t>(max_points, 2));
  auto add = [&out](const SoSample& s) {
    out.t.push_back(s.t);
    out.x.push_back(s.x);
    out.y.push_back(s.y);
    out.z.push_back(s.z);
  };
  if (m == n) {
    for (const SoSample& s : samples) add(s);
    return out;
  }
  for (size_t k = 0; k < m; ++k) {
    // Index k * (n - 1) / (m - 1): the first and the last are always kept.
    size_t i = static_cast<size_t>((static_cast<unsigned long long>(k) * (n - 1)) / (m - 1));
    add(samples[i]);
  }
  return out;
}

}  // namespace sandswim
