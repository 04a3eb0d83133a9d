#!/usr/bin/env bash
# Runs a campaign end to end on this machine, the embedded default: one sandswimd with a SQLite
# file and a local worker with one engine slot per core (a bed every run waits for is prepared on
# the idle slots' cores too), the campaign submitted and followed with a progress
# view, and its U_z table printed at the end. Usage: deploy/demo.sh [CAMPAIGN] [SCALE]
#   SANDSWIM_VAR   where the database, beds and runs go (default ./var)
#   SANDSWIM_PORT  port of the daemon (default 8640)
set -euo pipefail
campaign=${1:-paper-58}
scale=${2:-smoke}
here=$(cd "$(dirname "$0")/.." && pwd)
bin=${SANDSWIM_BIN:-$here/build/bin}
var=${SANDSWIM_VAR:-./var}
port=${SANDSWIM_PORT:-8640}
workers=${SANDSWIM_LOCAL_WORKERS:-$(nproc)}
export SANDSWIM_SERVER=http://127.0.0.1:$port

for b in sandswimd sandswim-render sandswim sandswim-worker; do
  [ -x "$bin/$b" ] || { echo "demo: $bin/$b is missing: build first (cmake -S . -B build -G Ninja && cmake --build build)" >&2; exit 1; }
done
mkdir -p "$var"
"$bin/sandswimd" --db "$var/sandswim.db" --data "$var/data" --listen "127.0.0.1:$port" \
  --local-workers "$workers" >>"$var/sandswimd.log" 2>&1 &
daemon=$!
trap 'kill -TERM $daemon 2>/dev/null; wait $daemon 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  curl -fsS "$SANDSWIM_SERVER/healthz" >/dev/null 2>&1 && break
  kill -0 $daemon 2>/dev/null || { echo "demo: sandswimd exited; see $var/sandswimd.log" >&2; exit 1; }
  sleep 0.1
done
# The daemon made its token in $var/data/token (mode 0600) on its first start; its workers and the
# CLI read it from there.
# ($SANDSWIM_TOKEN, when exported, is the token instead: the daemon, its workers and the CLI all
# take it from the environment.)
token_file=$var/data/token
echo "demo: sandswimd on $SANDSWIM_SERVER with $workers local engine slots (log: $var/sandswimd.log)" >&2
if [ -n "${SANDSWIM_TOKEN:-}" ]; then
  echo "demo: dashboard $SANDSWIM_SERVER/?token=\$SANDSWIM_TOKEN" >&2
  "$bin/sandswim" submit "$campaign" --scale "$scale" --wait
else
  echo "demo: dashboard $SANDSWIM_SERVER/?token=$(cat "$token_file")" >&2
  "$bin/sandswim" --token-file "$token_file" submit "$campaign" --scale "$scale" --wait
fi
