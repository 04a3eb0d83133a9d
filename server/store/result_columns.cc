#include "server/store/result_columns.h"

#include <vector>

namespace sandswim {
namespace {

// Binds a field's JSON value (core/result_fields.h ResultField::get): null is NULL.
void BindValue(Statement& st, int index, const nlohmann::json& v) {
  if (v.is_null()) st.BindNull(index);
  else if (v.is_boolean()) st.Bind(index, v.get<bool>());
  else if (v.is_number_integer()) st.Bind(index, v.get<int64_t>());
  else if (v.is_number()) st.Bind(index, v.get<double>());
  else st.Bind(index, v.get<std::string>());
}

// A column read as its field's JSON value: NULL is null for an optional field and the type's
// zero for another (a column added by a migration holds NULL in older rows).
nlohmann::json ReadValue(const Statement& st, int col, const ResultField& f) {
  if (f.optional && st.IsNull(col)) return nullptr;
  switch (f.type) {
    case ResultType::kReal:
      return st.Double(col);
    case ResultType::kInteger:
      return st.Int(col);
    case ResultType::kBool:
      return st.Int(col) != 0;
    case ResultType::kText:
      return st.Text(col);
  }
  return nullptr;
}

int KeyField() {
  static const int kKey = [] {
    const std::vector<ResultField>& fields = ResultFields();
    for (size_t i = 0; i < fields.size(); ++i) {
      if (fields[i].name == "key") return static_cast<int>(i);
    }
    return -1;
  }();
  return kKey;
}

}  // namespace

const std::string& ResultSelectList() {
  static const std::string kList = [] {
    std::string list;
    for (const ResultField& f : ResultFields()) list += (list.empty() ? "res." : ", res.") + f.name;
    return list;
  }();
  return kList;
}

std::optional<StoredResult> ReadResult(const Statement& st, int first) {
  if (st.IsNull(first + KeyField())) return std::nullopt;
  StoredResult s;
  const std::vector<ResultField>& fields = ResultFields();
  for (size_t i = 0; i < fields.size(); ++i) fields[i].set(s, ReadValue(st, first + static_cast<int>(i), fields[i]));
  return s;
}

Status InsertResult(Transaction& t, int64_t run_id, const StoredResult& result) {
  static const std::string kSql = [] {
    std::string columns = "run_id", values = "?";
    for (const ResultField& f : ResultFields()) {
      columns += ", " + f.name;
      values += ", ?";
    }
    return "INSERT OR REPLACE INTO results (" + columns + ") VALUES (" + values + ")";
  }();
  Statement st = t.Prepare(kSql);
  st.Bind(1, run_id);
  int index = 2;
  for (const ResultField& f : ResultFields()) BindValue(st, index++, f.get(result));
  return st.Run();
}

std::string UpdateAnalysedFieldsSql() {
  std::string set;
  for (const ResultField& f : ResultFields()) {
    if (f.origin == ResultOrigin::kAnalysis) set += (set.empty() ? "" : ", ") + f.name + " = ?";
  }
  return "UPDATE results SET " + set + " WHERE run_id = ?";
}

Status UpdateAnalysedFields(Statement& prepared, int64_t run_id, const api::RunResult& result) {
  const StoredResult s{result, {}, {}, 0};
  prepared.Reset();
  int index = 1;
  for (const ResultField& f : ResultFields()) {
    if (f.origin == ResultOrigin::kAnalysis) BindValue(prepared, index++, f.get(s));
  }
  prepared.Bind(index, run_id);
  return prepared.Run();
}

}  // namespace sandswim
