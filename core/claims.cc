#include "core/claims.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>

#include <gsl/gsl_cdf.h>

#include "core/scale.h"
#include "core/text.h"
#include "core/trajectory.h"

namespace sandswim {
namespace {
// The helpers live in a namespace of their own: in a unity build every anonymous namespace of the
// library is one, and the sweep parser and the fits have helpers of the same names.
namespace claim_rules {

using nlohmann::json;

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---- Parsing ------------------------------------------------------------------------------------

enum class ParamType {
  kSweep,        // the name of one of the campaign's sweeps
  kSweeps,       // a non-empty array of them
  kPositive,     // a number > 0
  kNonNegative,  // a number >= 0
  kFraction,     // a number in (0, 1)
  kAtLeastOne,   // a number >= 1
  kCount,        // an integer >= 3
  kExpect,       // "rise" | "sink" | "against_Omega"
};

struct ParamSpec {
  const char* name;
  ParamType type;
  bool required;
};

struct KindSpec {
  const char* kind;
  std::vector<ParamSpec> params;
};

const std::vector<KindSpec>& Kinds() {
  static const std::vector<KindSpec> kKinds = {
      {"sign", {{"sweeps", ParamType::kSweeps, true}, {"expect", ParamType::kExpect, true}}},
      {"saturation",
       {{"sweep", ParamType::kSweep, true},
        {"reached_fraction", ParamType::kFraction, false},
        {"min_points", ParamType::kCount, false},
        {"beyond_abs_Omega", ParamType::kPositive, false},
        {"min_duration_s", ParamType::kPositive, false}}},
      {"linear_in_A",
       {{"sweep", ParamType::kSweep, true},
        {"sinking_linear_to_A", ParamType::kPositive, false},
        {"break_tolerance_m", ParamType::kPositive, false}}},
      {"interior_maximum",
       {{"sweep", ParamType::kSweep, true},
        {"f_c_hz", ParamType::kPositive, true},
        {"f_c_tolerance_hz", ParamType::kNonNegative, false}}},
      {"grain_count",
       {{"paper_grains", ParamType::kPositive, true},
        {"paper_bed_m3", ParamType::kPositive, true},
        {"tolerance_rel", ParamType::kNonNegative, false}}},
      {"modes",
       {{"rises", ParamType::kSweeps, true},
        {"fastest", ParamType::kSweep, true},
        {"fastest_among", ParamType::kSweeps, true},
        {"x_within_m", ParamType::kPositive, true},
        {"z_osc_with", ParamType::kSweeps, true},
        {"z_osc_without", ParamType::kSweeps, true},
        {"osc_ratio", ParamType::kAtLeastOne, false},
        {"x_osc_with", ParamType::kSweeps, false},
        {"x_osc_without", ParamType::kSweeps, false}}},
  };
  return kKinds;
}

std::string JoinNames(const std::vector<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s;
}

bool IsClaimId(const std::string& id) {
  if (id.empty() || id.size() > 100) return false;
  return std::all_of(id.begin(), id.end(), [](char c) {
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  });
}

Status CheckSweepName(const json& v, const std::string& field, const std::vector<std::string>& sweeps) {
  if (!v.is_string()) return Status::InvalidArgument(field, "must be the name of one of the campaign's sweeps");
  const std::string name = v.get<std::string>();
  if (std::find(sweeps.begin(), sweeps.end(), name) == sweeps.end())
    return Status::InvalidArgument(field, "names no sweep of the campaign (\"" + name.substr(0, 100) +
                                              "\"; its sweeps: " + JoinNames(sweeps) + ")");
  return Status::Ok();
}

Status CheckParam(const ParamSpec& spec, const json& v, const std::string& field,
                  const std::vector<std::string>& sweeps) {
  auto number = [&](const char* want, auto ok) -> Status {
    if (!v.is_number() || !std::isfinite(v.get<double>())) return Status::InvalidArgument(field, "must be a number");
    if (!ok(v.get<double>())) return Status::InvalidArgument(field, std::string("must be ") + want);
    return Status::Ok();
  };
  switch (spec.type) {
    case ParamType::kSweep:
      return CheckSweepName(v, field, sweeps);
    case ParamType::kSweeps:
      if (!v.is_array() || v.empty()) return Status::InvalidArgument(field, "must be a non-empty array of sweep names");
      for (size_t i = 0; i < v.size(); ++i)
        SANDSWIM_RETURN_IF_ERROR(CheckSweepName(v[i], field + "[" + std::to_string(i) + "]", sweeps));
      return Status::Ok();
    case ParamType::kPositive:
      return number("> 0", [](double x) { return x > 0; });
    case ParamType::kNonNegative:
      return number(">= 0", [](double x) { return x >= 0; });
    case ParamType::kFraction:
      return number("between 0 and 1 (exclusive)", [](double x) { return x > 0 && x < 1; });
    case ParamType::kAtLeastOne:
      return number(">= 1", [](double x) { return x >= 1; });
    case ParamType::kCount:
      if (!v.is_number_integer() || v.get<int64_t>() < 3)
        return Status::InvalidArgument(field, "must be an integer >= 3");
      return Status::Ok();
    case ParamType::kExpect:
      if (!v.is_string() || (v != "rise" && v != "sink" && v != "against_Omega"))
        return Status::InvalidArgument(field, "must be one of rise, sink, against_Omega");
      return Status::Ok();
  }
  return Status::Ok();
}

Status CheckRule(const json& rule, const std::vector<std::string>& sweeps) {
  if (!rule.is_object()) return Status::InvalidArgument("rule", "must be an object {\"kind\": ..., parameters}");
  std::vector<std::string> kinds = ClaimKinds();
  auto kind = rule.find("kind");
  if (kind == rule.end()) return Status::InvalidArgument("rule.kind", "is required (one of " + JoinNames(kinds) + ")");
  const KindSpec* spec = nullptr;
  for (const KindSpec& k : Kinds())
    if (kind->is_string() && *kind == k.kind) spec = &k;
  if (spec == nullptr) return Status::InvalidArgument("rule.kind", "must be one of " + JoinNames(kinds));
  for (const auto& [key, value] : rule.items()) {
    if (key == "kind") continue;
    const std::string& name = key;  // a structured binding is not captured before C++20
    auto p = std::find_if(spec->params.begin(), spec->params.end(), [&](const ParamSpec& s) { return name == s.name; });
    if (p == spec->params.end()) {
      std::string allowed;
      for (const ParamSpec& s : spec->params) allowed += (allowed.empty() ? "" : ", ") + std::string(s.name);
      return Status::InvalidArgument(
          "rule." + key.substr(0, 64),
          "is not a parameter of kind \"" + std::string(spec->kind) + "\" (it takes " + allowed + ")");
    }
    SANDSWIM_RETURN_IF_ERROR(CheckParam(*p, value, "rule." + key, sweeps));
  }
  for (const ParamSpec& s : spec->params)
    if (s.required && !rule.contains(s.name))
      return Status::InvalidArgument("rule." + std::string(s.name),
                                     "is required by kind \"" + std::string(spec->kind) + "\"");
  return Status::Ok();
}

Result<Claim> ParseOne(const json& j, const std::vector<std::string>& sweeps) {
  if (!j.is_object()) return Status::InvalidArgument("", "must be an object {id, title, source, paper, rule}");
  for (const auto& [key, value] : j.items()) {
    (void)value;
    static const std::set<std::string> kKeys = {"id", "title", "source", "paper", "rule"};
    if (!kKeys.count(key)) return Status::InvalidArgument(key.substr(0, 64), "unknown field");
  }
  Claim c;
  for (const char* key : {"id", "title", "source"}) {
    auto it = j.find(key);
    if (it == j.end()) return Status::InvalidArgument(key, "is required");
    if (!it->is_string() || it->get<std::string>().empty() || it->get<std::string>().size() > 1000)
      return Status::InvalidArgument(key, "must be a string of 1 to 1000 characters");
  }
  c.id = j["id"].get<std::string>();
  if (!IsClaimId(c.id)) return Status::InvalidArgument("id", "may hold only A-Z a-z 0-9 . _ - (1 to 100 characters)");
  c.title = j["title"].get<std::string>();
  c.source = j["source"].get<std::string>();
  auto paper = j.find("paper");
  if (paper == j.end()) return Status::InvalidArgument("paper", "is required");
  if (!paper->is_object()) return Status::InvalidArgument("paper", "must be an object {\"text\": ..., numbers}");
  if (!paper->contains("text") || !(*paper)["text"].is_string())
    return Status::InvalidArgument("paper.text", "is required: what the paper reports, in words");
  for (const auto& [key, value] : paper->items()) {
    bool ok = value.is_string() || (value.is_number() && std::isfinite(value.get<double>()));
    if (value.is_array())
      ok = std::all_of(value.begin(), value.end(), [](const json& v) { return v.is_number() || v.is_string(); });
    if (!ok)
      return Status::InvalidArgument("paper." + key.substr(0, 64), "must be a string, a number or an array of them");
  }
  c.paper = *paper;
  auto rule = j.find("rule");
  if (rule == j.end()) return Status::InvalidArgument("rule", "is required");
  SANDSWIM_RETURN_IF_ERROR(CheckRule(*rule, sweeps));
  c.rule = *rule;
  return c;
}

double Param(const Claim& c, const char* name, double fallback) {
  auto it = c.rule.find(name);
  return it != c.rule.end() && it->is_number() ? it->get<double>() : fallback;
}

std::vector<std::string> SweepList(const Claim& c, const char* name) {
  auto it = c.rule.find(name);
  if (it == c.rule.end()) return {};
  if (it->is_string()) return {it->get<std::string>()};
  return it->get<std::vector<std::string>>();
}

// ---- The points of a campaign run --------------------------------------------------------------

std::string Label(const Point& p) {
  switch (p.mode) {
    case Mode::kOscillatory:
      return "Omega = " + Num(p.Omega) + " rad/s, A = " + Num(p.A) + " m, f = " + Num(p.f) + " Hz";
    case Mode::kVibration:
      return "vibration, A = " + Num(p.A) + " m, f = " + Num(p.f) + " Hz";
    case Mode::kRotation:
      return "rotation, omega = " + Num(p.omega) + " rad/s about " + std::string(AxisName(p.axis));
    case Mode::kVibrationRotation:
      return "vibration + rotation about " + std::string(AxisName(p.axis)) + ", omega = " + Num(p.omega) +
             " rad/s, A = " + Num(p.A) + " m, f = " + Num(p.f) + " Hz";
  }
  return "";
}

// One point of a sweep: its sample (over its beds) and its runs.
struct PointView {
  std::string sweep;
  Point point;
  const SweepSample* sample = nullptr;
  std::vector<const ClaimRun*> runs;
  bool usable() const { return sample != nullptr && sample->conclusive && sample->has_uz; }
  bool has_interval() const { return usable() && sample->uz_ci95 > 0; }
};

std::string WhyMissing(const PointView& p) {
  std::string why;
  if (p.sample != nullptr && !p.sample->inconclusive_reason.empty())
    why = "inconclusive: " + p.sample->inconclusive_reason;
  for (const ClaimRun* r : p.runs) {
    std::string one;
    if (r->state == "done") {
      if (r->result && !r->result->conclusive)
        one = "run " + std::to_string(r->run_id) + " inconclusive (" +
              (r->result->inconclusive_reason.empty() ? std::string("no U_z") : r->result->inconclusive_reason) + ")";
    } else if (r->state == "failed") {
      one = "run " + std::to_string(r->run_id) + " failed" + (r->failure.empty() ? "" : " (" + r->failure + ")");
    } else {
      one = "run " + std::to_string(r->run_id) + " " + r->state;
    }
    if (!one.empty()) why += (why.empty() ? "" : "; ") + one;
  }
  if (why.empty()) why = p.runs.empty() ? "no run" : "no conclusive U_z";
  return why;
}

const ClaimSweep* FindSweep(const ClaimInput& in, const std::string& name) {
  for (const ClaimSweep& s : in.sweeps)
    if (s.name == name) return &s;
  return nullptr;
}

// Every point of the sweeps, each once (a point two sweeps share is the first sweep's), in order.
std::vector<PointView> PointsOf(const ClaimInput& in, const std::vector<std::string>& sweeps) {
  std::vector<PointView> out;
  std::set<DriveId> seen;
  for (const std::string& name : sweeps) {
    const ClaimSweep* s = FindSweep(in, name);
    if (s == nullptr) continue;
    std::map<DriveId, size_t> index;
    std::vector<PointView> mine;
    for (const ClaimRun& r : s->runs) {
      auto [it, inserted] = index.emplace(DriveIdOf(r.point), mine.size());
      if (inserted) mine.push_back(PointView{name, r.point, nullptr, {}});
      mine[it->second].runs.push_back(&r);
    }
    for (const SweepSample& sample : s->samples) {
      auto [it, inserted] = index.emplace(DriveIdOf(sample.point), mine.size());
      if (inserted) mine.push_back(PointView{name, sample.point, nullptr, {}});
      mine[it->second].sample = &sample;
    }
    for (PointView& p : mine)
      if (seen.insert(DriveIdOf(p.point)).second) out.push_back(std::move(p));
  }
  return out;
}

void AddMissing(const std::vector<PointView>& points, std::vector<ClaimMissing>& missing) {
  for (const PointView& p : points) {
    if (p.has_interval()) continue;
    bool listed = std::any_of(missing.begin(), missing.end(),
                              [&](const ClaimMissing& m) { return DriveIdOf(m.point) == DriveIdOf(p.point); });
    if (listed) continue;
    ClaimMissing m;
    m.sweep = p.sweep;
    m.point = p.point;
    for (const ClaimRun* r : p.runs) m.run_ids.push_back(r->run_id);
    m.why = p.usable() ? "its U_z has no error (too few whole periods for one)" : WhyMissing(p);
    missing.push_back(std::move(m));
  }
}

// ---- Statistics --------------------------------------------------------------------------------

// The half-width of a sample's interval at the family-wise 95 % level over m comparisons
// (Bonferroni: the two-sided quantile 1 - 0.025 / m), with the degrees of freedom its own 95 %
// interval was made with (recovered from ci95 / stderr = t(0.975, dof)).
double FamilyHalfWidth(const SweepSample& s, int m) {
  if (m <= 1 || s.uz_stderr <= 0 || s.uz_ci95 <= 0) return s.uz_ci95;
  const double ratio = s.uz_ci95 / s.uz_stderr;
  const double q = 1.0 - 0.025 / m;
  if (ratio <= gsl_cdf_ugaussian_Pinv(0.975) * (1 + 1e-9)) return s.uz_stderr * gsl_cdf_ugaussian_Pinv(q);
  double lo = 0.5, hi = 1e7;  // t(0.975, dof) falls as dof grows
  for (int i = 0; i < 200; ++i) {
    const double mid = std::sqrt(lo * hi);
    if (gsl_cdf_tdist_Pinv(0.975, mid) > ratio) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return s.uz_stderr * gsl_cdf_tdist_Pinv(q, std::sqrt(lo * hi));
}

ClaimFigure UzFigure(const PointView& p) {
  ClaimFigure f;
  f.name = "U_z, " + Label(p.point) + " (" + p.sweep + ")";
  f.unit = "m/s";
  if (p.usable()) {
    f.value = p.sample->uz;
    if (p.sample->uz_stderr > 0) f.se = p.sample->uz_stderr;
    if (p.sample->uz_ci95 > 0) {
      f.lo = p.sample->uz - p.sample->uz_ci95;
      f.hi = p.sample->uz + p.sample->uz_ci95;
    }
  } else {
    f.note = WhyMissing(p);
  }
  return f;
}

ClaimFigure ParamFigure(const std::string& name, double v, double se, double t, const std::string& unit) {
  ClaimFigure f;
  f.name = name;
  f.value = v;
  f.se = se;
  f.lo = v - t * se;
  f.hi = v + t * se;
  f.unit = unit;
  return f;
}

Verdict Combine(const std::vector<ClaimPart>& parts) {
  if (parts.empty()) return Verdict::kInconclusive;
  bool all_hold = true;
  for (const ClaimPart& p : parts) {
    if (p.verdict == Verdict::kDiffers) return Verdict::kDiffers;
    all_hold = all_hold && p.verdict == Verdict::kHolds;
  }
  return all_hold ? Verdict::kHolds : Verdict::kInconclusive;
}

// ---- sign ---------------------------------------------------------------------------------------

// +1: the point should rise; -1: sink; 0: no expectation (Omega = 0 under "against_Omega").
int ExpectedSign(const std::string& expect, const Point& p) {
  if (expect == "rise") return 1;
  if (expect == "sink") return -1;
  return p.Omega < 0 ? 1 : p.Omega > 0 ? -1 : 0;
}

ClaimPart SignPart(const std::string& name, const std::vector<PointView>& points, const std::string& expect) {
  ClaimPart part;
  part.name = name;
  int m = 0;
  for (const PointView& p : points) m += p.has_interval() && ExpectedSign(expect, p.point) != 0 ? 1 : 0;
  int holding = 0, open = 0;
  std::string differing, unclear;
  for (const PointView& p : points) {
    ClaimFigure f = UzFigure(p);
    const int sign = ExpectedSign(expect, p.point);
    if (sign == 0) {
      f.note = "Omega = 0: no expected sign";
    } else if (p.has_interval()) {
      const double uz = p.sample->uz, ci = p.sample->uz_ci95;
      const double wide = FamilyHalfWidth(*p.sample, m);
      if (sign * (uz - sign * ci) > 0) {
        f.verdict = Verdict::kHolds;
        ++holding;
      } else if (sign * (uz + sign * wide) < 0) {
        f.verdict = Verdict::kDiffers;
        f.note = "clear of 0 on the other side at the family-wise level (+-" + Num(wide, 3) + " m/s over " +
                 std::to_string(m) + " points)";
        differing += (differing.empty() ? "" : "; ") + Label(p.point) + " (" + p.sweep +
                     "): U_z = " + WithError(uz, p.sample->uz_stderr) + " m/s";
      } else {
        f.verdict = Verdict::kInconclusive;
        f.note = "its 95 % interval holds 0";
        ++open;
        unclear += (unclear.empty() ? "" : "; ") + Label(p.point) + " (" + p.sweep + ")";
      }
    }
    part.figures.push_back(std::move(f));
  }
  const std::string way = expect == "rise" ? "rises" : expect == "sink" ? "sinks" : "moves against Omega";
  if (!differing.empty()) {
    part.verdict = Verdict::kDiffers;
    part.reason = "moves the other way than the paper's: " + differing;
  } else if (m > 0 && holding == m && open == 0) {
    part.verdict = Verdict::kHolds;
    part.reason = "each of the " + std::to_string(m) + " point(s) " + way + ", its 95 % interval clear of 0";
  } else {
    part.verdict = Verdict::kInconclusive;
    part.reason = m == 0 ? "no point has a conclusive U_z with an error"
                         : std::to_string(holding) + " of " + std::to_string(m) + " point(s) " + way + " clear of 0" +
                               (unclear.empty() ? "" : "; the interval holds 0 at " + unclear);
  }
  return part;
}

void EvaluateSign(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  std::vector<PointView> points = PointsOf(in, SweepList(c, "sweeps"));
  AddMissing(points, v.missing);
  v.parts.push_back(SignPart("sign of U_z", points, c.rule.value("expect", "")));
}

// ---- saturation ---------------------------------------------------------------------------------

bool ReachedBoundary(const api::RunResult& r, bool rising) {
  const std::string boundary = rising ? "surface" : "floor";
  return r.stop_reason == boundary || r.window_end == boundary || (rising ? r.broke_surface : r.near_floor);
}

ClaimPart BeyondPart(const Claim& c, const ClaimSweep& s, double beyond) {
  ClaimPart part;
  part.name = "past |Omega| = " + Num(beyond) + " rad/s: the surface (rising) or the floor (sinking)";
  const double min_duration = Param(c, "min_duration_s", 4.0);
  int reached = 0, not_reached = 0, unknown = 0;
  std::string detail;
  for (const ClaimRun& r : s.runs) {
    if (!(std::fabs(r.point.Omega) > beyond)) continue;
    const bool rising = r.point.Omega < 0;
    ClaimFigure f;
    f.name = "run " + std::to_string(r.run_id) + ": " + Label(r.point) + ", replicate " + std::to_string(r.replicate);
    if (r.state != "done" || !r.result) {
      f.verdict = Verdict::kInconclusive;
      f.note = r.state + (r.failure.empty() ? "" : ": " + r.failure);
      ++unknown;
    } else {
      f.value = r.result->sim_time_s;
      f.unit = "s simulated";
      f.note = "stop: " + r.result->stop_reason + (r.result->stop_note.empty() ? "" : " (" + r.result->stop_note + ")");
      if (ReachedBoundary(*r.result, rising)) {
        f.verdict = Verdict::kHolds;
        ++reached;
      } else if (r.result->stop_reason == "duration" && r.result->sim_time_s >= min_duration - 1e-9) {
        f.verdict = Verdict::kDiffers;
        ++not_reached;
        detail += (detail.empty() ? "" : "; ") + std::string("run ") + std::to_string(r.run_id) + " ran " +
                  Num(r.result->sim_time_s, 3) + " s without reaching the " + (rising ? "surface" : "floor");
      } else {
        f.verdict = Verdict::kInconclusive;
        f.note += "; it ended after " + Num(r.result->sim_time_s, 3) + " s, shorter than " + Num(min_duration) +
                  " s, before reaching a boundary";
        ++unknown;
      }
    }
    part.figures.push_back(std::move(f));
  }
  if (not_reached > 0) {
    part.verdict = Verdict::kDiffers;
    part.reason = detail;
  } else if (reached > 0 && unknown == 0) {
    part.verdict = Verdict::kHolds;
    part.reason = "each of the " + std::to_string(reached) + " run(s) reached its boundary";
  } else {
    part.reason = part.figures.empty() ? "the sweep has no point past |Omega| = " + Num(beyond) + " rad/s"
                                       : std::to_string(unknown) + " run(s) ended early or did not finish; " +
                                             std::to_string(reached) + " reached the boundary";
  }
  return part;
}

void EvaluateSaturation(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  const std::string name = c.rule.value("sweep", "");
  const ClaimSweep* s = FindSweep(in, name);
  if (s == nullptr) {
    v.parts.push_back({"eq. 8", Verdict::kInconclusive, "the campaign run has no sweep \"" + name + "\"", {}});
    return;
  }
  AddMissing(PointsOf(in, {name}), v.missing);
  const double fraction = Param(c, "reached_fraction", 0.95);
  const int min_points = static_cast<int>(Param(c, "min_points", 4));
  const double k = -std::log(1 - fraction);
  for (const char* branch : {"rising", "sinking"}) {
    const BranchFit* b = nullptr;
    for (const BranchFit& x : s->fits.branches)
      if (x.branch == branch) b = &x;
    const std::string grows = std::string(branch) + ": |U_z| grows with |Omega| (C1 > 0)";
    const std::string saturates = std::string(branch) + ": saturates within the swept |Omega|";
    if (b == nullptr || b->points < min_points || !b->saturation) {
      const std::string why =
          b == nullptr ? "no conclusive point"
          : b->points < min_points
              ? std::to_string(b->points) + " conclusive point(s), fewer than " + std::to_string(min_points)
              : "eq. 8 could not be fitted: " + b->error;
      v.parts.push_back({grows, Verdict::kInconclusive, why, {}});
      v.parts.push_back({saturates, Verdict::kInconclusive, why, {}});
      continue;
    }
    const SaturationFit& fit = *b->saturation;
    const double t = StudentT95(std::max(fit.n - 2, 1));
    ClaimPart g{grows, Verdict::kInconclusive, "", {}};
    g.figures.push_back(ParamFigure("C1 (" + std::string(branch) + ")", fit.c1, fit.c1_stderr, t, "m/s"));
    g.figures.push_back(ParamFigure("C2 (" + std::string(branch) + ")", fit.c2, fit.c2_stderr, t, "s/rad"));
    const double c1_lo = fit.c1 - t * fit.c1_stderr, c1_hi = fit.c1 + t * fit.c1_stderr;
    g.verdict = c1_lo > 0 ? Verdict::kHolds : c1_hi < 0 ? Verdict::kDiffers : Verdict::kInconclusive;
    g.reason = "C1 = " + WithError(fit.c1, fit.c1_stderr) + " m/s, 95 % interval [" + Num(c1_lo, 3) + ", " +
               Num(c1_hi, 3) + "] (" + std::to_string(fit.n) + " points, R^2 = " + Num(fit.r2, 3) + ")";
    v.parts.push_back(std::move(g));

    double max_abs = 0;
    for (const SweepSample& x : s->samples)
      if (x.conclusive && ((x.point.Omega < 0) == (std::string(branch) == "rising")) && x.point.Omega != 0)
        max_abs = std::max(max_abs, std::fabs(x.point.Omega));
    ClaimPart sat{saturates, Verdict::kInconclusive, "", {}};
    const double c2_lo = fit.c2 - t * fit.c2_stderr, c2_hi = fit.c2 + t * fit.c2_stderr;
    ClaimFigure at;
    at.name = "|Omega| where U_z reaches " + Num(100 * fraction) + " % of C1 (" + branch + ")";
    at.unit = "rad/s";
    if (fit.c2 > 0) at.value = k / fit.c2;
    if (c2_hi > 0) at.lo = k / c2_hi;
    at.hi = c2_lo > 0 ? k / c2_lo : kInf;
    at.note = "the swept |Omega| reaches " + Num(max_abs) + " rad/s";
    if (!(c2_hi > 0)) {
      sat.verdict = Verdict::kDiffers;
      sat.reason = "C2 = " + WithError(fit.c2, fit.c2_stderr) + " s/rad: U_z does not saturate (C2 <= 0)";
    } else if (*at.hi <= max_abs) {
      sat.verdict = Verdict::kHolds;
      sat.reason = Num(100 * fraction) + " % of C1 is reached by |Omega| = " + Num(*at.lo, 3) + " .. " +
                   Num(*at.hi, 3) + " rad/s, within the swept " + Num(max_abs) + " rad/s";
    } else if (*at.lo > max_abs) {
      sat.verdict = Verdict::kDiffers;
      sat.reason = Num(100 * fraction) + " % of C1 is reached only past |Omega| = " + Num(*at.lo, 3) +
                   " rad/s, beyond the swept " + Num(max_abs) + " rad/s: no saturation in the range";
    } else {
      sat.reason = Num(100 * fraction) + " % of C1 is reached somewhere in |Omega| = " + Num(*at.lo, 3) + " .. " +
                   (std::isinf(*at.hi) ? std::string("infinity") : Num(*at.hi, 3)) +
                   " rad/s: not decided within the swept " + Num(max_abs) + " rad/s";
    }
    sat.figures.push_back(std::move(at));
    v.parts.push_back(std::move(sat));
  }
  if (c.rule.contains("beyond_abs_Omega")) v.parts.push_back(BeyondPart(c, *s, Param(c, "beyond_abs_Omega", 320)));
}

// ---- linear_in_A --------------------------------------------------------------------------------

// chi^2 of points about the line U_z = c3 A, each with its own variance plus (A stderr_c3)^2 (0 for
// the points the line was fitted to), and its upper-tail probability with `dof` degrees of freedom.
struct LineCheck {
  double chi2 = 0;
  int dof = 0;
  double p = 1;
};
LineCheck AboutLine(const std::vector<const SweepSample*>& points, double c3, double c3_se, int dof) {
  LineCheck out;
  for (const SweepSample* s : points) {
    const double r = s->uz - c3 * s->point.A;
    out.chi2 += r * r / (s->uz_stderr * s->uz_stderr + s->point.A * s->point.A * c3_se * c3_se);
  }
  out.dof = dof;
  out.p = dof > 0 ? gsl_cdf_chisq_Q(out.chi2, dof) : 1.0;
  return out;
}

ClaimFigure LineFigure(const std::string& name, const LineCheck& l) {
  ClaimFigure f;
  f.name = name;
  f.value = l.p;
  f.unit = "p";
  f.note = "chi^2 = " + Num(l.chi2, 3) + " for " + std::to_string(l.dof) + " degrees of freedom";
  return f;
}

constexpr double kLineLevel = 0.01;  // a line is refused when chi^2's upper tail is below this

void EvaluateLinear(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  const std::string name = c.rule.value("sweep", "");
  const ClaimSweep* s = FindSweep(in, name);
  if (s == nullptr) {
    v.parts.push_back({"eq. 9", Verdict::kInconclusive, "the campaign run has no sweep \"" + name + "\"", {}});
    return;
  }
  AddMissing(PointsOf(in, {name}), v.missing);
  const bool with_break = c.rule.contains("sinking_linear_to_A");
  const double brk = Param(c, "sinking_linear_to_A", 0), tol = Param(c, "break_tolerance_m", 0.015);
  for (const char* branch : {"rising", "sinking"}) {
    const bool rising = std::string(branch) == "rising";
    if (!rising && !with_break) continue;
    ClaimPart part;
    part.name = rising ? "rising: U_z = C3 A over the swept A"
                       : "sinking: linear in A up to A = " + Num(brk) + " m, not past " + Num(brk + tol) + " m";
    // The branch's conclusive points with an error, by A.
    std::vector<const SweepSample*> points, lower, upper;
    for (const SweepSample& x : s->samples)
      if (x.conclusive && x.has_uz && x.uz_stderr > 0 && x.point.Omega != 0 && (x.point.Omega < 0) == rising)
        points.push_back(&x);
    std::sort(points.begin(), points.end(),
              [](const SweepSample* a, const SweepSample* b) { return a->point.A < b->point.A; });
    for (const SweepSample* x : points) {
      if (x->point.A <= brk * (1 + 1e-9)) lower.push_back(x);
      if (x->point.A > (brk + tol) * (1 + 1e-9)) upper.push_back(x);
    }
    // Rising: the sweep's own fit (core/fit.h, over every A while the points stay in its band).
    // Sinking: the same law fitted to the points up to the paper's A.
    std::optional<LinearFit> fitted;
    std::string error;
    if (rising) {
      for (const BranchFit& x : s->fits.branches)
        if (x.branch == branch) {
          if (x.linear) fitted = *x.linear;
          error = x.error;
        }
    } else if (lower.size() >= 3) {
      std::vector<double> a, y, e;
      for (const SweepSample* x : lower) {
        a.push_back(x->point.A);
        y.push_back(x->uz);
        e.push_back(x->uz_stderr);
      }
      auto r = FitThroughOrigin(a, y, e);
      if (r.ok()) {
        fitted = *r;
      } else {
        error = r.status().reason();
      }
    } else {
      error = std::to_string(lower.size()) + " conclusive point(s) up to A = " + Num(brk) + " m, fewer than 3";
    }
    if (!fitted) {
      part.reason = points.empty() ? "no conclusive point with an error" : "eq. 9 could not be fitted: " + error;
      v.parts.push_back(std::move(part));
      continue;
    }
    const LinearFit& fit = *fitted;
    const double t = StudentT95(std::max(fit.n - 1, 1));
    part.figures.push_back(ParamFigure(std::string("C3 (") + branch + ")", fit.c3, fit.c3_stderr, t, "1/s"));
    ClaimFigure range;
    range.name = std::string("A over which the line holds (") + branch + ")";
    range.lo = fit.a_from;
    range.hi = fit.a_to;
    range.unit = "m";
    range.note = std::to_string(fit.n) + " of " + std::to_string(fit.n_total) +
                 " points in the line's 3-sigma prediction band (R^2 = " + Num(fit.r2, 3) + ")";
    part.figures.push_back(range);
    const int sign = rising ? 1 : -1;
    const double lo = fit.c3 - t * fit.c3_stderr, hi = fit.c3 + t * fit.c3_stderr;
    const std::string c3 =
        "C3 = " + WithError(fit.c3, fit.c3_stderr) + " 1/s, 95 % interval [" + Num(lo, 3) + ", " + Num(hi, 3) + "]";
    if (lo <= 0 && hi >= 0) {
      part.reason = c3 + ": holds 0, a line cannot be told from no dependence on A";
    } else if (sign * fit.c3 < 0) {
      part.verdict = Verdict::kDiffers;
      part.reason = c3 + ": U_z moves the other way than the paper's as A grows";
    } else if (rising) {
      const LineCheck all = AboutLine(points, fit.c3, 0, static_cast<int>(points.size()) - 1);
      part.figures.push_back(LineFigure("the rising points about the line", all));
      double next = kInf;
      for (const SweepSample* x : points)
        if (x->point.A > fit.a_to * (1 + 1e-9)) next = std::min(next, x->point.A);
      if (fit.n < fit.n_total) {
        part.verdict = Verdict::kDiffers;
        part.reason = c3 + "; not linear over the swept A: the point at A = " + Num(next) +
                      " m leaves the line's 3-sigma band (the line holds to A = " + Num(fit.a_to) + " m)";
      } else if (all.p < kLineLevel) {
        part.verdict = Verdict::kDiffers;
        part.reason = c3 + "; not a line: chi^2 = " + Num(all.chi2, 3) + " for " + std::to_string(all.dof) +
                      " degrees of freedom about it (p = " + Num(all.p, 2) + ")";
      } else {
        part.verdict = Verdict::kHolds;
        part.reason =
            c3 + "; every point up to A = " + Num(fit.a_to) + " m lies on the line (chi^2 p = " + Num(all.p, 2) + ")";
      }
    } else {
      const LineCheck below = AboutLine(lower, fit.c3, 0, static_cast<int>(lower.size()) - 1);
      const LineCheck above = AboutLine(upper, fit.c3, fit.c3_stderr, static_cast<int>(upper.size()));
      part.figures.push_back(LineFigure("the points up to A = " + Num(brk) + " m about their line", below));
      if (!upper.empty())
        part.figures.push_back(LineFigure("the points past A = " + Num(brk + tol) + " m about that line", above));
      if (below.p < kLineLevel) {
        part.verdict = Verdict::kDiffers;
        part.reason = c3 + "; not linear up to A = " + Num(brk) + " m: chi^2 = " + Num(below.chi2, 3) + " for " +
                      std::to_string(below.dof) + " degrees of freedom (p = " + Num(below.p, 2) + ")";
      } else if (upper.empty()) {
        part.reason = c3 + "; no conclusive point past A = " + Num(brk + tol) + " m to test";
      } else if (above.p < kLineLevel) {
        part.verdict = Verdict::kHolds;
        part.reason = c3 + " up to A = " + Num(brk) + " m (chi^2 p = " + Num(below.p, 2) + "); the " +
                      std::to_string(upper.size()) + " point(s) past A = " + Num(brk + tol) +
                      " m leave that line (chi^2 p = " + Num(above.p, 2) + ")";
      } else {
        part.verdict = Verdict::kDiffers;
        part.reason = c3 + "; the points past A = " + Num(brk + tol) +
                      " m stay on the line (chi^2 p = " + Num(above.p, 2) +
                      "): no end of linearity near A = " + Num(brk) + " m";
      }
    }
    v.parts.push_back(std::move(part));
  }
}

// ---- interior_maximum ---------------------------------------------------------------------------

void EvaluateInteriorMaximum(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  const std::string name = c.rule.value("sweep", "");
  const double paper_fc = Param(c, "f_c_hz", 0);
  ClaimPart part;
  part.name = "the rising rate peaks at an interior f";
  const ClaimSweep* s = FindSweep(in, name);
  if (s == nullptr) {
    part.reason = "the campaign run has no sweep \"" + name + "\"";
    v.parts.push_back(std::move(part));
    return;
  }
  std::vector<PointView> rising;
  for (PointView& p : PointsOf(in, {name}))
    if (p.point.Omega < 0) rising.push_back(std::move(p));
  std::sort(rising.begin(), rising.end(), [](const PointView& a, const PointView& b) { return a.point.f < b.point.f; });
  AddMissing(rising, v.missing);
  for (const PointView& p : rising) part.figures.push_back(UzFigure(p));
  const bool complete = std::all_of(rising.begin(), rising.end(), [](const PointView& p) { return p.has_interval(); });
  if (!complete || rising.size() < 3) {
    part.reason = rising.size() < 3 ? "fewer than 3 rising points in f"
                                    : "a rising point has no conclusive U_z with an error: the maximum over the swept "
                                      "f cannot be located";
    v.parts.push_back(std::move(part));
    return;
  }
  size_t top = 0;
  for (size_t i = 1; i < rising.size(); ++i)
    if (rising[i].sample->uz > rising[top].sample->uz) top = i;
  auto above = [&](size_t i, size_t j, double* diff, double* half) {
    *diff = rising[i].sample->uz - rising[j].sample->uz;
    *half = std::hypot(rising[i].sample->uz_ci95, rising[j].sample->uz_ci95);
    return *diff > *half;
  };
  const double f_top = rising[top].point.f;
  double d1 = 0, h1 = 0, d2 = 0, h2 = 0;
  if (top == 0 || top + 1 == rising.size()) {
    const size_t neighbour = top == 0 ? 1 : top - 1;
    if (above(top, neighbour, &d1, &h1)) {
      part.verdict = Verdict::kDiffers;
      part.reason = "no interior maximum in the swept range: the rising rate is largest at the edge f = " + Num(f_top) +
                    " Hz, above f = " + Num(rising[neighbour].point.f) + " Hz by " + Num(d1, 3) + " m/s (> " +
                    Num(h1, 3) + ", their combined 95 % half-widths)";
    } else {
      part.reason = "the largest rising rate is at the edge f = " + Num(f_top) + " Hz but not above its neighbour by " +
                    "more than their intervals";
    }
    v.parts.push_back(std::move(part));
    return;
  }
  const bool over_low = above(top, 0, &d1, &h1), over_high = above(top, rising.size() - 1, &d2, &h2);
  if (!over_low || !over_high) {
    part.reason = "the largest rising rate, at f = " + Num(f_top) + " Hz, is not above both edge values by more than " +
                  "their combined 95 % half-widths (" + Num(d1, 3) + " vs " + Num(h1, 3) + ", " + Num(d2, 3) + " vs " +
                  Num(h2, 3) + " m/s)";
    v.parts.push_back(std::move(part));
    return;
  }
  const BranchFit* b = nullptr;
  for (const BranchFit& x : s->fits.branches)
    if (x.branch == "rising") b = &x;
  if (b == nullptr || !b->fastest_rise) {
    part.reason = "an interior maximum at f = " + Num(f_top) + " Hz, but f_c could not be fitted" +
                  (b == nullptr ? std::string() : ": " + b->error);
    v.parts.push_back(std::move(part));
    return;
  }
  const FastestRise& fr = *b->fastest_rise;
  const double f_lo = rising[top - 1].point.f, f_hi = rising[top + 1].point.f;
  ClaimFigure fc;
  fc.name = "f_c, the fastest rise";
  fc.value = fr.f_c;
  fc.unit = "Hz";
  if (fr.f_c_stderr > 0) {
    const double z = gsl_cdf_ugaussian_Pinv(0.975);
    fc.se = fr.f_c_stderr;
    fc.lo = std::clamp(fr.f_c - z * fr.f_c_stderr, f_lo, f_hi);
    fc.hi = std::clamp(fr.f_c + z * fr.f_c_stderr, f_lo, f_hi);
  } else {
    fc.lo = f_lo;
    fc.hi = f_hi;
    fc.note = "no point errors for the quadratic: the interval is the neighbours' f";
  }
  // The paper's f_c is read off its grid of f: it stands for f_c -+ the tolerance.
  const double tol = Param(c, "f_c_tolerance_hz", 0);
  const bool inside = *fc.hi >= paper_fc - tol - 1e-12 && *fc.lo <= paper_fc + tol + 1e-12;
  fc.verdict = inside ? Verdict::kHolds : Verdict::kDiffers;
  part.verdict = *fc.verdict;
  part.reason = "an interior maximum: f_c = " + Num(fr.f_c, 3) + " Hz, 95 % interval [" + Num(*fc.lo, 3) + ", " +
                Num(*fc.hi, 3) + "] Hz, " + (inside ? "meeting" : "apart from") + " the paper's " + Num(paper_fc) +
                (tol > 0 ? " +- " + Num(tol) : std::string()) + " Hz";
  part.figures.push_back(std::move(fc));
  v.parts.push_back(std::move(part));
}

// ---- grain_count --------------------------------------------------------------------------------

void EvaluateGrainCount(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  const double paper = Param(c, "paper_grains", 0), paper_m3 = Param(c, "paper_bed_m3", 0);
  const double tol = Param(c, "tolerance_rel", 0.1);
  const double d = kMaterials.d_grain;
  const double v_grain = M_PI / 6 * d * d * d, v_so = M_PI / 6 * std::pow(kMaterials.d_so, 3);
  ClaimPart part;
  part.name = "grains in the bed against the paper's " + Num(paper);
  ClaimFigure implied;
  implied.name = "solid fraction the paper's count implies in " + Num(paper_m3) + " m^3";
  implied.value = paper * v_grain / (paper_m3 - v_so);
  implied.note = "spheres pack randomly to at most about 0.64";
  part.figures.push_back(implied);
  const Scale* scale = FindScale(in.scale);
  double lo = kInf, hi = 0;
  int prepared = 0;
  std::string pending;
  for (const ClaimBed& bed : in.beds) {
    if (bed.state != "done" || !bed.grains || scale == nullptr) {
      pending += (pending.empty() ? "" : ", ") + std::string("bed ") + std::to_string(bed.id) + " " + bed.state;
      continue;
    }
    ++prepared;
    const double n = static_cast<double>(*bed.grains);
    const bool nominal = !bed.bed_height;
    const double surface = (nominal ? scale->z_bed_top - scale->z_floor : *bed.bed_height) + d / 2;
    auto count_at = [&](double h) { return n * (paper_m3 - v_so) / (scale->x_len * scale->y_len * h - v_so); };
    auto fraction_at = [&](double h) { return n * v_grain / (scale->x_len * scale->y_len * h - v_so); };
    ClaimFigure grains;
    grains.name = "bed " + std::to_string(bed.id) + " (replicate " + std::to_string(bed.replicate) + "): grains";
    grains.value = n;
    part.figures.push_back(grains);
    ClaimFigure phi;
    phi.name = "bed " + std::to_string(bed.id) + ": solid fraction";
    phi.value = fraction_at(surface);
    phi.lo = fraction_at(surface + d);
    phi.hi = fraction_at(surface - d);
    phi.note = "the surface at " + Num(surface, 3) + " +- " + Num(d) + " m above the floor" +
               (nominal ? " (the scale's nominal bed top: this bed has no measured height)" : "");
    part.figures.push_back(phi);
    ClaimFigure eq;
    eq.name = "bed " + std::to_string(bed.id) + ": grains at that fraction in the paper's " + Num(paper_m3) + " m^3";
    eq.value = count_at(surface);
    eq.lo = count_at(surface + d);
    eq.hi = count_at(surface - d);
    part.figures.push_back(eq);
    lo = std::min(lo, *eq.lo);
    hi = std::max(hi, *eq.hi);
  }
  if (prepared == 0) {
    part.reason = scale == nullptr ? "unknown scale \"" + in.scale + "\""
                                   : "no prepared bed" + (pending.empty() ? std::string() : " (" + pending + ")");
  } else if (paper >= lo * (1 - tol) && paper <= hi * (1 + tol)) {
    part.verdict = Verdict::kHolds;
    part.reason = "the beds' packing gives " + Num(lo, 3) + " .. " + Num(hi, 3) + " grains in " + Num(paper_m3) +
                  " m^3, within " + Num(100 * tol) + " % of the paper's " + Num(paper);
  } else {
    part.verdict = Verdict::kDiffers;
    part.reason = "the beds' packing gives " + Num(lo, 3) + " .. " + Num(hi, 3) + " grains in " + Num(paper_m3) +
                  " m^3, not the paper's " + Num(paper) + " (which would need a solid fraction of " +
                  Num(*implied.value, 3) + ")";
  }
  v.parts.push_back(std::move(part));
}

// ---- modes --------------------------------------------------------------------------------------

void EvaluateModes(const Claim& c, const ClaimInput& in, ClaimVerdict& v) {
  std::vector<PointView> rises = PointsOf(in, SweepList(c, "rises"));
  AddMissing(rises, v.missing);
  v.parts.push_back(SignPart("vibration alone rises", rises, "rise"));

  // The fastest mode: its U_z against each other's.
  const std::string fastest = c.rule.value("fastest", "");
  std::vector<PointView> best = PointsOf(in, {fastest});
  std::vector<std::string> others;
  for (const std::string& s : SweepList(c, "fastest_among"))
    if (s != fastest) others.push_back(s);
  std::vector<PointView> rivals = PointsOf(in, others);
  AddMissing(best, v.missing);
  AddMissing(rivals, v.missing);
  ClaimPart fast;
  fast.name = fastest + " rises fastest";
  if (best.empty() || !best[0].has_interval()) {
    fast.reason = fastest + " has no conclusive U_z with an error";
  } else {
    const SweepSample& b = *best[0].sample;
    fast.figures.push_back(UzFigure(best[0]));
    const int m = static_cast<int>(rivals.size());
    int faster = 0;
    std::string slower;
    for (const PointView& r : rivals) {
      ClaimFigure f = UzFigure(r);
      if (r.has_interval()) {
        const double diff = b.uz - r.sample->uz, half = std::hypot(b.uz_ci95, r.sample->uz_ci95);
        const double wide = std::hypot(FamilyHalfWidth(b, m), FamilyHalfWidth(*r.sample, m));
        if (diff > half) {
          f.verdict = Verdict::kHolds;
          ++faster;
        } else if (diff < -wide) {
          f.verdict = Verdict::kDiffers;
          slower += (slower.empty() ? "" : ", ") + r.sweep;
        } else {
          f.verdict = Verdict::kInconclusive;
        }
        f.note = fastest + " minus this: " + Num(diff, 3) + " m/s (combined 95 % half-width " + Num(half, 3) + ")";
      }
      fast.figures.push_back(std::move(f));
    }
    if (!slower.empty()) {
      fast.verdict = Verdict::kDiffers;
      fast.reason = fastest + " rises slower than " + slower + " beyond their intervals (family-wise over " +
                    std::to_string(m) + ")";
    } else if (faster == m) {
      fast.verdict = Verdict::kHolds;
      fast.reason = fastest + " rises faster than each of the " + std::to_string(m) +
                    " other mode(s), beyond their "
                    "combined 95 % half-widths";
    } else {
      fast.reason = fastest + " is faster than " + std::to_string(faster) + " of " + std::to_string(m) +
                    " other mode(s) beyond their intervals";
    }
  }
  v.parts.push_back(std::move(fast));

  // Stays near its initial x: x drift of every bed's run, as measured (x_drift has no error).
  ClaimPart near;
  const double within = Param(c, "x_within_m", 0.02);
  near.name = fastest + " stays within " + Num(within) + " m of its initial x";
  int done = 0, beyond = 0;
  if (const ClaimSweep* s = FindSweep(in, fastest)) {
    for (const ClaimRun& r : s->runs) {
      if (r.state != "done" || !r.result) continue;
      ++done;
      ClaimFigure f;
      f.name = "x drift, run " + std::to_string(r.run_id) + " (replicate " + std::to_string(r.replicate) + ")";
      f.value = r.result->x_drift;
      f.unit = "m";
      f.verdict = std::fabs(r.result->x_drift) <= within ? Verdict::kHolds : Verdict::kDiffers;
      beyond += *f.verdict == Verdict::kDiffers ? 1 : 0;
      near.figures.push_back(std::move(f));
    }
  }
  near.verdict = done == 0 ? Verdict::kInconclusive : beyond > 0 ? Verdict::kDiffers : Verdict::kHolds;
  near.reason = done == 0
                    ? "no finished run"
                    : std::to_string(done - beyond) + " of " + std::to_string(done) + " run(s) within " + Num(within) +
                          " m (x drift has no error "
                          "estimate: compared as measured)";
  v.parts.push_back(std::move(near));

  // z oscillates at f with an x component of omega, smoothly without one.
  ClaimPart osc;
  const double ratio = Param(c, "osc_ratio", 2.0);
  osc.name = "z oscillates strongly at f when omega has an x component";
  auto amplitudes = [&](const std::vector<std::string>& sweeps, bool with, int* unfinished) {
    std::vector<double> a;
    for (const std::string& name : sweeps) {
      const ClaimSweep* s = FindSweep(in, name);
      if (s == nullptr) continue;
      for (const ClaimRun& r : s->runs) {
        if (r.state != "done" || !r.result) {
          ++*unfinished;
          continue;
        }
        a.push_back(r.result->z_osc_amplitude);
        ClaimFigure f;
        f.name = "z amplitude at f, " + name + " run " + std::to_string(r.run_id) + (with ? " (x component)" : "");
        f.value = r.result->z_osc_amplitude;
        f.unit = "m";
        osc.figures.push_back(std::move(f));
      }
    }
    return a;
  };
  int unfinished = 0;
  std::vector<double> with = amplitudes(SweepList(c, "z_osc_with"), true, &unfinished);
  std::vector<double> without = amplitudes(SweepList(c, "z_osc_without"), false, &unfinished);
  if (with.empty() || without.empty()) {
    osc.reason = "no finished run on one side";
  } else {
    const double min_with = *std::min_element(with.begin(), with.end());
    const double max_without = *std::max_element(without.begin(), without.end());
    const std::string numbers = "smallest amplitude with an x component " + Num(min_with, 3) + " m, largest without " +
                                Num(max_without, 3) + " m";
    if (min_with <= max_without) {
      osc.verdict = Verdict::kDiffers;
      osc.reason = numbers + ": not larger";
    } else if (min_with >= ratio * max_without && unfinished == 0) {
      osc.verdict = Verdict::kHolds;
      osc.reason = numbers + ": at least " + Num(ratio) + " times";
    } else {
      osc.reason = numbers + (unfinished > 0 ? "; " + std::to_string(unfinished) + " run(s) not finished" : "") +
                   (min_with < ratio * max_without ? ": larger, but less than " + Num(ratio) + " times" : "");
    }
  }
  v.parts.push_back(std::move(osc));

  if (c.rule.contains("x_osc_with")) {
    v.parts.push_back({"x oscillates strongly at f when omega has a z component",
                       Verdict::kInconclusive,
                       "the run analysis measures x's drift, not its amplitude at f: not decided",
                       {}});
  }
}

}  // namespace claim_rules
}  // namespace

std::vector<std::string> ClaimKinds() {
  std::vector<std::string> out;
  for (const auto& k : claim_rules::Kinds()) out.push_back(k.kind);
  return out;
}

std::vector<std::string> ClaimRuleParams(const std::string& kind, bool required_only) {
  std::vector<std::string> out;
  for (const auto& k : claim_rules::Kinds()) {
    if (kind != k.kind) continue;
    for (const auto& p : k.params)
      if (p.required || !required_only) out.push_back(p.name);
  }
  return out;
}

Result<std::vector<Claim>> ParseClaims(const nlohmann::json& j, const std::vector<std::string>& sweep_names) {
  if (!j.is_array()) return Status::InvalidArgument("", "must be an array of claims");
  std::vector<Claim> out;
  for (size_t i = 0; i < j.size(); ++i) {
    const std::string path = "[" + std::to_string(i) + "]";
    auto c = claim_rules::ParseOne(j[i], sweep_names);
    if (!c.ok()) {
      const Status& s = c.status();
      return Status(s.code(), s.reason(), s.field().empty() ? path : path + "." + s.field());
    }
    for (const Claim& other : out)
      if (other.id == c->id) return Status::InvalidArgument(path + ".id", "repeats claim \"" + c->id + "\"");
    out.push_back(std::move(c).value());
  }
  return out;
}

nlohmann::json ClaimToJson(const Claim& c) {
  return {{"id", c.id}, {"title", c.title}, {"source", c.source}, {"paper", c.paper}, {"rule", c.rule}};
}

const char* VerdictName(Verdict v) {
  switch (v) {
    case Verdict::kHolds:
      return "holds";
    case Verdict::kDiffers:
      return "differs";
    case Verdict::kInconclusive:
      return "inconclusive";
  }
  return "inconclusive";
}

std::vector<ClaimVerdict> EvaluateClaims(const std::vector<Claim>& claims, const ClaimInput& input) {
  std::vector<ClaimVerdict> out;
  for (const Claim& c : claims) {
    ClaimVerdict v;
    v.claim = c;
    const std::string kind = c.kind();
    if (kind == "sign") {
      claim_rules::EvaluateSign(c, input, v);
    } else if (kind == "saturation") {
      claim_rules::EvaluateSaturation(c, input, v);
    } else if (kind == "linear_in_A") {
      claim_rules::EvaluateLinear(c, input, v);
    } else if (kind == "interior_maximum") {
      claim_rules::EvaluateInteriorMaximum(c, input, v);
    } else if (kind == "grain_count") {
      claim_rules::EvaluateGrainCount(c, input, v);
    } else if (kind == "modes") {
      claim_rules::EvaluateModes(c, input, v);
    }
    v.verdict = claim_rules::Combine(v.parts);
    const ClaimPart* first = nullptr;
    for (const ClaimPart& p : v.parts)
      if (first == nullptr && p.verdict == v.verdict) first = &p;
    if (v.verdict == Verdict::kHolds && !v.missing.empty()) {
      // Never a verdict from too little: what was measured agrees, but not everything was.
      v.verdict = Verdict::kInconclusive;
      v.reason = "what was measured agrees, but " + std::to_string(v.missing.size()) +
                 " point(s) have no conclusive U_z (listed under missing)";
    } else if (v.verdict == Verdict::kHolds) {
      v.reason = "every part holds";
      if (v.parts.size() == 1) v.reason = v.parts[0].reason;
    } else if (first != nullptr) {
      v.reason = first->name + ": " + first->reason;
    } else {
      v.reason = "no rule of kind \"" + kind + "\"";
    }
    if (v.verdict == Verdict::kInconclusive && !v.missing.empty() && v.reason.find("missing") == std::string::npos)
      v.reason += " (" + std::to_string(v.missing.size()) + " point(s) missing)";
    out.push_back(std::move(v));
  }
  return out;
}

std::string DescribeFigure(const ClaimFigure& f) {
  if (!f.value && !f.lo) return f.note.empty() ? "–" : f.note;
  std::string text;
  if (f.value) text = f.se ? WithError(*f.value, *f.se) : Num(*f.value, 4);
  if (f.lo && f.hi) {
    const std::string hi = std::isinf(*f.hi) ? std::string("infinity") : Num(*f.hi, 3);
    text += (text.empty() ? "" : " ") + std::string("[") + Num(*f.lo, 3) + ", " + hi + "]";
  }
  if (!f.unit.empty()) text += " " + f.unit;
  return text;
}

VerdictCounts CountVerdicts(const std::vector<ClaimVerdict>& verdicts) {
  VerdictCounts c;
  for (const ClaimVerdict& v : verdicts) {
    switch (v.verdict) {
      case Verdict::kHolds:
        ++c.holds;
        break;
      case Verdict::kDiffers:
        ++c.differs;
        break;
      case Verdict::kInconclusive:
        ++c.inconclusive;
        break;
    }
  }
  return c;
}

std::string DescribeClaimPoint(const Point& point) { return claim_rules::Label(point); }

std::string DescribePaperNumbers(const nlohmann::json& paper) {
  std::string out;
  if (!paper.is_object()) return out;
  auto text = [](const nlohmann::json& x) {
    return x.is_number() ? Num(x.get<double>(), 6) : x.is_string() ? x.get<std::string>() : x.dump();
  };
  for (const auto& [key, value] : paper.items()) {
    if (key == "text") continue;
    std::string v;
    if (value.is_array()) {
      for (const auto& x : value) v += (v.empty() ? "" : ", ") + text(x);
    } else {
      v = text(value);
    }
    out += (out.empty() ? "" : "; ") + key + " = " + v;
  }
  return out;
}

nlohmann::json ClaimVerdictToJson(const ClaimVerdict& v) {
  using nlohmann::json;
  json j = ClaimToJson(v.claim);
  j["verdict"] = VerdictName(v.verdict);
  j["reason"] = v.reason;
  json parts = json::array();
  for (const ClaimPart& p : v.parts) {
    json figures = json::array();
    for (const ClaimFigure& f : p.figures) {
      json fj = {{"name", f.name}, {"unit", f.unit}, {"note", f.note}, {"text", DescribeFigure(f)}};
      auto put = [&](const char* key, const std::optional<double>& x) {
        if (x && std::isfinite(*x)) fj[key] = *x;
      };
      put("value", f.value);
      put("stderr", f.se);
      put("lo", f.lo);
      put("hi", f.hi);
      if (f.hi && std::isinf(*f.hi)) fj["hi"] = nullptr;  // unbounded
      if (f.verdict) fj["verdict"] = VerdictName(*f.verdict);
      figures.push_back(std::move(fj));
    }
    parts.push_back(
        {{"name", p.name}, {"verdict", VerdictName(p.verdict)}, {"reason", p.reason}, {"figures", figures}});
  }
  j["parts"] = std::move(parts);
  json missing = json::array();
  for (const ClaimMissing& m : v.missing) {
    missing.push_back(
        {{"sweep", m.sweep}, {"point", DescribeClaimPoint(m.point)}, {"run_ids", m.run_ids}, {"why", m.why}});
  }
  j["missing"] = std::move(missing);
  return j;
}

}  // namespace sandswim
