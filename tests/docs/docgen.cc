// sandswim-docgen: prints the references that are made from core/'s tables, as Markdown, so that
// docs/reference/ cannot drift from the code. tests/docs/check_docs.py runs it and compares its
// output with the committed pages (ctest docs_check); `--update` there rewrites them.
//
// Usage: sandswim-docgen result-fields|scales. Exit status 2 on an unknown page.
#include <cstdio>
#include <string>
#include <string_view>

#include "core/result_fields.h"
#include "core/scale.h"

namespace sandswim {
namespace {

const char* TypeName(ResultType t) {
  switch (t) {
    case ResultType::kReal: return "real";
    case ResultType::kInteger: return "integer";
    case ResultType::kBool: return "bool (0/1)";
    case ResultType::kText: return "text";
  }
  return "?";
}

const char* OriginName(ResultOrigin o) {
  switch (o) {
    case ResultOrigin::kAnalysis: return "analysis (a re-analysis rewrites it)";
    case ResultOrigin::kRun: return "the run, as the worker saw it end";
    case ResultOrigin::kExecution: return "how it ran";
    case ResultOrigin::kStore: return "the store";
  }
  return "?";
}

void PrintResultFields() {
  std::printf("# Reference: a run's result fields\n\n");
  std::printf("Generated from `core/result_fields.cc` by `sandswim-docgen result-fields`; do not edit by hand\n"
              "(`tests/docs/check_docs.py --update` rewrites it).\n\n");
  std::printf("`name` is the C++ member, the `results` table's column and the key in a worker's report and in\n"
              "`GET /api/v1/runs/{id}`'s `\"result\"`; `row / CSV` is its key in a results row and its CSV column\n"
              "(empty: not in a results row). Optional fields may be absent: null in JSON, NULL in SQL, an\n"
              "empty CSV cell.\n\n");
  std::printf("| name | row / CSV | unit | type | optional | made by |\n| --- | --- | --- | --- | --- | --- |\n");
  for (const ResultField& f : ResultFields()) {
    std::printf("| `%s` | %s | %s | %s | %s | %s |\n", f.name.c_str(),
                f.row_key.empty() ? "" : ("`" + f.row_key + "`").c_str(), f.unit.c_str(), TypeName(f.type),
                f.optional ? "yes" : "no", OriginName(f.origin));
  }
}

std::string Num(double v) {
  char b[64];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

void PrintScales() {
  std::printf("# Reference: scales\n\n");
  std::printf("Generated from `core/scale.cc` by `sandswim-docgen scales`; do not edit by hand\n"
              "(`tests/docs/check_docs.py --update` rewrites it). Lengths in m; x and y are periodic, y is the\n"
              "vibration direction. Grains are the estimate for Table 1's materials before a bed is prepared.\n\n");
  std::printf("| scale | purpose | box x × y (m) | floor (m) | bed top (m) | grains (estimate) | max grains | "
              "largest A (m) | default precision target | bed-to-bed prior |\n"
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const Scale& s : AllScales()) {
    std::string precision = "none (runs last the duration they ask for)";
    if (s.default_precision) {
      const PrecisionTarget& p = *s.default_precision;
      precision = "uz_rel " + Num(p.uz_rel) + ", uz_abs " + Num(p.uz_abs) + " m/s, min_periods " +
                  std::to_string(p.min_periods) + ", max_duration_s " + Num(p.max_duration_s);
    }
    std::string prior = s.bed_sd_rel ? Num(*s.bed_sd_rel) + " of \\|U_z\\|" : "not measured";
    std::printf("| `%s` | %s | %s × %s | %s | %s | %.0f | %.0f | %s | %s | %s |\n", std::string(s.name).c_str(),
                std::string(s.purpose).c_str(), Num(s.x_len).c_str(), Num(s.y_len).c_str(), Num(s.z_floor).c_str(),
                Num(s.z_bed_top).c_str(), EstimatedGrains(s), s.max_grains, Num(s.max_amplitude()).c_str(),
                precision.c_str(), prior.c_str());
  }
  std::printf("\nThe shortest time step any scale runs: %s s.\n", Num(kMinTimeStepS).c_str());
}

}  // namespace
}  // namespace sandswim

int main(int argc, char** argv) {
  const std::string_view page = argc == 2 ? argv[1] : "";
  if (page == "result-fields") {
    sandswim::PrintResultFields();
  } else if (page == "scales") {
    sandswim::PrintScales();
  } else {
    std::fprintf(stderr, "usage: sandswim-docgen result-fields|scales\n");
    return 2;
  }
  return 0;
}
