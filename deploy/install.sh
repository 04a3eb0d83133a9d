#!/usr/bin/env bash
# Installs sandswim as systemd services. Idempotent; starts nothing.
#
#   cmake -S . -B build -G Ninja && ninja -C build
#   sudo deploy/install.sh [BUILD_DIR]          # BUILD_DIR defaults to ./build
#   sudoedit /etc/sandswim/sandswim.env
#   sudo systemctl enable --now sandswimd sandswim-worker@1
#
# What it does:
#   - installs sandswimd, sandswim-render (which the daemon draws each figure in, so a plotting
#     error cannot end it), sandswim, sandswim-worker and sandswim-engine-guard (which the worker
#     starts each engine under, so no engine outlives its worker) from BUILD_DIR/bin to /usr/local/bin;
#   - installs sandswimd.service and sandswim-worker@.service to /etc/systemd/system, and the
#     Slurm batch scripts (deploy/slurm) to /usr/local/share/sandswim/slurm;
#   - creates the system user "sandswim", /var/lib/sandswim (owned by it) and /etc/sandswim, and
#     copies sandswim.env.example to /etc/sandswim/sandswim.env unless that file exists;
#   - runs `systemctl daemon-reload` when systemd is running.
# DESTDIR=/some/dir stages everything under that directory instead (no user, no chown, no
# daemon-reload): that is how the script is tried without root.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
build="${1:-$here/../build}"
dest="${DESTDIR:-}"
bin_dir="$dest/usr/local/bin"
unit_dir="$dest/etc/systemd/system"
etc_dir="$dest/etc/sandswim"
state_dir="$dest/var/lib/sandswim"

if [ -z "$dest" ] && [ "$(id -u)" -ne 0 ]; then
  echo "install.sh: run as root (sudo $0 ${1:-}), or set DESTDIR to stage the files" >&2
  exit 2
fi
for b in sandswimd sandswim-render sandswim sandswim-worker sandswim-engine-guard; do
  if [ ! -x "$build/bin/$b" ]; then
    echo "install.sh: $build/bin/$b is missing; build first: cmake -S . -B build -G Ninja && ninja -C build" >&2
    exit 1
  fi
done

install -d -m 0755 "$bin_dir" "$unit_dir" "$etc_dir"
for b in sandswimd sandswim-render sandswim sandswim-worker sandswim-engine-guard; do
  install -m 0755 "$build/bin/$b" "$bin_dir/$b"
done
install -m 0644 "$here/sandswimd.service" "$unit_dir/sandswimd.service"
install -m 0644 "$here/sandswim-worker@.service" "$unit_dir/sandswim-worker@.service"
# The Slurm batch scripts, where `sandswim slurm submit` looks for them (deploy/slurm/README.md).
install -d -m 0755 "$dest/usr/local/share/sandswim/slurm"
install -m 0755 "$here/slurm/pilot.sbatch" "$here/slurm/array.sbatch" "$dest/usr/local/share/sandswim/slurm/"
if [ ! -e "$etc_dir/sandswim.env" ]; then
  install -m 0640 "$here/sandswim.env.example" "$etc_dir/sandswim.env"
  created_env=1
else
  created_env=0
fi
install -d -m 0750 "$state_dir"

if [ -z "$dest" ]; then
  if ! id -u sandswim >/dev/null 2>&1; then
    useradd --system --home-dir /var/lib/sandswim --no-create-home --shell /usr/sbin/nologin sandswim
  fi
  chown sandswim:sandswim "$state_dir"
  chgrp sandswim "$etc_dir/sandswim.env"
  if [ -d /run/systemd/system ]; then
    systemctl daemon-reload
  fi
fi

echo "sandswim installed: binaries in $bin_dir, units in $unit_dir, state in $state_dir"
if [ "$created_env" -eq 1 ]; then
  echo "edit $etc_dir/sandswim.env (database, listen address, schedules), then:"
else
  echo "kept the existing $etc_dir/sandswim.env; then:"
fi
echo "  systemctl enable --now sandswimd sandswim-worker@1"
