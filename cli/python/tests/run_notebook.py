"""Executes examples/baseline.ipynb with Debian's nbconvert against a real sandswimd and worker.

The notebook runs as a user's would: in the daemon's directory (./var/data/token is the daemon's
token file) with $SANDSWIM_SERVER naming it, nothing else given. Prints its cells and run time;
exits non-zero when a cell fails (nbconvert stops there and says which). Usage:
    /usr/bin/python3 cli/python/tests/run_notebook.py WORKDIR
The executed notebook is left in WORKDIR/service/baseline.ipynb for reading.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from service import Service  # noqa: E402

NOTEBOOK = os.path.join(HERE, "..", "examples", "baseline.ipynb")


def main() -> int:
    work = os.path.abspath(sys.argv[1] if len(sys.argv) > 1 else "notebook-run")
    shutil.rmtree(work, ignore_errors=True)
    with Service(os.path.join(work, "service"), pace=0.1) as service:
        target = os.path.join(service.root, "baseline.ipynb")
        shutil.copyfile(NOTEBOOK, target)
        env = {k: v for k, v in os.environ.items() if k != "SANDSWIM_TOKEN"}
        env["SANDSWIM_SERVER"] = service.url
        # The client from this tree (the python_client test checks the pip-installed one).
        env["PYTHONPATH"] = os.pathsep.join(p for p in (os.path.join(HERE, ".."), env.get("PYTHONPATH")) if p)
        env.setdefault("PYDEVD_DISABLE_FILE_VALIDATION", "1")  # the kernel's debugger notice, not ours
        env.setdefault("MPLBACKEND", "module://matplotlib_inline.backend_inline")
        started = time.monotonic()
        done = subprocess.run([sys.executable, "-m", "nbconvert", "--to", "notebook", "--execute", "--inplace",
                               "--ExecutePreprocessor.timeout=900", "--ExecutePreprocessor.kernel_name=python3",
                               target], cwd=service.root, env=env)
        took = time.monotonic() - started
        if done.returncode != 0:
            print(service.worker_output()[-3000:], file=sys.stderr)
            return done.returncode
    with open(target, encoding="utf-8") as f:
        nb = json.load(f)
    code = [c for c in nb["cells"] if c["cell_type"] == "code"]
    errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    images = sum(1 for c in code for o in c.get("outputs", []) if "image/png" in o.get("data", {})
                 or "image/svg+xml" in o.get("data", {}))
    print(f"notebook: {len(nb['cells'])} cells ({len(code)} code), {images} figures, executed in {took:.1f} s "
          f"against {service.url} (truth engine); errors: {len(errors)}")
    return 1 if errors or images < 3 else 0


if __name__ == "__main__":
    sys.exit(main())
