#include "core/sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <map>
#include <set>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "core/deck.h"
#include "core/embedded.h"
#include "core/keys.h"
#include "core/text.h"

namespace sandswim {
namespace {

using nlohmann::json;

// ---------------------------------------------------------------------------------------------
// JSON helpers. Every error names the field relative to the object being read; callers prefix.

// A key the user wrote, made safe to put in a field path: control characters escaped, length
// capped, so an error message never carries a raw newline or a megabyte of text.
std::string SafeKey(const std::string& key) {
  std::string out;
  for (unsigned char c : key) {
    if (out.size() >= 64) {
      out += "...";
      break;
    }
    if (c < 0x20 || c == 0x7f) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  return out;
}

const char* TypeName(const json& j) {
  switch (j.type()) {
    case json::value_t::null:
      return "null";
    case json::value_t::object:
      return "an object";
    case json::value_t::array:
      return "an array";
    case json::value_t::string:
      return "a string";
    case json::value_t::boolean:
      return "a boolean";
    case json::value_t::binary:
      return "binary data";
    case json::value_t::discarded:
      return "nothing";
    default:
      return "a number";
  }
}

Status WrongType(const std::string& field, const char* want, const json& got) {
  return Status::InvalidArgument(field, std::string("must be ") + want + ", got " + TypeName(got));
}

// Refuses keys outside `allowed`, in the object's (sorted) key order so the error is stable.
Status CheckKeys(const json& obj, const std::set<std::string>& allowed) {
  for (const auto& [key, value] : obj.items()) {
    (void)value;
    if (!allowed.count(key)) return Status::InvalidArgument(SafeKey(key), "unknown field");
  }
  return Status::Ok();
}

Status RequireObject(const json& j, const std::string& field) {
  if (!j.is_object()) return WrongType(field, "an object", j);
  return Status::Ok();
}

// A JSON number (never a string, a boolean or null). JSON cannot carry NaN or Infinity, but a
// very large literal can overflow to infinity when read: refuse it here.
Result<double> ReadNumber(const json& obj, const std::string& key) {
  auto it = obj.find(key);
  if (it == obj.end()) return Status::InvalidArgument(key, "is required");
  if (!it->is_number()) return WrongType(key, "a number", *it);
  double v = it->get<double>();
  if (!std::isfinite(v)) return Status::InvalidArgument(key, "must be a finite number");
  return v;
}

Result<std::string> ReadString(const json& obj, const std::string& key) {
  auto it = obj.find(key);
  if (it == obj.end()) return Status::InvalidArgument(key, "is required");
  if (!it->is_string()) return WrongType(key, "a string", *it);
  return it->get<std::string>();
}

Status CheckName(const std::string& field, const std::string& name) {
  if (name.empty() || name.size() > kMaxNameLength)
    return Status::InvalidArgument(field, "must be 1 to " + std::to_string(kMaxNameLength) + " characters");
  for (char c : name) {
    bool ok =
        (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok) return Status::InvalidArgument(field, "may hold only A-Z a-z 0-9 . _ -");
  }
  // A URL's path normalises them away (/campaigns/.. is /): such a sweep or campaign could be
  // stored but never opened, scheduled or deleted by its address.
  if (name == "." || name == "..") return Status::InvalidArgument(field, "may not be \".\" or \"..\"");
  return Status::Ok();
}

std::string ScaleNames() {
  std::string s;
  for (const auto& sc : AllScales()) s += (s.empty() ? "" : ", ") + std::string(sc.name);
  return s;
}

// ---------------------------------------------------------------------------------------------
// Parameters: which fields each mode uses.

const std::vector<std::string>& ModeParams(Mode mode) {
  static const std::vector<std::string> kVib = {"A", "f", "duration_s"};
  static const std::vector<std::string> kRot = {"omega", "duration_s"};
  static const std::vector<std::string> kVibRot = {"A", "f", "omega", "duration_s"};
  static const std::vector<std::string> kOsc = {"A", "f", "Omega", "duration_s"};
  switch (mode) {
    case Mode::kVibration:
      return kVib;
    case Mode::kRotation:
      return kRot;
    case Mode::kVibrationRotation:
      return kVibRot;
    case Mode::kOscillatory:
      return kOsc;
  }
  return kOsc;
}

// Every mode takes the materials (core/materials.h), each optional: absent is Table 1's.
bool IsMaterialParam(const std::string& param) { return FindMaterialField(param) != nullptr; }

bool ModeUsesParam(Mode mode, const std::string& param) {
  if (IsMaterialParam(param)) return true;
  const auto& ps = ModeParams(mode);
  return std::find(ps.begin(), ps.end(), param) != ps.end();
}

bool ModeUsesAxis(Mode mode) { return mode == Mode::kRotation || mode == Mode::kVibrationRotation; }

double* ParamSlot(Point& p, const std::string& param) {
  if (param == "A") return &p.A;
  if (param == "f") return &p.f;
  if (param == "Omega") return &p.Omega;
  if (param == "omega") return &p.omega;
  if (param == "duration_s") return &p.duration_s;
  if (const MaterialField* m = FindMaterialField(param)) return &(p.materials.*m->member);
  return nullptr;
}

const std::vector<std::string>& AllParams() {
  static const std::vector<std::string> kAll = [] {
    std::vector<std::string> all = {"A", "f", "Omega", "omega", "duration_s"};
    for (const MaterialField& m : MaterialFields()) all.emplace_back(m.name);
    return all;
  }();
  return kAll;
}

bool IsParam(const std::string& name) {
  const auto& all = AllParams();
  return std::find(all.begin(), all.end(), name) != all.end();
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : ", ") + x;
  return s;
}

// ---------------------------------------------------------------------------------------------
// Parsing.

Result<Point> ParseBase(const json& j) {
  SANDSWIM_RETURN_IF_ERROR(RequireObject(j, ""));
  auto mode_name = ReadString(j, "mode");
  if (!mode_name.ok()) return mode_name.status();
  auto mode = ParseMode(*mode_name);
  if (!mode)
    return Status::InvalidArgument("mode", "must be one of vibration, rotation, vibration+rotation, oscillatory");
  Point p;
  p.mode = *mode;
  // Unknown fields first, then fields the mode does not use, then missing ones.
  std::set<std::string> known = {"mode", "axis"};
  for (const auto& param : AllParams()) known.insert(param);
  SANDSWIM_RETURN_IF_ERROR(CheckKeys(j, known));
  for (const auto& [key, value] : j.items()) {
    (void)value;
    if (key == "mode") continue;
    bool used = key == "axis" ? ModeUsesAxis(p.mode) : ModeUsesParam(p.mode, key);
    if (!used)
      return Status::InvalidArgument(key, "is not used by mode \"" + std::string(ModeName(p.mode)) + "\" (it takes " +
                                              Join(ModeParams(p.mode)) + (ModeUsesAxis(p.mode) ? ", axis" : "") + ")");
  }
  for (const auto& param : ModeParams(p.mode)) {
    auto v = ReadNumber(j, param);
    if (!v.ok()) return v.status();
    *ParamSlot(p, param) = *v;
  }
  for (const MaterialField& m : MaterialFields()) {
    const std::string name(m.name);
    if (!j.count(name)) continue;
    auto v = ReadNumber(j, name);
    if (!v.ok()) return v.status();
    p.materials.*m.member = *v;
  }
  if (ModeUsesAxis(p.mode)) {
    auto axis_name = ReadString(j, "axis");
    if (!axis_name.ok()) return axis_name.status();
    auto axis = ParseAxis(*axis_name);
    if (!axis) return Status::InvalidArgument("axis", "must be one of x, y, z, xz");
    p.axis = *axis;
  }
  return p;
}

// 12 significant digits: 0.01 + 9 * 0.01 reads back as exactly 0.1.
double Round12(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.12g", v);
  return std::strtod(buf, nullptr);
}

Result<SweepAxis> ParseAxisSpec(const json& j) {
  SANDSWIM_RETURN_IF_ERROR(RequireObject(j, ""));
  SANDSWIM_RETURN_IF_ERROR(CheckKeys(j, {"param", "values", "range", "geometric"}));
  SweepAxis axis;
  auto param = ReadString(j, "param");
  if (!param.ok()) return param.status();
  if (!IsParam(*param)) return Status::InvalidArgument("param", "must be one of " + Join(AllParams()));
  axis.param = *param;
  int sources = static_cast<int>(j.count("values") + j.count("range") + j.count("geometric"));
  if (sources != 1) return Status::InvalidArgument("", "must give exactly one of \"values\", \"range\", \"geometric\"");

  if (j.count("values")) {
    axis.source = "values";
    const json& vs = j["values"];
    if (!vs.is_array()) return WrongType("values", "an array of numbers", vs);
    if (vs.empty()) return Status::InvalidArgument("values", "must hold at least one number");
    if (vs.size() > kMaxRunsPerSubmission)
      return Status::ResourceExhausted("values", "holds " + std::to_string(vs.size()) + " values; at most " +
                                                     std::to_string(kMaxRunsPerSubmission) + " runs per submission");
    for (size_t i = 0; i < vs.size(); ++i) {
      std::string f = "values[" + std::to_string(i) + "]";
      if (!vs[i].is_number()) return WrongType(f, "a number", vs[i]);
      double v = vs[i].get<double>();
      if (!std::isfinite(v)) return Status::InvalidArgument(f, "must be a finite number");
      axis.values.push_back(v);
    }
    return axis;
  }

  if (j.count("range")) {
    axis.source = "range";
    const json& r = j["range"];
    auto in_range = [](Status s) { return s.WithFieldPrefix("range"); };
    if (!r.is_object()) return WrongType("range", "an object", r);
    if (Status s = CheckKeys(r, {"from", "to", "step"}); !s.ok()) return in_range(s);
    auto from = ReadNumber(r, "from");
    if (!from.ok()) return in_range(from.status());
    auto to = ReadNumber(r, "to");
    if (!to.ok()) return in_range(to.status());
    auto step = ReadNumber(r, "step");
    if (!step.ok()) return in_range(step.status());
    if (*step <= 0) return Status::InvalidArgument("range.step", "must be > 0");
    if (*to < *from) return Status::InvalidArgument("range.to", "must be >= range.from");
    // Count before materializing: a tiny step must not allocate a billion values. The 1e-9
    // slack keeps `to` in the series when (to - from) / step lands just under an integer.
    double n = std::floor((*to - *from) / *step + 1e-9) + 1;
    if (!(n <= static_cast<double>(kMaxRunsPerSubmission)))
      return Status::ResourceExhausted("range", "gives " + Num(n) + " values; at most " +
                                                    std::to_string(kMaxRunsPerSubmission) + " runs per submission");
    for (long long i = 0; i < static_cast<long long>(n); ++i) axis.values.push_back(Round12(*from + i * *step));
    return axis;
  }

  axis.source = "geometric";
  const json& g = j["geometric"];
  auto in_geo = [](Status s) { return s.WithFieldPrefix("geometric"); };
  if (!g.is_object()) return WrongType("geometric", "an object", g);
  if (Status s = CheckKeys(g, {"start", "ratio", "count", "signs"}); !s.ok()) return in_geo(s);
  auto start = ReadNumber(g, "start");
  if (!start.ok()) return in_geo(start.status());
  auto ratio = ReadNumber(g, "ratio");
  if (!ratio.ok()) return in_geo(ratio.status());
  if (*ratio <= 0) return Status::InvalidArgument("geometric.ratio", "must be > 0");
  auto count_d = ReadNumber(g, "count");
  if (!count_d.ok()) return in_geo(count_d.status());
  if (*count_d != std::floor(*count_d) || *count_d < 1)
    return Status::InvalidArgument("geometric.count", "must be a whole number >= 1");
  std::vector<double> signs = {1.0};
  if (g.count("signs")) {
    const json& sj = g["signs"];
    if (!sj.is_array()) return WrongType("geometric.signs", "an array of -1 and 1", sj);
    if (sj.empty() || sj.size() > 2) return Status::InvalidArgument("geometric.signs", "must hold one or two of -1, 1");
    signs.clear();
    for (size_t i = 0; i < sj.size(); ++i) {
      std::string f = "geometric.signs[" + std::to_string(i) + "]";
      if (!sj[i].is_number()) return WrongType(f, "-1 or 1", sj[i]);
      double s = sj[i].get<double>();
      if (s != 1.0 && s != -1.0) return Status::InvalidArgument(f, "must be -1 or 1");
      if (std::find(signs.begin(), signs.end(), s) != signs.end()) return Status::InvalidArgument(f, "repeats a sign");
      signs.push_back(s);
    }
  }
  double total = *count_d * static_cast<double>(signs.size());
  if (total > static_cast<double>(kMaxRunsPerSubmission))
    return Status::ResourceExhausted(
        "geometric.count",
        "gives " + Num(total) + " values; at most " + std::to_string(kMaxRunsPerSubmission) + " runs per submission");
  const long long count = static_cast<long long>(*count_d);
  for (double s : signs) {
    for (long long i = 0; i < count; ++i) {
      double v = s * *start * std::pow(*ratio, static_cast<double>(i));
      if (!std::isfinite(v))
        return Status::InvalidArgument("geometric", "value " + std::to_string(i) + " of the series overflows");
      axis.values.push_back(Round12(v));
    }
  }
  return axis;
}

// Number of points the axes expand to, or nullopt past `cap` (computed without overflow and
// without materializing anything).
std::optional<size_t> PointCount(const std::vector<SweepAxis>& axes, Combine combine, size_t cap) {
  if (axes.empty()) return size_t{1};
  if (combine == Combine::kZip) {
    size_t n = axes[0].values.size();
    return n <= cap ? std::optional<size_t>(n) : std::nullopt;
  }
  size_t n = 1;
  for (const auto& a : axes) {
    size_t k = a.values.size();
    if (k == 0) return size_t{0};
    if (n > cap / k) return std::nullopt;
    n *= k;
  }
  return n <= cap ? std::optional<size_t>(n) : std::nullopt;
}

// "precision" (core/precision.h), "replicates" (an integer from 1 to kMaxReplicates),
// "snapshots" (core/deck.h) and "numerics" (core/numerics.h), which a sweep and a campaign (for
// its sweeps) may set; absent keys
// leave the values as they are.
Status ReadRunSettings(const json& obj, std::optional<PrecisionTarget>& precision, std::optional<int>& replicates,
                       std::optional<SnapshotFractions>& snapshots, std::optional<Numerics>& numerics) {
  if (obj.count("numerics")) {
    auto n = ParseNumerics(obj["numerics"]);
    if (!n.ok()) return n.status().WithFieldPrefix("numerics");
    numerics = *n;
  }
  if (obj.count("snapshots")) {
    const json& v = obj["snapshots"];
    if (!v.is_array()) return WrongType("snapshots", "an array of fractions of the run's length", v);
    std::vector<double> fractions;
    for (size_t i = 0; i < v.size(); ++i) {
      if (!v[i].is_number()) return WrongType("snapshots[" + std::to_string(i) + "]", "a number", v[i]);
      fractions.push_back(v[i].get<double>());
    }
    auto checked = CheckSnapshotFractions(std::move(fractions));
    if (!checked.ok()) return checked.status();
    snapshots = *checked;
  }
  if (obj.count("precision")) {
    auto t = PrecisionFromJson(obj["precision"]);
    if (!t.ok()) return t.status().WithFieldPrefix("precision");
    precision = *t;
  }
  if (obj.count("replicates")) {
    const json& v = obj["replicates"];
    if (!v.is_number_integer()) return WrongType("replicates", "an integer", v);
    const auto k = v.get<int64_t>();
    if (k < 1 || k > kMaxReplicates)
      return Status::InvalidArgument(
          "replicates", "must be from 1 to " + std::to_string(kMaxReplicates) + " beds, got " + std::to_string(k));
    replicates = static_cast<int>(k);
  }
  return Status::Ok();
}

Status TooMany(size_t cap) {
  return Status::ResourceExhausted("axes", "the sweep expands to more than " + std::to_string(cap) +
                                               " points (at most " + std::to_string(cap) + " runs per submission)");
}

// A sweep that passes what is left of the submission's cap (`cap` runs in all) once the sweeps
// before it took `used`: said in runs of the submission, not as "more than 0 points".
Status PastSubmissionCap(const Status& st, size_t cap, size_t used) {
  return Status::ResourceExhausted(st.field(), "with the " + std::to_string(used) +
                                                   " runs of the sweeps before it, the submission comes to more than " +
                                                   std::to_string(cap) + " runs, the most one submission may hold");
}

// The path of an axis' i-th value, as the user wrote it.
Status AtAxisValue(const Status& s, const SweepAxis& axis, size_t axis_index, size_t value_index) {
  std::string path = "axes[" + std::to_string(axis_index) + "]";
  if (axis.source == "values" || axis.source.empty())
    return Status(s.code(), s.reason(), path + ".values[" + std::to_string(value_index) + "]");
  return Status(s.code(),
                "value [" + std::to_string(value_index) + "] of the series (" + Num(axis.values[value_index]) +
                    "): " + s.reason(),
                path + "." + axis.source);
}

// Validates one point and names the field a user wrote: an axis value if an axis set that
// parameter (`index[k]` is the point's index along axis k), else "base.<field>".
Status CheckPoint(const Point& p, const Scale& scale, const std::vector<SweepAxis>& axes,
                  const std::vector<size_t>& index) {
  Status s = Validate(p);
  if (s.ok()) s = FitsScale(p, scale);
  if (s.ok()) return s;
  for (size_t k = 0; k < axes.size(); ++k)
    if (axes[k].param == s.field()) return AtAxisValue(s, axes[k], k, index[k]);
  return s.WithFieldPrefix("base");
}

// Sweep objects appear alone (with "scale") and inside campaigns (without: the campaign's
// scale applies).
Result<SweepSpec> ParseSweepObject(const json& j, bool in_campaign, const std::string& campaign_scale) {
  SANDSWIM_RETURN_IF_ERROR(RequireObject(j, ""));
  std::set<std::string> allowed = {"name",      "base",       "axes",      "combine", "description",
                                   "precision", "replicates", "snapshots", "numerics"};
  if (!in_campaign) {
    allowed.insert("scale");
    allowed.insert("force");
  }
  if (in_campaign && j.count("scale"))
    return Status::InvalidArgument("scale", "a campaign's sweeps run at the campaign's scale; set it there");
  SANDSWIM_RETURN_IF_ERROR(CheckKeys(j, allowed));

  SweepSpec s;
  auto name = ReadString(j, "name");
  if (!name.ok()) return name.status();
  SANDSWIM_RETURN_IF_ERROR(CheckName("name", *name));
  s.name = *name;

  if (in_campaign) {
    s.scale = campaign_scale;
  } else {
    auto scale = ReadString(j, "scale");
    if (!scale.ok()) return scale.status();
    if (!FindScale(*scale)) return Status::InvalidArgument("scale", "must be one of " + ScaleNames());
    s.scale = *scale;
  }
  if (j.count("force") && !j["force"].is_boolean()) return WrongType("force", "a boolean", j["force"]);
  if (j.count("description")) {
    if (!j["description"].is_string()) return WrongType("description", "a string", j["description"]);
    if (j["description"].get_ref<const std::string&>().size() > kMaxDescriptionLength)
      return Status::InvalidArgument("description",
                                     "must be at most " + std::to_string(kMaxDescriptionLength) + " characters");
  }

  SANDSWIM_RETURN_IF_ERROR(ReadRunSettings(j, s.precision, s.replicates, s.snapshots, s.numerics));

  if (!j.count("base")) return Status::InvalidArgument("base", "is required");
  auto base = ParseBase(j["base"]);
  if (!base.ok()) return base.status().WithFieldPrefix("base");
  s.base = *base;

  if (j.count("combine")) {
    const json& c = j["combine"];
    if (!c.is_string()) return WrongType("combine", "a string", c);
    if (c == "product") {
      s.combine = Combine::kProduct;
    } else if (c == "zip") {
      s.combine = Combine::kZip;
    } else {
      return Status::InvalidArgument("combine", "must be \"product\" or \"zip\"");
    }
  }

  if (j.count("axes")) {
    const json& axes = j["axes"];
    if (!axes.is_array()) return WrongType("axes", "an array", axes);
    for (size_t i = 0; i < axes.size(); ++i) {
      std::string path = "axes[" + std::to_string(i) + "]";
      auto axis = ParseAxisSpec(axes[i]);
      if (!axis.ok()) return axis.status().WithFieldPrefix(path);
      if (!ModeUsesParam(s.base.mode, axis->param))
        return Status::InvalidArgument(path + ".param", "\"" + axis->param + "\" is not used by mode \"" +
                                                            std::string(ModeName(s.base.mode)) + "\" (it takes " +
                                                            Join(ModeParams(s.base.mode)) + ")");
      for (size_t k = 0; k < s.axes.size(); ++k)
        if (s.axes[k].param == axis->param)
          return Status::InvalidArgument(
              path + ".param", "\"" + axis->param + "\" already has an axis (axes[" + std::to_string(k) + "])");
      s.axes.push_back(std::move(*axis));
    }
  }
  if (s.combine == Combine::kZip) {
    for (size_t i = 1; i < s.axes.size(); ++i)
      if (s.axes[i].values.size() != s.axes[0].values.size())
        return Status::InvalidArgument("axes[" + std::to_string(i) + "]",
                                       "\"zip\" needs axes of equal length: axes[0] has " +
                                           std::to_string(s.axes[0].values.size()) + " values, axes[" +
                                           std::to_string(i) + "] has " + std::to_string(s.axes[i].values.size()));
  }
  if (!PointCount(s.axes, s.combine, kMaxRunsPerSubmission)) return TooMany(kMaxRunsPerSubmission);

  // Every field check is independent of the others, so checking the base alone and each axis
  // value on the base finds every bad point without expanding the product.
  const Scale& scale = *FindScale(s.scale);
  if (Status st = Validate(s.base); !st.ok()) return st.WithFieldPrefix("base");
  if (Status st = FitsScale(s.base, scale); !st.ok()) return st.WithFieldPrefix("base");
  for (size_t k = 0; k < s.axes.size(); ++k) {
    for (size_t i = 0; i < s.axes[k].values.size(); ++i) {
      Point p = s.base;
      *ParamSlot(p, s.axes[k].param) = s.axes[k].values[i];
      Status st = Validate(p);
      if (st.ok()) st = FitsScale(p, scale);
      if (!st.ok()) return AtAxisValue(st, s.axes[k], k, i);
    }
  }
  return s;
}

Status CheckSchedule(const std::string& cron) {
  // Five fields (minute hour day-of-month month day-of-week) of digits, '*', ',', '-', '/'.
  size_t fields = 0;
  size_t i = 0;
  while (i < cron.size()) {
    while (i < cron.size() && cron[i] == ' ') ++i;
    if (i == cron.size()) break;
    ++fields;
    while (i < cron.size() && cron[i] != ' ') {
      char c = cron[i];
      if (!((c >= '0' && c <= '9') || c == '*' || c == ',' || c == '-' || c == '/'))
        return Status::InvalidArgument("schedule", "must be a five-field cron expression such as \"0 2 * * *\"");
      ++i;
    }
  }
  if (fields != 5 || cron.size() > 100)
    return Status::InvalidArgument("schedule", "must be a five-field cron expression such as \"0 2 * * *\"");
  return Status::Ok();
}

std::string CampaignTemplatePath(const std::string& name) { return "templates/campaigns/" + name + ".json"; }

// Both sets of snapshot fractions, ascending, each once (a run shared by sweeps takes them all).
SnapshotFractions UnionOfFractions(const SnapshotFractions& a, const SnapshotFractions& b) {
  SnapshotFractions out;
  std::set_union(a.begin(), a.end(), b.begin(), b.end(), std::back_inserter(out));
  return out;
}

void AddSweepName(std::vector<std::string>& names, const std::string& name) {
  if (std::find(names.begin(), names.end(), name) == names.end()) names.push_back(name);
}

}  // namespace

Result<SweepSpec> ParseSweep(const json& j) { return ParseSweepObject(j, false, ""); }

Result<std::vector<Point>> ExpandSweep(const SweepSpec& s, size_t max_points) {
  const Scale* scale = FindScale(s.scale);
  if (!scale) return Status::InvalidArgument("scale", "must be one of " + ScaleNames());
  for (size_t k = 0; k < s.axes.size(); ++k) {
    if (!IsParam(s.axes[k].param))
      return Status::InvalidArgument("axes[" + std::to_string(k) + "].param", "must be one of " + Join(AllParams()));
    if (s.axes[k].values.empty())
      return Status::InvalidArgument("axes[" + std::to_string(k) + "]", "must hold at least one value");
    if (s.combine == Combine::kZip && s.axes[k].values.size() != s.axes[0].values.size())
      return Status::InvalidArgument("axes[" + std::to_string(k) + "]", "\"zip\" needs axes of equal length");
  }
  auto n = PointCount(s.axes, s.combine, max_points);
  if (!n) return TooMany(max_points);

  std::vector<Point> points;
  points.reserve(*n);
  std::vector<size_t> index(s.axes.size(), 0);
  for (size_t i = 0; i < *n; ++i) {
    if (s.combine == Combine::kZip) {
      std::fill(index.begin(), index.end(), i);
    } else if (i > 0) {
      // Odometer: the last axis fastest.
      for (size_t k = s.axes.size(); k-- > 0;) {
        if (++index[k] < s.axes[k].values.size()) break;
        index[k] = 0;
      }
    }
    Point p = s.base;
    for (size_t k = 0; k < s.axes.size(); ++k) *ParamSlot(p, s.axes[k].param) = s.axes[k].values[index[k]];
    SANDSWIM_RETURN_IF_ERROR(CheckPoint(p, *scale, s.axes, index));
    SANDSWIM_RETURN_IF_ERROR(ResolveDriveStep(p, *scale, s.numerics.value_or(Numerics{})));
    points.push_back(p);
  }
  return points;
}

namespace {

Result<AdaptiveSettings> ParseAdaptiveSettings(const json& j) {
  SANDSWIM_RETURN_IF_ERROR(RequireObject(j, ""));
  SANDSWIM_RETURN_IF_ERROR(CheckKeys(j, {"budget_core_h", "max_rounds"}));
  AdaptiveSettings a;
  if (!j.count("budget_core_h")) return Status::InvalidArgument("budget_core_h", "is required (core-hours of engine time)");
  auto budget = ReadNumber(j, "budget_core_h");
  if (!budget.ok()) return budget.status();
  if (!std::isfinite(*budget) || *budget <= 0)
    return Status::InvalidArgument("budget_core_h", "must be a positive number of core-hours");
  a.budget_core_h = *budget;
  if (j.count("max_rounds")) {
    const json& v = j["max_rounds"];
    if (!v.is_number_integer()) return WrongType("max_rounds", "an integer", v);
    const int64_t n = v.get<int64_t>();
    if (n < 1 || n > kMaxAdaptiveRounds)
      return Status::InvalidArgument("max_rounds", "must be from 1 to " + std::to_string(kMaxAdaptiveRounds) +
                                                       " (the first round included), got " + std::to_string(n));
    a.max_rounds = static_cast<int>(n);
  }
  return a;
}

}  // namespace

Result<Campaign> ParseCampaign(const json& j) {
  SANDSWIM_RETURN_IF_ERROR(RequireObject(j, ""));
  SANDSWIM_RETURN_IF_ERROR(CheckKeys(j, {"name", "description", "scale", "schedule", "drift_tolerance_mps", "precision",
                                         "replicates", "snapshots", "numerics", "sweeps", "claims", "adaptive"}));
  Campaign c;
  auto name = ReadString(j, "name");
  if (!name.ok()) return name.status();
  SANDSWIM_RETURN_IF_ERROR(CheckName("name", *name));
  c.name = *name;
  auto description = ReadString(j, "description");
  if (!description.ok()) return description.status();
  if (description->size() > kMaxDescriptionLength)
    return Status::InvalidArgument("description",
                                   "must be at most " + std::to_string(kMaxDescriptionLength) + " characters");
  c.description = *description;
  auto scale = ReadString(j, "scale");
  if (!scale.ok()) return scale.status();
  if (!FindScale(*scale)) return Status::InvalidArgument("scale", "must be one of " + ScaleNames());
  c.scale = *scale;
  if (j.count("schedule")) {
    auto schedule = ReadString(j, "schedule");
    if (!schedule.ok()) return schedule.status();
    SANDSWIM_RETURN_IF_ERROR(CheckSchedule(*schedule));
    c.schedule = *schedule;
  }
  if (j.count("drift_tolerance_mps")) {
    auto tol = ReadNumber(j, "drift_tolerance_mps");
    if (!tol.ok()) return tol.status();
    if (*tol < 0) return Status::InvalidArgument("drift_tolerance_mps", "must be >= 0 m/s");
    c.drift_tolerance_mps = *tol;
  }
  SANDSWIM_RETURN_IF_ERROR(ReadRunSettings(j, c.precision, c.replicates, c.snapshots, c.numerics));
  if (!j.count("sweeps")) return Status::InvalidArgument("sweeps", "is required");
  const json& sweeps = j["sweeps"];
  if (!sweeps.is_array()) return WrongType("sweeps", "an array", sweeps);
  if (sweeps.empty()) return Status::InvalidArgument("sweeps", "must hold at least one sweep");
  size_t total = 0;
  for (size_t i = 0; i < sweeps.size(); ++i) {
    std::string path = "sweeps[" + std::to_string(i) + "]";
    auto s = ParseSweepObject(sweeps[i], true, c.scale);
    if (!s.ok()) return s.status().WithFieldPrefix(path);
    if (!s->precision) s->precision = c.precision;
    if (!s->replicates) s->replicates = c.replicates;
    if (!s->snapshots) s->snapshots = c.snapshots;
    if (!s->numerics) s->numerics = c.numerics;
    for (const auto& other : c.sweeps)
      if (other.name == s->name) return Status::InvalidArgument(path + ".name", "repeats sweep \"" + s->name + "\"");
    total += *PointCount(s->axes, s->combine, kMaxRunsPerSubmission) * s->Replicates();
    if (total > kMaxRunsPerSubmission) return TooMany(kMaxRunsPerSubmission).WithFieldPrefix(path);
    c.sweeps.push_back(std::move(*s));
  }
  if (j.count("claims")) {
    std::vector<std::string> names;
    for (const SweepSpec& s : c.sweeps) names.push_back(s.name);
    auto claims = ParseClaims(j["claims"], names);
    if (!claims.ok()) return claims.status().WithFieldPrefix("claims");
    c.claims = std::move(claims).value();
  }
  if (j.count("adaptive")) {
    auto adaptive = ParseAdaptiveSettings(j["adaptive"]);
    if (!adaptive.ok()) return adaptive.status().WithFieldPrefix("adaptive");
    if (c.claims.empty())
      return Status::InvalidArgument("adaptive", "needs claims: rounds are planned from the claims still undecided");
    for (size_t i = 0; i < c.sweeps.size(); ++i) {
      if (c.sweeps[i].Replicates() > 1) {
        return Status::InvalidArgument(
            j.count("replicates") ? "replicates" : "sweeps[" + std::to_string(i) + "].replicates",
            "must be 1 (or absent) in an adaptive campaign: its first round runs every point on one bed, and "
            "later rounds add beds where a claim needs them");
      }
    }
    c.adaptive = *adaptive;
  }
  return c;
}

std::vector<std::string> BuiltinCampaignNames() { return {"paper-58", "density-ratio", "dt-convergence"}; }

Result<json> BuiltinCampaignDefinition(const std::string& name) {
  auto names = BuiltinCampaignNames();
  if (std::find(names.begin(), names.end(), name) == names.end())
    return Status::NotFound("no built-in campaign \"" + SafeKey(name) + "\" (built in: " + Join(names) + ")");
  auto text = EmbeddedFile(CampaignTemplatePath(name));
  if (!text) return Status::Internal("campaign " + name + " is not compiled in");
  json j = json::parse(text->begin(), text->end(), nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return Status::Internal(CampaignTemplatePath(name) + " is not valid JSON");
  return j;
}

Result<Campaign> BuiltinCampaign(const std::string& name) {
  Result<json> j = BuiltinCampaignDefinition(name);
  if (!j.ok()) return j.status();
  auto c = ParseCampaign(*j);
  if (!c.ok()) return Status::Internal(CampaignTemplatePath(name) + ": " + c.status().ToString());
  return c;
}

Result<Plan> PlanSweeps(const std::vector<SweepSpec>& sweeps, const Scale& scale, const std::string& engine_version,
                        size_t max_runs) {
  PlanOptions options;
  options.max_runs = max_runs;
  return PlanSweeps(sweeps, scale, engine_version, options);
}

Result<Plan> PlanSweeps(const std::vector<SweepSpec>& sweeps, const Scale& scale, const std::string& engine_version,
                        const PlanOptions& options) {
  Plan plan;
  plan.scale = std::string(scale.name);
  // Beds in first-appearance order, one per (bed materials, replicate): points that differ only in
  // drive-only parameters share theirs (core/materials.h). With Table 1 only, beds 0..K-1 are the
  // replicates in order, as before materials could be swept.
  std::map<std::pair<std::array<double, kMaterialFieldCount>, int>, int> bed_index;
  auto bed_for = [&](const Materials& materials, int replicate) -> int {
    const Materials m = BedMaterials(materials);
    std::array<double, kMaterialFieldCount> id{};
    for (size_t i = 0; i < kMaterialFieldCount; ++i) id[i] = m.*MaterialFields()[i].member;
    auto [it, inserted] = bed_index.emplace(std::make_pair(id, replicate), static_cast<int>(plan.beds.size()));
    if (inserted) {
      PlannedBed bed;
      bed.replicate = replicate;
      bed.seeds = BedSeedsFor(replicate);
      bed.materials = m;
      bed.deck = RenderBedDeck(scale, replicate, m);
      bed.key = BedKey(bed.deck, engine_version);
      plan.beds.push_back(std::move(bed));
    }
    return it->second;
  };

  std::map<std::pair<DriveId, int>, size_t> by_drive;
  size_t expanded = 0;
  for (size_t i = 0; i < sweeps.size(); ++i) {
    SweepSpec s = sweeps[i];
    s.scale = std::string(scale.name);
    const size_t k = static_cast<size_t>(s.Replicates());
    auto points = ExpandSweep(s, (options.max_runs - expanded) / k);
    if (!points.ok()) {
      Status st = points.status();
      const size_t used = options.runs_before + expanded;
      if (used > 0 && st.code() == StatusCode::kResourceExhausted)
        st = PastSubmissionCap(st, options.runs_before + options.max_runs, used);
      else if (k > 1 && st.code() == StatusCode::kResourceExhausted)
        st = Status::ResourceExhausted("replicates", "its points on " + std::to_string(k) +
                                                         " beds each come to more than " +
                                                         std::to_string(options.max_runs - expanded) + " runs");
      // Name the sweep only when there is more than one.
      if (sweeps.size() == 1) return st;
      return st.WithFieldPrefix("sweeps[" + std::to_string(i) + "]");
    }
    expanded += points->size() * k;
    const std::optional<PrecisionTarget> target = s.precision ? s.precision : scale.default_precision;
    for (const Point& p : *points) {
      for (int replicate = 0; replicate < static_cast<int>(k); ++replicate) {
        auto [it, inserted] = by_drive.emplace(std::make_pair(DriveIdOf(p), replicate), plan.runs.size());
        if (inserted) {
          PlannedRun r;
          r.point = p;
          r.replicate = replicate;
          try {
            r.bed = bed_for(p.materials, replicate);
          } catch (const std::exception& e) {
            return Status::Internal(std::string("rendering the bed deck failed: ") + e.what());
          }
          r.precision = target;
          r.snapshots = s.snapshots.value_or(SnapshotFractions{});
          r.sweeps.push_back(s.name);
          plan.runs.push_back(std::move(r));
        } else {
          PlannedRun& r = plan.runs[it->second];
          r.point.duration_s = std::max(r.point.duration_s, p.duration_s);
          r.precision = r.precision && target ? Tightest(*r.precision, *target) : std::nullopt;
          if (s.snapshots) r.snapshots = UnionOfFractions(r.snapshots, *s.snapshots);
          AddSweepName(r.sweeps, s.name);
        }
      }
    }
  }

  // Render once the durations are final. Each run touches only its own slot, so the work splits
  // into contiguous slices, one per thread.
  const size_t n = plan.runs.size();
  const size_t threads = std::max<size_t>(1, std::min<size_t>(options.threads > 0 ? options.threads : 1, n / 1000 + 1));
  std::vector<std::string> errors(threads);
  auto render = [&](size_t t) {
    size_t begin = n * t / threads, end = n * (t + 1) / threads;
    try {
      for (size_t i = begin; i < end; ++i) {
        PlannedRun& r = plan.runs[i];
        r.run_duration_s = RunDuration(r.point, r.precision);
        r.steps = DriveSteps(r.point, r.precision);
        std::string deck = RenderDriveDeck(r.point, scale, r.precision, r.snapshots);
        r.key = RunKey(deck, plan.beds[r.bed].key, engine_version);
        if (options.keep_decks) r.deck = std::move(deck);
      }
    } catch (const std::exception& e) {
      errors[t] = std::string("rendering a drive deck failed: ") + e.what();
    }
  };
  if (threads == 1) {
    render(0);
  } else {
    std::vector<std::thread> pool;
    for (size_t t = 0; t < threads; ++t) pool.emplace_back(render, t);
    for (auto& th : pool) th.join();
  }
  for (const auto& e : errors)
    if (!e.empty()) return Status::Internal(e);

  // Runs whose decks come out identical are one run.
  std::unordered_map<std::string, size_t> by_key;
  by_key.reserve(n);
  std::vector<PlannedRun> runs;
  runs.reserve(n);
  for (PlannedRun& r : plan.runs) {
    auto [it, inserted] = by_key.emplace(r.key, runs.size());
    if (inserted) {
      runs.push_back(std::move(r));
    } else {
      for (const auto& name : r.sweeps) AddSweepName(runs[it->second].sweeps, name);
    }
  }
  plan.runs = std::move(runs);
  return plan;
}

json PointToJson(const Point& p) {
  json j = json::object();
  j["mode"] = std::string(ModeName(p.mode));
  for (const auto& param : ModeParams(p.mode)) {
    if (param == "duration_s") continue;
    Point copy = p;
    j[param] = *ParamSlot(copy, param);
  }
  if (ModeUsesAxis(p.mode)) j["axis"] = std::string(AxisName(p.axis));
  j["duration_s"] = p.duration_s;
  // Materials only where they are not Table 1's: a Table 1 point's JSON is what it always was.
  for (const MaterialField& m : MaterialFields())
    if (p.materials.*m.member != kTable1.*m.member) j[std::string(m.name)] = p.materials.*m.member;
  // A step other than the materials' rule (core/numerics.h): part of the drive's identity.
  if (p.dt_s) j["dt_s"] = *p.dt_s;
  return j;
}

json PlannedRunToJson(const PlannedRun& r) {
  json j = PointToJson(r.point);
  j["key"] = r.key;
  j["run_duration_s"] = r.run_duration_s;
  j["steps"] = r.steps;
  if (const double dt = DriveStep(r.point); dt != kMaterials.dt) {
    j["dt_s"] = dt;
    StepCriteria c = JudgeStep(r.point, dt);
    c.source = r.point.dt_s ? "numerics.dt or the scale's default, core/numerics.h" : kTimeStepRule;
    j["dt_criteria"] = StepCriteriaToJson(c);
  }
  j["replicate"] = r.replicate;
  if (r.precision) j["precision"] = PrecisionToJson(*r.precision);
  if (!r.snapshots.empty()) j["snapshots"] = r.snapshots;
  j["sweeps"] = r.sweeps;
  return j;
}

Result<std::vector<ScalePlan>> PlanSubmission(const std::vector<SweepSpec>& sweeps, const std::string& engine_version,
                                              const PlanOptions& options, bool campaign) {
  std::vector<ScalePlan> groups;
  std::map<std::string, size_t> seen_names;
  for (size_t i = 0; i < sweeps.size(); ++i) {
    const std::string field = campaign ? "campaign" : "sweeps[" + std::to_string(i) + "]";
    if (!seen_names.emplace(sweeps[i].name, i).second) {
      return Status::InvalidArgument(field + ".name", "'" + sweeps[i].name + "' names two sweeps of one submission");
    }
    if (FindScale(sweeps[i].scale) == nullptr) {
      return Status::InvalidArgument(campaign ? "scale" : field + ".scale",
                                     "'" + sweeps[i].scale + "' is not one of paper, mini, smoke");
    }
    auto g = std::find_if(groups.begin(), groups.end(), [&](const ScalePlan& x) { return x.scale == sweeps[i].scale; });
    if (g == groups.end()) {
      groups.push_back(ScalePlan{sweeps[i].scale, {}, {}});
      g = groups.end() - 1;
    }
    g->sweep_indexes.push_back(i);
  }
  size_t planned = 0;
  for (ScalePlan& g : groups) {
    std::vector<SweepSpec> group_sweeps;
    for (size_t i : g.sweep_indexes) group_sweeps.push_back(sweeps[i]);
    PlanOptions group_options = options;
    group_options.max_runs = options.max_runs > planned ? options.max_runs - planned : 0;
    group_options.runs_before = options.runs_before + planned;
    Result<Plan> plan = PlanSweeps(group_sweeps, *FindScale(g.scale), engine_version, group_options);
    if (!plan.ok()) {
      Status s = plan.status();
      // A single sweep's field paths are relative to it; name the sweep when there are several.
      if (!campaign && sweeps.size() > 1 && g.sweep_indexes.size() == 1) {
        s = s.WithFieldPrefix("sweeps[" + std::to_string(g.sweep_indexes[0]) + "]");
      }
      return s;
    }
    planned += plan->runs.size();
    g.plan = std::move(plan).value();
  }
  return groups;
}

}  // namespace sandswim
