#!/usr/bin/env bash
# Installs everything sandswim needs to build, test and run, from Debian 12's packages.
# Idempotent; run as root (or with sudo). Used by README.md's commands and by .ci/run.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config
  liggghts libliggghts-dev openmpi-bin libopenmpi-dev
  libsqlite3-dev sqlite3 nlohmann-json3-dev libcpp-httplib-dev libspdlog-dev
  libssl-dev zlib1g-dev libbrotli-dev   # cpp-httplib's pkg-config asks for these
  libcli11-dev                          # the CLI's argument parsing
  libgsl-dev                            # the paper's fits, eqs. 8 and 9 and f_c (core/fit.h)
  libplplot-dev plplot-driver-cairo     # figures as SVG and PNG (server/analysis/figures.h; cairo draws the PNGs)
  libgtest-dev libgmock-dev curl procps
  clang-14 libclang-rt-14-dev           # the fuzz targets (tests/fuzz): libFuzzer and the sanitizers' runtimes
  chromium chromium-driver              # the dashboard's browser tests (tests/browser), headless
  # The Python client (cli/python) and its example notebook, run by Debian's /usr/bin/python3:
  # requests and pandas for the client, tqdm for its progress bar, venv, pip, setuptools and wheel for
  # `pip install` into a venv with no index (PEP 668 keeps pip out of the system),
  # pytest and mypy for its tests, and nbconvert, ipykernel and matplotlib to execute the notebook.
  python3-requests python3-pandas python3-tqdm
  python3-venv python3-pip python3-setuptools python3-wheel python3-pytest python3-mypy
  python3-nbconvert python3-ipykernel python3-matplotlib
  # Slurm, for `sandswim slurm submit` and the tests/slurm test, which starts a real single-node
  # cluster from these itself (deploy/slurm/local-cluster.sh, no systemd needed).
  slurmctld slurmd slurm-client munge
)
# The dashboard's one npm package (server/dashboard/package-lock.json) and the OpenAPI validator
# (tests/openapi/package-lock.json) are installed by the build with npm: Debian's npm unless the
# machine already has one.
command -v npm >/dev/null 2>&1 || packages+=(npm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "sandswim: installing ${missing[*]}" >&2
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
