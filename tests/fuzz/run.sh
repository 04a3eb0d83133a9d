#!/usr/bin/env bash
# Builds sandswim's fuzz targets with clang (libFuzzer, AddressSanitizer, UndefinedBehaviorSanitizer)
# and runs each for SECONDS on a corpus seeded from the repository's own files.
#
#   tests/fuzz/run.sh BUILD_DIR [SECONDS]
#
# BUILD_DIR is the main build (the targets take its generated, embedded templates); the fuzz build
# goes to BUILD_DIR/fuzz. ctest runs it for 5 s a target (test `fuzz`); a long run on demand:
#   tests/fuzz/run.sh build 3600
# Targets: fuzz_sweep (sweep, campaign and submission JSON, planned when it parses), fuzz_dump (a
# trajectory dump as the worker follows it, a full-bed snapshot as the daemon checks an upload),
# fuzz_engine_log (the engine's log as the worker judges a job), fuzz_request (what a client sends
# on a connection, through the HTTP library's parser and sandswimd's server, routes and handlers on
# a real SQLite file). SANDSWIM_FUZZ_TARGETS="..." picks some. Each first replays every input in
# tests/fuzz/regressions/TARGET/ (inputs that once crashed it: keep each one there, beside the fix);
# a new crash is written to BUILD_DIR/fuzz/crashes/ and fails the run -- copy it into regressions.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
build=$(cd "${1:?usage: run.sh BUILD_DIR [SECONDS]}" && pwd)
seconds=${2:-10}
cxx=${SANDSWIM_FUZZ_CXX:-$(command -v clang++-14 || command -v clang++ || true)}
if [ -z "$cxx" ]; then
  echo "fuzz: no clang++ (deploy/install-deps.sh installs clang-14 and libclang-rt-14-dev)" >&2
  exit 1
fi
out=$build/fuzz
mkdir -p "$out/obj" "$out/crashes"
sanitize="-fsanitize=address,undefined -fno-sanitize-recover=undefined"
flags=(-std=c++17 ${SANDSWIM_FUZZ_OPT:--O1} -gline-tables-only -fno-omit-frame-pointer $sanitize -I"$root")

# The libraries once, as objects, compiled in batches of 16 sources (a unity build, as the main
# build's: the big headers are parsed once a batch, not once a file; 16 took 129 s of CPU against
# 149 s for 8); a batch is rebuilt when one of its sources, or any header, is newer than its
# object. The core serves every target; the platform and server libraries (and the HTTP
# library's flags, which change its classes' layout) only fuzz_request.
mkdir -p "$out/unity"
batch=16
batches() {  # batches NAME SOURCES...: appends each batch's (unity source, object) to jobs, object to $2's array
  local name=$1 list=$2
  shift 2
  local sources=("$@") i unity obj src
  for ((i = 0; i < ${#sources[@]}; i += batch)); do
    unity=$out/unity/${name}_$((i / batch)).cc
    obj=$out/obj/${name}_$((i / batch)).o
    {
      for src in "${sources[@]:i:batch}"; do printf '#include "%s"\n' "$src"; done
    } > "$unity.new"
    if cmp -s "$unity.new" "$unity"; then rm "$unity.new"; else mv "$unity.new" "$unity"; rm -f "$obj"; fi
    for src in "${sources[@]:i:batch}"; do if [ "$src" -nt "$obj" ]; then rm -f "$obj"; fi; done
    if [ -f "$obj" ] && [ -n "$(find "$root/core" "$root/platform" "$root/server" -name '*.h' -newer "$obj" -print -quit)" ]; then
      rm -f "$obj"  # a header changed: a class's layout may have
    fi
    eval "$list+=(\"\$obj\")"
    jobs+=("$unity" "$obj")
  done
}
library_sources() {  # library_sources DIR...: their .cc files but tests and programs' mains
  local f
  for f in $(printf '%s/*.cc\n' "${@%/}"); do
    case "$f" in *_test.cc | */main.cc | */render_main.cc | */room_link_check.cc) continue ;; esac
    [ -f "$f" ] && printf '%s\n' "$f"
  done
}
targets=(${SANDSWIM_FUZZ_TARGETS:-fuzz_sweep fuzz_dump fuzz_engine_log fuzz_request})
objs=("$out/obj/templates_embedded.o")
server_objs=("$out/obj/schema_embedded.o" "$out/obj/dashboard_embedded.o" "$out/obj/help_embedded.o")
jobs=("$build/templates/sandswim_templates_embedded.cc" "$out/obj/templates_embedded.o")
mapfile -t core_sources < <(library_sources "$root/core")
batches core objs "${core_sources[@]}"
if [[ " ${targets[*]} " == *" fuzz_request "* ]]; then
  mapfile -t server_sources < <(library_sources "$root/platform"; library_sources "$root/server" "$root"/server/*/)
  batches server server_objs "${server_sources[@]}"
  jobs+=("$build/templates/sandswim_schema_embedded.cc" "$out/obj/schema_embedded.o"
         "$build/server/sandswim_dashboard_embedded.cc" "$out/obj/dashboard_embedded.o"
         "$build/server/sandswim_help_embedded.cc" "$out/obj/help_embedded.o")
fi
# The HTTP library's and the figures' flags for every object, so that all see one layout.
read -r -a lib_cflags <<< "$(pkg-config --cflags cpp-httplib plplot spdlog)"
flags+=("${lib_cflags[@]}")
# Objects built with other flags (another SANDSWIM_FUZZ_OPT, another compiler) are built again.
if [ "$(cat "$out/obj/flags" 2>/dev/null)" != "$cxx ${flags[*]}" ]; then
  rm -f "$out"/obj/*.o
  printf '%s' "$cxx ${flags[*]}" > "$out/obj/flags"
fi
start=$(date +%s)
printf '%s\0%s\0' "${jobs[@]}" | FLAGS="${flags[*]}" xargs -0 -n 2 -P "$(nproc)" bash -c \
  'src=$0 obj=$1; if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ]; then '"$cxx"' $FLAGS -fsanitize=fuzzer-no-link -c "$src" -o "$obj"; fi'
echo "fuzz: libraries built with $cxx in $(( $(date +%s) - start )) s"

seed() {  # seed TARGET FILES...: the corpus starts from these
  local dir=$out/corpus/$1
  shift
  mkdir -p "$dir"
  for f in "$@"; do [ -f "$f" ] && cp -n "$f" "$dir/" || true; done
}
seed fuzz_sweep "$root"/templates/campaigns/*.json
printf '%s' '{"name": "omega-sign", "scale": "smoke", "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 0.3}, "axes": [{"param": "Omega", "values": [-80, 80]}], "snapshots": [0, 0.5, 1], "precision": {"uz_rel": 0.1, "max_duration_s": 2}, "replicates": 2}' \
  > "$out/corpus/fuzz_sweep/example-sweep.json"
seed fuzz_dump "$root"/tests/fixtures/*.dump
seed fuzz_engine_log "$root"/tests/fixtures/*.log "$root"/tests/fixtures/runs/*/log.liggghts
# Requests as a client sends them: the API's own examples and a worker's calls.
mkdir -p "$out/corpus/fuzz_request"
request() {  # request NAME METHOD PATH [BODY]
  local body=${4-}
  printf '%s %s HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: %d\r\n\r\n%s' \
    "$2" "$3" "${#body}" "$body" > "$out/corpus/fuzz_request/$1"
}
request sweep POST /api/v1/sweeps "$(cat "$out/corpus/fuzz_sweep/example-sweep.json")"
request campaign POST /api/v1/sweeps '{"campaign": "paper-58", "scale": "smoke"}'
request status GET /api/v1/sweeps/1
request runs GET '/api/v1/runs?sweep=1&state=queued&limit=10'
request results GET '/api/v1/sweeps/1/results?format=csv'
request run GET /api/v1/runs/1
request figure GET /api/v1/sweeps/1/uz.svg
request lease POST /api/v1/leases '{"worker": "w", "host": "h", "ranks": 1}'
request heartbeat POST /api/v1/leases/abc/heartbeat '{"sim_time_s": 0.1, "so_z": -0.01, "step": 10}'
request cancel POST /api/v1/sweeps/1/cancel '{}'
request metrics GET /metrics

# The targets, two at a time.
start=$(date +%s)
read -r -a request_libs <<< "$(pkg-config --libs cpp-httplib plplot spdlog) -lsqlite3"
link() {  # link TARGET
  local extra=()
  if [ "$1" = fuzz_request ]; then extra=("${server_objs[@]}"); fi
  "$cxx" "${flags[@]}" -fsanitize=fuzzer "$root/tests/fuzz/$1.cc" "${extra[@]}" "${objs[@]}" \
    $([ "$1" = fuzz_request ] && printf '%s ' "${request_libs[@]}") -lssl -lcrypto -lgsl -lgslcblas -lm -o "$out/$1"
}
pids=()
for target in "${targets[@]}"; do
  link "$target" &
  pids+=($!)
  if [ ${#pids[@]} -ge "$(nproc)" ]; then wait "${pids[0]}"; pids=("${pids[@]:1}"); fi
done
for pid in "${pids[@]}"; do wait "$pid"; done
echo "fuzz: targets built in $(( $(date +%s) - start )) s"

status=0
for target in "${targets[@]}"; do
  regressions=("$root"/tests/fuzz/regressions/$target/*)
  if [ -e "${regressions[0]}" ]; then
    "$out/$target" "${regressions[@]}" > "$out/$target.regressions.log" 2>&1 || {
      echo "fuzz: $target fails a regression input again (see $out/$target.regressions.log)" >&2
      status=1
    }
  fi
  if "$out/$target" "$out/corpus/$target" -max_total_time="$seconds" -rss_limit_mb=2048 -max_len=65536 \
    -artifact_prefix="$out/crashes/$target-" -print_final_stats=1 > "$out/$target.log" 2>&1; then
    runs=$(grep -o 'Done [0-9]* runs' "$out/$target.log" | tail -1 | grep -o '[0-9]*' || echo "?")
    echo "fuzz: $target: $runs executions in $seconds s, no crash (corpus $(ls "$out/corpus/$target" | wc -l) inputs)"
  else
    echo "fuzz: $target CRASHED; the input is in $out/crashes/, the report in $out/$target.log:" >&2
    grep -m 5 -E "ERROR|runtime error|SUMMARY" "$out/$target.log" >&2 || true
    status=1
  fi
done
exit $status
