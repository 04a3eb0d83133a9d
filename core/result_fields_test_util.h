// Test support: a run's stored result with every field of its description (core/result_fields.h)
// set to a value no other field has and no default is (its position in the description shows in
// it), so that a read from a shifted column, a JSON key or a CSV column that is not its own
// cannot pass.
//
// Thread safety: pure function.
#ifndef SANDSWIM_CORE_RESULT_FIELDS_TEST_UTIL_H_
#define SANDSWIM_CORE_RESULT_FIELDS_TEST_UTIL_H_

#include <cstdint>
#include <vector>

#include "core/result_fields.h"

namespace sandswim::testing {

inline StoredResult EveryFieldSet() {
  StoredResult s;
  const std::vector<ResultField>& fields = ResultFields();
  for (size_t i = 0; i < fields.size(); ++i) {
    switch (fields[i].type) {
      case ResultType::kReal:
        fields[i].set(s, 0.125 * static_cast<double>(i + 1));
        break;
      case ResultType::kInteger:
        fields[i].set(s, static_cast<int64_t>(100 + i));
        break;
      case ResultType::kBool:
        fields[i].set(s, true);
        break;
      case ResultType::kText:
        fields[i].set(s, "text of " + fields[i].name);
        break;
    }
  }
  return s;
}

}  // namespace sandswim::testing

#endif  // SANDSWIM_CORE_RESULT_FIELDS_TEST_UTIL_H_
