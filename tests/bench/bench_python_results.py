#!/usr/bin/python3
"""bench_python_results: a notebook's results frame of 10,000 runs, fetched and built.

bench_seed_store writes a store holding a campaign of 10,000 runs with SYNTHETIC results
(tests/bench/synthetic_campaign.h); the real sandswimd serves it; the Python client
(cli/python) asks for the campaign run's results as a DataFrame, ROUNDS times. Prints the time of
Client.results() and its parts (the HTTP GET and its bytes, the JSON parse, the frame with units in
its column names), and for comparison the same table as CSV read by pandas.read_csv.

    /usr/bin/python3 tests/bench/bench_python_results.py [--rounds 5] [--build build] [--dir DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from io import StringIO

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "cli", "python"))
sys.path.insert(0, os.path.join(ROOT, "cli", "python", "tests"))

import pandas as pd  # noqa: E402
import requests  # noqa: E402

from sandswim import Client, frames  # noqa: E402
from service import Service  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--build", default=os.path.join(ROOT, "build"))
    parser.add_argument("--dir", default=os.path.join(tempfile.gettempdir(), "sandswim-bench-python-results"))
    args = parser.parse_args()
    bin_dir = os.path.join(os.path.abspath(args.build), "bin")
    os.environ.setdefault("SANDSWIMD", os.path.join(bin_dir, "sandswimd"))

    seeded = subprocess.run([os.path.join(bin_dir, "bench_seed_store"), args.dir], check=True,
                            capture_output=True, text=True)
    print(seeded.stdout.strip())
    with Service(args.dir, worker=False) as service:
        client = Client(service.url, token_file=service.token_file)
        campaign_run = client.get("/api/v1/campaign-runs")["campaign_runs"][0]["id"]
        path = f"/api/v1/campaign-runs/{campaign_run}/results?limit=10000"  # one page, as Client.results asks
        session = requests.Session()
        session.headers["Authorization"] = "Bearer " + service.token
        schemas = frames.Schemas(client.api())
        totals, gets, parses, builds, csvs = [], [], [], [], []
        size = 0
        frame = None
        for _ in range(args.rounds):
            t0 = time.perf_counter()
            frame = client.results(f"cr:{campaign_run}")
            totals.append(time.perf_counter() - t0)
            # The same work in its parts.
            t0 = time.perf_counter()
            body = session.get(service.url + path, timeout=300).content
            t1 = time.perf_counter()
            rows = json.loads(body)["results"]
            t2 = time.perf_counter()
            frames.results_frame(rows, schemas)
            t3 = time.perf_counter()
            gets.append(t1 - t0)
            parses.append(t2 - t1)
            builds.append(t3 - t2)
            size = len(body)
            t0 = time.perf_counter()
            text = session.get(service.url + path, params={"format": "csv"}, timeout=300).text
            pd.read_csv(StringIO(text))
            csvs.append(time.perf_counter() - t0)
        assert frame is not None
        done = int((frame["state"] == "done").sum())
        med = statistics.median
        print(f"Client.results(cr:{campaign_run}): {len(frame)} rows ({done} done) x {len(frame.columns)} columns, "
              f"median of {args.rounds}: {med(totals):.2f} s (min {min(totals):.2f}, max {max(totals):.2f})")
        print(f"  parts: GET {size / 1e6:.1f} MB JSON {med(gets):.2f} s, json.loads {med(parses):.2f} s, "
              f"DataFrame with units {med(builds):.2f} s")
        print(f"  for comparison, the CSV route read by pandas.read_csv: {med(csvs):.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
