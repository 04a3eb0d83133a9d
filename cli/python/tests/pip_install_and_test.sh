#!/usr/bin/env bash
# The Python client as a user installs it, tested against a real daemon: a venv that sees Debian's
# packages (python3-requests, python3-pandas; PEP 668 keeps pip out of the system's Python),
# `pip install` of a copy of cli/python with no package index (its dependencies must already be
# there), then the client's tests (pytest) with the venv's Python, checking they import the
# installed copy. Usage: pip_install_and_test.sh PYTHON SOURCE_DIR WORK_DIR
set -euo pipefail
python=$1
source_dir=$2
work=$3
rm -rf "$work"
mkdir -p "$work"
# A copy: pip builds in the tree it is given, and the source tree stays clean.
cp -r "$source_dir" "$work/src"
rm -rf "$work/src/tests" "$work/src/examples"
# --without-pip: the venv's Python runs Debian's pip (python3-pip, seen through the system's site
# packages), which installs into the venv; bootstrapping a pip of its own took 9 of the test's seconds.
"$python" -m venv --system-site-packages --without-pip "$work/venv"
"$work/venv/bin/python" -m pip install --quiet --no-index --no-build-isolation "$work/src"
"$work/venv/bin/python" -m pip show sandswim | sed -n '1,2p'
cd "$work"
export PYTHONDONTWRITEBYTECODE=1 SANDSWIM_EXPECT_INSTALLED_IN="$work/venv" SANDSWIM_PYTHON_TEST_DIR="$work"
exec "$work/venv/bin/python" -m pytest -q -p no:cacheprovider "$source_dir/tests"
