// Test support: the text of a file under tests/fixtures/ (real engine logs, dumps and decks), for
// the unit tests beside the code. SANDSWIM_SOURCE_DIR is the source root (each test target's
// CMakeLists.txt defines it); a missing fixture reads as "" and the test's own checks fail.
//
// Thread safety: reads a file; no shared state.
#ifndef SANDSWIM_TESTS_FIXTURE_FILE_H_
#define SANDSWIM_TESTS_FIXTURE_FILE_H_

#include <fstream>
#include <sstream>
#include <string>

namespace sandswim::testing {

inline std::string Fixture(const std::string& name) {
  std::ifstream in(std::string(SANDSWIM_SOURCE_DIR) + "/tests/fixtures/" + name, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_FIXTURE_FILE_H_
