#include "core/result_table.h"

#include "core/result_fields.h"

namespace sandswim {

const std::vector<std::string>& ResultColumns() {
  static const std::vector<std::string> kColumns = [] {
    // The run's and its point's, then its U_z as text, then the stored result's (ResultFields).
    std::vector<std::string> columns = {"run_id", "key",        "state",          "mode",      "A",      "f",
                                        "Omega",  "omega",      "axis",           "duration_s", "run_duration_s",
                                        "replicate", "bed_id", "Uz_text"};
    for (const ResultField& f : ResultFields()) {
      if (!f.row_key.empty()) columns.push_back(f.row_key);
    }
    return columns;
  }();
  return kColumns;
}

std::string MaterialCsvColumn(const MaterialField& field) {
  std::string column(field.name);
  if (field.unit.empty()) return column;
  column += '_';
  for (char ch : field.unit) {
    if (ch == '/') column += '_';
    else if (ch != '^') column += ch;
  }
  return column;
}

const std::vector<std::string>& ResultCsvColumns() {
  static const std::vector<std::string> kColumns = [] {
    std::vector<std::string> columns = ResultColumns();
    for (const MaterialField& f : MaterialFields()) columns.push_back(MaterialCsvColumn(f));
    return columns;
  }();
  return kColumns;
}

nlohmann::json ResultCsvRow(const nlohmann::json& row) {
  nlohmann::json out = row;
  for (const MaterialField& f : MaterialFields()) {
    const std::string name(f.name);
    auto it = row.find(name);
    nlohmann::json value = it != row.end() && it->is_number() ? *it : nlohmann::json(kTable1.*f.member);
    out.erase(name);  // before: a dimensionless field's column is its name
    out[MaterialCsvColumn(f)] = std::move(value);
  }
  return out;
}

std::string CsvCell(const nlohmann::json& v) {
  if (v.is_null()) return "";
  if (v.is_array()) {
    std::string joined;
    for (const auto& e : v) joined += (joined.empty() ? "" : ";") + (e.is_string() ? e.get<std::string>() : e.dump());
    return CsvCell(nlohmann::json(joined));
  }
  if (!v.is_string()) return v.dump();  // shortest round-trip form for numbers
  std::string s = v.get<std::string>();
  if (s.find_first_of(",\"\n\r") == std::string::npos) return s;
  std::string quoted = "\"";
  for (char ch : s) quoted += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return quoted + "\"";
}

std::string RowsToCsv(const std::vector<nlohmann::json>& rows, const std::vector<std::string>& columns) {
  std::string out;
  for (size_t i = 0; i < columns.size(); ++i) out += (i ? "," : "") + columns[i];
  out += "\n";
  for (const auto& row : rows) {
    for (size_t i = 0; i < columns.size(); ++i) {
      if (i) out += ",";
      auto it = row.find(columns[i]);
      if (it != row.end()) out += CsvCell(*it);
    }
    out += "\n";
  }
  return out;
}

}  // namespace sandswim
