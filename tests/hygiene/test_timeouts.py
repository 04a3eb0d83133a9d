#!/usr/bin/env python3
"""Every ctest test has a TIMEOUT of its own (ctest test `test_timeouts`).

CI runs ctest without --timeout (.ci/run), so a test registered without one could hang CI for
ctest's default of 1500 s -- or for ever under a DART_TESTING_TIMEOUT of 0. Each CMakeLists gives
its tests a TIMEOUT by label (unit 60 s, the engine and service tests more); this check lists any
test that has none, so that a new add_test without it fails here rather than in a hung CI.

Usage: test_timeouts.py CTEST BUILD_DIR. Exit status 1 with one line per test without a TIMEOUT.
"""
import json
import subprocess
import sys


def main():
    ctest, build = sys.argv[1], sys.argv[2]
    out = subprocess.run([ctest, "--test-dir", build, "--show-only=json-v1"], check=True, capture_output=True,
                         text=True, timeout=50).stdout
    tests = json.loads(out)["tests"]
    missing = []
    for t in tests:
        props = {p["name"]: p["value"] for p in t.get("properties", [])}
        if float(props.get("TIMEOUT", 0)) <= 0:
            missing.append(t["name"])
    for name in missing:
        print(f"{name}: no TIMEOUT: give it one (set_tests_properties ... TIMEOUT, or the PROPERTIES of its "
              f"gtest_discover_tests) above its slowest CI time")
    print(f"{len(tests)} tests, {len(tests) - len(missing)} with a TIMEOUT")
    return 1 if missing or not tests else 0


if __name__ == "__main__":
    sys.exit(main())
