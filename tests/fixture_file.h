// Test support: the text of a file under tests/fixtures/ (real engine logs, dumps and decks), for
// the unit tests beside the code, and a temporary directory. SANDSWIM_SOURCE_DIR is the source root (each test target's
// CMakeLists.txt defines it); a missing fixture reads as "" and the test's own checks fail.
//
// Thread safety: reads a file; no shared state.
#ifndef SANDSWIM_TESTS_FIXTURE_FILE_H_
#define SANDSWIM_TESTS_FIXTURE_FILE_H_

#include <stdlib.h>

#include <fstream>
#include <sstream>
#include <string>

namespace sandswim {

// The engine version the unit tests' fake runs report.
inline constexpr char kTestEngine[] = "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, test)";

}  // namespace sandswim

namespace sandswim::testing {

// A new, empty directory /tmp/sandswim-<tag>-XXXXXX for one test's files ("/tmp" if none can be
// made: the test's own checks then fail).
inline std::string TempDir(const std::string& tag) {
  std::string tmpl = "/tmp/sandswim-" + tag + "-XXXXXX";
  const char* d = mkdtemp(tmpl.data());
  return d ? d : "/tmp";
}

inline std::string Fixture(const std::string& name) {
  std::ifstream in(std::string(SANDSWIM_SOURCE_DIR) + "/tests/fixtures/" + name, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

}  // namespace sandswim::testing

#endif  // SANDSWIM_TESTS_FIXTURE_FILE_H_
