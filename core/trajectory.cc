#include "core/trajectory.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>

namespace sandswim {
namespace {

constexpr double kPi = 3.14159265358979323846;

std::string_view Trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t' || s.front() == '\r')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

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

struct LineFit {
  double slope = 0, intercept = 0, slope_stderr = 0;
};

// Least squares z = intercept + slope * t over samples [i0, i1).
LineFit FitLine(const std::vector<SoSample>& s, size_t i0, size_t i1) {
  const double n = static_cast<double>(i1 - i0);
  double tm = 0, zm = 0;
  for (size_t i = i0; i < i1; ++i) {
    tm += s[i].t;
    zm += s[i].z;
  }
  tm /= n;
  zm /= n;
  double sxx = 0, sxz = 0;
  for (size_t i = i0; i < i1; ++i) {
    sxx += (s[i].t - tm) * (s[i].t - tm);
    sxz += (s[i].t - tm) * (s[i].z - zm);
  }
  LineFit fit;
  fit.slope = sxx > 0 ? sxz / sxx : 0;
  fit.intercept = zm - fit.slope * tm;
  double ssr = 0;
  for (size_t i = i0; i < i1; ++i) {
    double r = s[i].z - fit.intercept - fit.slope * s[i].t;
    ssr += r * r;
  }
  fit.slope_stderr = (n > 2 && sxx > 0) ? std::sqrt(ssr / (n - 2) / sxx) : 0;
  return fit;
}

// Least squares of z = c0 + c1 (t - tm) + a sin(2 pi f t) + b cos(2 pi f t) over [i0, i1): the
// oscillation is fitted together with the trend, so a window that is not a whole number of
// periods does not bias the slope (a plain line fit of a sinusoid is off by ~ amp / (f T)).
// Returns false when the samples cannot resolve f (then the caller keeps the plain line fit).
bool FitLineAndOscillation(const std::vector<SoSample>& s, size_t i0, size_t i1, double f, LineFit* line,
                           double* amplitude) {
  constexpr int k = 4;
  const double n = static_cast<double>(i1 - i0);
  double tm = 0;
  for (size_t i = i0; i < i1; ++i) tm += s[i].t;
  tm /= n;
  double m[k][2 * k] = {};  // [X'X | I], reduced to [I | (X'X)^-1]
  double rhs[k] = {};
  auto basis = [&](const SoSample& p, double* x) {
    double w = 2 * kPi * f * p.t;
    x[0] = 1;
    x[1] = p.t - tm;
    x[2] = std::sin(w);
    x[3] = std::cos(w);
  };
  for (size_t i = i0; i < i1; ++i) {
    double x[k];
    basis(s[i], x);
    for (int a = 0; a < k; ++a) {
      rhs[a] += x[a] * s[i].z;
      for (int b = 0; b < k; ++b) m[a][b] += x[a] * x[b];
    }
  }
  for (int a = 0; a < k; ++a) m[a][k + a] = 1;
  double scale[k];
  for (int a = 0; a < k; ++a) scale[a] = m[a][a];
  for (int c = 0; c < k; ++c) {
    int p = c;
    for (int r = c + 1; r < k; ++r) {
      if (std::fabs(m[r][c]) > std::fabs(m[p][c])) p = r;
    }
    if (std::fabs(m[p][c]) < 1e-9 * std::max(scale[c], 1e-300)) return false;
    for (int j = 0; j < 2 * k; ++j) std::swap(m[c][j], m[p][j]);
    double d = m[c][c];
    for (int j = 0; j < 2 * k; ++j) m[c][j] /= d;
    for (int r = 0; r < k; ++r) {
      if (r == c) continue;
      double q = m[r][c];
      for (int j = 0; j < 2 * k; ++j) m[r][j] -= q * m[c][j];
    }
  }
  double coef[k] = {};
  for (int a = 0; a < k; ++a) {
    for (int b = 0; b < k; ++b) coef[a] += m[a][k + b] * rhs[b];
  }
  double ssr = 0;
  for (size_t i = i0; i < i1; ++i) {
    double x[k];
    basis(s[i], x);
    double r = s[i].z;
    for (int a = 0; a < k; ++a) r -= coef[a] * x[a];
    ssr += r * r;
  }
  line->slope = coef[1];
  line->intercept = coef[0] - coef[1] * tm;
  line->slope_stderr = n > k ? std::sqrt(std::max(0.0, ssr / (n - k) * m[1][k + 1])) : 0;
  *amplitude = std::sqrt(coef[2] * coef[2] + coef[3] * coef[3]);
  return true;
}

}  // namespace

Result<DriveInfo> ReadDriveInfo(std::string_view deck) {
  DriveInfo info;
  auto dt = LineValue(deck, "timestep");
  if (!dt || *dt <= 0) return Status::InvalidArgument("deck", "the deck has no 'timestep <dt>' line with dt > 0");
  info.dt = *dt;
  info.f = LineValue(deck, "variable f equal ").value_or(0.0);
  info.A = LineValue(deck, "variable A equal ").value_or(0.0);
  if (info.f < 0) return Status::InvalidArgument("deck", "'variable f equal' is negative");
  return info;
}

Result<std::vector<SoSample>> SamplesFromFrames(const std::vector<DumpFrame>& frames, double dt) {
  SoSampleSink sink(dt);
  for (const DumpFrame& f : frames) {
    DumpFrameView view;
    view.step = f.step;
    view.atoms = f.atoms;
    view.names = &f.columns;
    view.values = f.values.data();  // columns_serial 0: the sink looks the columns up
    sink.OnFrame(view);
  }
  return sink.Take();
}

void SoSampleSink::OnFrame(const DumpFrameView& f) {
  if (!status_.ok()) return;
  if (f.columns_serial == 0 || f.columns_serial != serial_) {
    cx_ = f.Column("x");
    cy_ = f.Column("y");
    cz_ = f.Column("z");
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
  SoSample s;
  s.step = f.step;
  s.t = static_cast<double>(f.step) * dt_;
  s.x = f.values[cx_];  // atom 0
  s.y = f.values[cy_];
  s.z = f.values[cz_];
  if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z)) {
    status_ = Status::Corruption("dump frame at step " + std::to_string(f.step) + " has a non-finite position");
    return;
  }
  samples_.push_back(s);
}

Result<std::vector<SoSample>> SoSampleSink::Take() {
  if (!status_.ok()) return status_;
  return std::move(samples_);
}

Result<std::vector<SoSample>> SamplesFromDump(std::string_view text, double dt) {
  SoSampleSink sink(dt);
  if (Status s = ReadDump(text, sink); !s.ok()) return s;
  return sink.Take();
}

double SteadyWindowStart(double f, double duration) {
  double skip = f > 0 ? 1.0 / f : 0.1 * duration;
  return std::min(skip, 0.5 * duration);
}

Result<api::RunResult> AnalyzeTrajectory(const std::vector<SoSample>& samples, double f,
                                         const std::optional<DriveStartMarker>& start,
                                         const std::optional<DriveStopMarker>& stop) {
  if (samples.size() < 3) {
    return Status::FailedPrecondition("trajectory", "the SO dump has " + std::to_string(samples.size()) +
                                                        " frames; at least 3 are needed");
  }
  const SoSample& first = samples.front();
  const SoSample& last = samples.back();
  const double duration = last.t - first.t;
  const double t0 = first.t + SteadyWindowStart(f, duration);
  size_t i0 = 0;
  while (i0 < samples.size() && samples[i0].t < t0 - 1e-12) ++i0;
  const size_t i1 = samples.size();
  if (i1 - i0 < 3) {
    return Status::FailedPrecondition("trajectory", "fewer than 3 samples in the steady window");
  }
  LineFit line = FitLine(samples, i0, i1);
  double amplitude = 0;
  // The oscillation is fitted only over at least one whole period and 8 samples; over less, a
  // sinusoid and a trend cannot be told apart (the fit swings wildly), so the plain line stands
  // and the amplitude is reported as 0.
  // Each sample stands for one sampling interval, so n samples cover n intervals: a window of
  // samples 0.334 .. 0.667 s at 1 ms covers one whole 3 Hz period.
  const double spacing = (samples[i1 - 1].t - samples[i0].t) / static_cast<double>(i1 - i0 - 1);
  const double window = samples[i1 - 1].t - samples[i0].t + spacing;
  if (f > 0 && i1 - i0 >= 8 && window * f >= 1.0 - 1e-9 &&
      !FitLineAndOscillation(samples, i0, i1, f, &line, &amplitude)) {
    line = FitLine(samples, i0, i1);
    amplitude = 0;
  }

  api::RunResult r;
  r.uz = line.slope;
  r.uz_stderr = line.slope_stderr;
  r.window_t0 = samples[i0].t;
  r.window_t1 = last.t;
  r.dz = last.z - first.z;
  r.x_drift = last.x - first.x;
  r.z0 = first.z;
  r.z_osc_amplitude = amplitude;
  r.sim_time_s = last.t;
  r.steps = last.step;
  r.stop_reason = "duration";
  if (stop) {
    r.stop_reason = stop->reason;
    r.broke_surface = stop->reason == "surface";
    r.near_floor = stop->reason == "floor";
    r.steps = stop->step;
    r.sim_time_s = stop->t;
  }
  if (start) r.grains = start->grains;
  return r;
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
