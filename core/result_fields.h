// A run's result, described once: every field of a stored result (the figures a worker reports,
// api::RunResult; how it ran, api::Execution; and the store's key and time) with its one name
// (the C++ member, the `results` table's column and the key of the worker's report and of a run's
// stored result in GET /api/v1/runs/{id}), its key in a results row and its CSV column (the REST
// API's "Uz" for uz), its type and its unit. The SQL of the store (the SELECT list and its reads,
// the INSERT, the re-analysis's UPDATE), the worker's report JSON (api.cc), the stored result's
// JSON, the results rows' JSON and their CSV columns (core/result_table.h) are all made from this
// table: a field added here appears in each, and a field whose column the schema lacks fails the
// store's schema test (server/store/store_test.cc ResultFieldsAreTheResultsTable).
//
// Thread safety: the table is built once (a function-local static) and read-only after.
#ifndef SANDSWIM_CORE_RESULT_FIELDS_H_
#define SANDSWIM_CORE_RESULT_FIELDS_H_

#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/api.h"

namespace sandswim {

// A run's result as stored: the measured figures plus how it was executed.
struct StoredResult {
  api::RunResult result;
  api::Execution execution;
  std::string key;  // the run key the result was computed under
  double created_at = 0;
};

// A field's value type (a column's storage: kBool as 0/1).
enum class ResultType { kReal, kInteger, kBool, kText };

// Who makes a field, which says who may rewrite it.
enum class ResultOrigin {
  kAnalysis,   // the trajectory analysis (core/trajectory.h): a re-analysis rewrites it
  kRun,        // the run as the worker saw it end (kept by a re-analysis)
  kExecution,  // how it ran (api::Execution)
  kStore,      // the store's: the run key and the time it was stored
};

struct ResultField {
  std::string name;     // the C++ member, the results table's column and the report/stored JSON key
  std::string row_key;  // its key in a results row and its CSV column; "" when not in a results row
  std::string unit;     // SI unit; "" when dimensionless or not a quantity
  ResultType type = ResultType::kReal;
  bool optional = false;  // may be absent: null in JSON, NULL in SQL, an empty CSV cell
  ResultOrigin origin = ResultOrigin::kRun;
  // What a worker's report that lacks the key means (null: the type's zero). Only a report made
  // before the field existed lacks it.
  nlohmann::json absent;
  // The field's value as JSON (null when absent), and the field set from one (null: absent for an
  // optional field; a non-optional field takes its JSON type's value and throws
  // nlohmann::json::type_error on another).
  nlohmann::json (*get)(const StoredResult&) = nullptr;
  void (*set)(StoredResult&, const nlohmann::json&) = nullptr;
};

// Every field, in the order of the results rows' columns (those with a row_key), the others
// beside their kin.
const std::vector<ResultField>& ResultFields();

// The stored result's JSON (GET /api/v1/runs/{id} "result"): every field under its name (an
// absent optional one left out), plus "uz_text" (core/trajectory.h DescribeUz).
void to_json(nlohmann::json& j, const StoredResult& r);

// ---- How a field is made (used by ResultFields; here so that types are checked where declared) --
namespace result_fields_internal {

template <typename T>
struct Member;
template <typename C, typename T>
struct Member<T C::*> {
  using Class = C;
  using Type = T;
};

template <typename T>
struct Unwrap {
  using Type = T;
  static constexpr bool kOptional = false;
};
template <typename T>
struct Unwrap<std::optional<T>> {
  using Type = T;
  static constexpr bool kOptional = true;
};

template <typename T>
constexpr ResultType TypeOf() {
  if constexpr (std::is_same_v<T, bool>) return ResultType::kBool;
  else if constexpr (std::is_same_v<T, std::string>) return ResultType::kText;
  else if constexpr (std::is_integral_v<T>) return ResultType::kInteger;
  else {
    static_assert(std::is_same_v<T, double>, "a result field is a double, an integer, a bool or a string");
    return ResultType::kReal;
  }
}

template <auto M>
auto& Part(StoredResult& s) {
  using C = typename Member<decltype(M)>::Class;
  if constexpr (std::is_same_v<C, api::RunResult>) return s.result.*M;
  else if constexpr (std::is_same_v<C, api::Execution>) return s.execution.*M;
  else {
    static_assert(std::is_same_v<C, StoredResult>, "a result field is a member of RunResult, Execution or StoredResult");
    return s.*M;
  }
}

template <auto M>
nlohmann::json Get(const StoredResult& s) {
  const auto& v = Part<M>(const_cast<StoredResult&>(s));
  using T = typename Member<decltype(M)>::Type;
  if constexpr (Unwrap<T>::kOptional) return v ? nlohmann::json(*v) : nlohmann::json(nullptr);
  else return nlohmann::json(v);
}

template <auto M>
void Set(StoredResult& s, const nlohmann::json& j) {
  using T = typename Member<decltype(M)>::Type;
  using V = typename Unwrap<T>::Type;
  auto& v = Part<M>(s);
  if constexpr (Unwrap<T>::kOptional) {
    if (j.is_null()) v.reset();
    else v = j.get<V>();
  } else {
    v = j.get<V>();
  }
}

}  // namespace result_fields_internal

// A field of member M (of api::RunResult, api::Execution or StoredResult) named `name`: its type
// and whether it is optional come from the member's, so a table entry cannot disagree with it.
template <auto M>
ResultField MakeResultField(std::string name, std::string row_key, std::string unit, ResultOrigin origin,
                            nlohmann::json absent = nullptr) {
  namespace in = result_fields_internal;
  using T = typename in::Member<decltype(M)>::Type;
  ResultField f;
  f.name = std::move(name);
  f.row_key = std::move(row_key);
  f.unit = std::move(unit);
  f.type = in::TypeOf<typename in::Unwrap<T>::Type>();
  f.optional = in::Unwrap<T>::kOptional;
  f.origin = origin;
  f.absent = std::move(absent);
  f.get = &in::Get<M>;
  f.set = &in::Set<M>;
  return f;
}

}  // namespace sandswim

#endif  // SANDSWIM_CORE_RESULT_FIELDS_H_
