"""A real sandswimd and sandswim-worker for the client's tests and the example notebook.

The daemon runs on a fresh SQLite file with its default token handling (it makes DATA/token,
mode 0600, as on a first start) and listens on an ephemeral loopback port, read from the line it
prints. The worker's engine is sandswim-truth-engine (tests/truth/): a stand-in whose SO follows a
known law, so runs take seconds and their numbers are not physics (every result says so in its
engine_version). The programs come from $SANDSWIMD, $SANDSWIM_WORKER and $SANDSWIM_TRUTH_ENGINE
(ctest sets them), else from build/bin of this tree.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from typing import Optional

_HERE = os.path.dirname(os.path.abspath(__file__))
_BIN = os.path.normpath(os.path.join(_HERE, "..", "..", "..", "build", "bin"))


def _program(env: str, name: str) -> str:
    path = os.environ.get(env) or os.path.join(_BIN, name)
    if not os.access(path, os.X_OK):
        raise RuntimeError(f"{path} is missing: build it (cmake --build build --target {name}) or set ${env}")
    return path


class Service:
    """sandswimd under `root` (root/sandswim.db, root/var/data) and one worker with `slots` slots.

    `pace`: the truth engine's wall seconds per simulated second (0: a run is written at once).
    The token file is root/var/data/token, so a client started in `root` finds it as
    ./var/data/token, the file a daemon started with its default --data makes. A root that already
    holds sandswim.db (a benchmark's seeded store) is served as it is; `worker=False` starts none.
    """

    def __init__(self, root: str, *, slots: int = 2, pace: float = 0.0, law: str = "paper", seed: int = 1,
                 worker: bool = True) -> None:
        self.root = os.path.abspath(root)
        os.makedirs(self.root, exist_ok=True)
        self.token_file = os.path.join(self.root, "var", "data", "token")
        self._daemon_log = os.path.join(self.root, "sandswimd.out")
        self._worker_log = os.path.join(self.root, "worker.out")
        self._daemon: Optional[subprocess.Popen] = None
        self._worker: Optional[subprocess.Popen] = None
        env = {k: v for k, v in os.environ.items() if k not in ("SANDSWIM_TOKEN", "SANDSWIM_SERVER")}
        env.update(SANDSWIM_TRUTH_LAW=law, SANDSWIM_TRUTH_SEED=str(seed), SANDSWIM_TRUTH_PACE=str(pace))
        try:
            self._daemon = self._start(
                [_program("SANDSWIMD", "sandswimd"), "--db", os.path.join(self.root, "sandswim.db"),
                 "--data", os.path.join(self.root, "var", "data"), "--listen", "127.0.0.1:0",
                 "--local-workers", "0"], self._daemon_log, env)
            self.url = self._wait_for_url()
            if not worker:
                return
            self._worker = self._start(
                [_program("SANDSWIM_WORKER", "sandswim-worker"), "--server", self.url, "--token-file", self.token_file,
                 "--slots", str(slots), "--ranks", "1", "--workdir", os.path.join(self.root, "worker"),
                 "--heartbeat", "1", "--launcher", "direct",
                 "--engine", _program("SANDSWIM_TRUTH_ENGINE", "sandswim-truth-engine")], self._worker_log, env)
        except BaseException:
            self.stop()
            raise

    def _start(self, argv: list[str], log: str, env: dict[str, str]) -> subprocess.Popen:
        with open(log, "wb") as out:
            return subprocess.Popen(argv, cwd=self.root, stdout=out, stderr=subprocess.STDOUT, env=env,
                                    start_new_session=True)

    def _wait_for_url(self, timeout_s: float = 60.0) -> str:
        deadline = time.monotonic() + timeout_s
        pattern = re.compile(r"listening on (http://127\.0\.0\.1:\d+)")
        while time.monotonic() < deadline:
            text = self.daemon_output()
            found = pattern.search(text)
            if found and os.path.exists(self.token_file):
                return found.group(1)
            if self._daemon is not None and self._daemon.poll() is not None:
                break
            time.sleep(0.05)
        raise RuntimeError("sandswimd did not start; it printed:\n" + self.daemon_output())

    def daemon_output(self) -> str:
        with open(self._daemon_log, encoding="utf-8", errors="replace") as f:
            return f.read()

    def worker_output(self) -> str:
        try:
            with open(self._worker_log, encoding="utf-8", errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    @property
    def token(self) -> str:
        with open(self.token_file, encoding="utf-8") as f:
            return f.read().strip()

    def stop(self) -> None:
        """SIGTERM to the worker, then the daemon; SIGKILL to what is still there after 20 s."""
        for process in (self._worker, self._daemon):
            if process is None or process.poll() is not None:
                continue
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()

    def __enter__(self) -> "Service":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
