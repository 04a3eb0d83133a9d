#include "core/result_fields.h"

#include <algorithm>
#include <set>

#include <gtest/gtest.h>

#include "core/result_fields_test_util.h"
#include "core/result_table.h"
#include "core/trajectory.h"

namespace sandswim {
namespace {

using testing::EveryFieldSet;

bool InReport(const ResultField& f) {
  return f.origin == ResultOrigin::kAnalysis || f.origin == ResultOrigin::kRun;
}

TEST(ResultFieldsTest, NamesAndRowKeysAreEachUsedOnce) {
  std::set<std::string> names, row_keys;
  for (const ResultField& f : ResultFields()) {
    EXPECT_TRUE(names.insert(f.name).second) << f.name;
    if (!f.row_key.empty()) {
      EXPECT_TRUE(row_keys.insert(f.row_key).second) << f.row_key;
    }
  }
  // A field of the report is a member of RunResult; the others are not reported by a worker.
  EXPECT_EQ(names.count("uz"), 1u);
}

TEST(ResultFieldsTest, TypesComeFromTheMembers) {
  auto find = [](const std::string& name) {
    const auto& fields = ResultFields();
    return *std::find_if(fields.begin(), fields.end(), [&](const ResultField& f) { return f.name == name; });
  };
  EXPECT_EQ(find("uz").type, ResultType::kReal);
  EXPECT_TRUE(find("uz").optional);
  EXPECT_EQ(find("uz").unit, "m/s");
  EXPECT_EQ(find("uz_blocks").type, ResultType::kInteger);
  EXPECT_FALSE(find("uz_blocks").optional);
  EXPECT_EQ(find("precision_met").type, ResultType::kBool);
  EXPECT_TRUE(find("precision_met").optional);
  EXPECT_EQ(find("engine_version").type, ResultType::kText);
  EXPECT_EQ(find("created_at").origin, ResultOrigin::kStore);
}

// Every field of the description shows in the forms made from it: the worker's report (to_json /
// from_json of api::RunResult), the stored result's JSON, and a results row's columns and CSV.
TEST(ResultFieldsTest, EveryFieldIsInTheReportTheStoredJsonAndTheResultsColumns) {
  const StoredResult full = EveryFieldSet();
  const nlohmann::json report = full.result;
  const api::RunResult back = report.get<api::RunResult>();
  const StoredResult round{back, full.execution, full.key, full.created_at};
  const nlohmann::json stored = full;
  const std::vector<std::string>& columns = ResultColumns();
  const std::vector<std::string>& csv = ResultCsvColumns();
  for (const ResultField& f : ResultFields()) {
    EXPECT_EQ(report.contains(f.name), InReport(f)) << f.name;
    EXPECT_EQ(f.get(round), f.get(full)) << f.name << " does not survive the report";
    ASSERT_TRUE(stored.contains(f.name)) << f.name;
    EXPECT_EQ(stored[f.name], f.get(full)) << f.name;
    if (f.row_key.empty()) continue;
    EXPECT_EQ(std::count(columns.begin(), columns.end(), f.row_key), 1) << f.row_key;
    EXPECT_EQ(std::count(csv.begin(), csv.end(), f.row_key), 1) << f.row_key;
  }
  EXPECT_EQ(stored["uz_text"], DescribeUz(full.result));
}

TEST(ResultFieldsTest, AReportWithoutAFieldMeansWhatItMeantBeforeTheFieldExisted) {
  const api::RunResult old = nlohmann::json{{"uz", 0.1}}.get<api::RunResult>();
  EXPECT_EQ(old.analysis, 1);  // the old estimator
  EXPECT_EQ(old.analysed_from, "dump");
  EXPECT_FALSE(old.uz_stderr.has_value());
  EXPECT_EQ(old.uz_blocks, 0);
  const nlohmann::json bare = api::RunResult{};
  EXPECT_FALSE(bare.contains("uz"));  // an absent optional field is left out, not null
  EXPECT_THROW((nlohmann::json{{"uz_blocks", "three"}}.get<api::RunResult>()), nlohmann::json::type_error);
}

}  // namespace
}  // namespace sandswim
