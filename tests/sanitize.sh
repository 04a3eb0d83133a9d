#!/usr/bin/env bash
# Builds sandswim with a sanitizer, apart from the main build, and runs the tests it can watch.
#
#   tests/sanitize.sh address [BUILD_DIR]   AddressSanitizer + UndefinedBehaviorSanitizer (gcc): every
#                                           fast test (ctest -LE "engine|crash|fuzz|browser|slurm")
#   tests/sanitize.sh thread [BUILD_DIR]    ThreadSanitizer (gcc): the daemon's concurrent parts: the
#                                           store and its group commit, the lease queue, the live
#                                           feed, the HTTP server and routes (server_tests), and the real
#                                           daemon started by its tests
#
# BUILD_DIR defaults to build-asan or build-tsan. On demand (a sanitized build takes about as long
# as the main one, and its tests run several times slower): CI runs the fuzz targets, which are
# built with ASan and UBSan, instead. Any report fails the run (halt_on_error); the report is in
# BUILD_DIR/Testing/Temporary/LastTest.log.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
kind=${1:?usage: tests/sanitize.sh address|thread [BUILD_DIR]}
case "$kind" in
  address)
    build=${2:-$root/build-asan}
    flags="-fsanitize=address,undefined -fno-sanitize-recover=undefined -fno-omit-frame-pointer"
    export ASAN_OPTIONS=halt_on_error=1:detect_leaks=1:abort_on_error=0
    export LSAN_OPTIONS=suppressions=$root/tests/lsan.supp
    export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
    targets=()
    tests=(-LE "engine|crash|fuzz|browser|slurm")
    ;;
  thread)
    build=${2:-$root/build-tsan}
    flags="-fsanitize=thread -fno-omit-frame-pointer"
    # The HTTP library and the logger are Debian's shared libraries, not instrumented: TSan cannot
    # see the guard of a function-local static they initialise on first use (the logger's
    # registry, the library's own static strings), and reported those 6 times in the first run
    # here. Races are judged where instrumented code runs; a race in sandswim's own code is still
    # reported (its frames are instrumented).
    export TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:ignore_noninstrumented_modules=1
    targets=(--target server_tests sandswimd sandswim-render)
    tests=(-R "^(StoreTest|DatabaseTest|GroupCommit|LeaseQueue|LiveFeed|Routes|Sandswimd|GuardedHttpServer)")
    ;;
  *)
    echo "sanitize: address or thread, not '$kind'" >&2
    exit 2
    ;;
esac
cmake -S "$root" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS="$flags" -DCMAKE_C_FLAGS="$flags" \
  -DCMAKE_EXE_LINKER_FLAGS="${flags%% *}" -DCMAKE_SHARED_LINKER_FLAGS="${flags%% *}"
start=$(date +%s)
cmake --build "$build" "${targets[@]}"
echo "sanitize ($kind): built in $(( $(date +%s) - start )) s"
ctest --test-dir "$build" "${tests[@]}" -j2 --output-on-failure
