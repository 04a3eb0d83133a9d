"""The Python client against a REAL sandswimd and sandswim-worker (truth engine, tests/service.py).

Run: /usr/bin/python3 -m pytest cli/python/tests (ctest: python_client, from a venv the package
was pip-installed into). Each test reads what the daemon itself answers for comparison, so no
number here is hard-coded.
"""

from __future__ import annotations

import io
import json
import os
import tempfile

import pandas as pd
import pytest
import requests

import sandswim
import sandswim.client as sandswim_client
from sandswim import Client, SandswimError, Submission, find_token
from service import Service

BASELINE = {
    "name": "baseline",
    "scale": "smoke",
    "replicates": 3,
    "base": {"mode": "oscillatory", "A": 0.03, "f": 3, "Omega": -80, "duration_s": 5},
    "axes": [{"param": "Omega", "values": [-80, 80]}],
}


@pytest.fixture(scope="module")
def service():
    root = os.environ.get("SANDSWIM_PYTHON_TEST_DIR") or tempfile.mkdtemp(prefix="sandswim-python-")
    with Service(os.path.join(root, "service")) as s:
        yield s
        print(s.worker_output()[-2000:])


@pytest.fixture(scope="module")
def client(service):
    with Client(service.url, token_file=service.token_file) as c:
        yield c


@pytest.fixture(scope="module")
def baseline(client):
    job = client.submit(BASELINE)
    client.wait(job, timeout=300, progress=False)
    return job


def raw(service, path):
    r = requests.get(service.url + path, headers={"Authorization": "Bearer " + service.token}, timeout=60)
    r.raise_for_status()
    return r


# ---- the package --------------------------------------------------------------------------------

def test_version_is_the_api_version_the_daemon_serves(client):
    served = client.api()["info"]["version"]
    assert sandswim.API_VERSION == served
    assert sandswim.__version__.split(".")[0] == served


def test_a_daemon_serving_another_api_version_is_refused_with_what_to_do():
    class Newer(Client):
        def api(self):
            return {"openapi": "3.0.3", "info": {"version": "2"}, "paths": {}}

    with pytest.raises(SandswimError) as e:
        Newer("http://127.0.0.1:9", token="x").results(1)
    assert e.value.field == "version"
    assert "pip install cli/python" in str(e.value)


def test_package_is_typed_and_the_one_under_test():
    assert os.path.exists(os.path.join(os.path.dirname(sandswim.__file__), "py.typed"))
    # ctest runs these tests in a venv the package was pip-installed into: that copy, not the source.
    installed = os.environ.get("SANDSWIM_EXPECT_INSTALLED_IN")
    if installed:
        assert os.path.realpath(sandswim.__file__).startswith(os.path.realpath(installed))


# ---- the token: the CLI's rule (platform/token.h) -----------------------------------------------

def test_token_order_given_then_file_then_environment_then_loopback_default(tmp_path):
    file = tmp_path / "token"
    file.write_text("  from-file\n")
    default = tmp_path / "default"
    default.write_text("from-default\n")
    env = {"SANDSWIM_TOKEN": " from-env "}
    url = "http://127.0.0.1:8640"
    assert find_token(url, "given", str(file), env, str(default)) == "given"
    assert find_token(url, None, str(file), env, str(default)) == "from-file"
    assert find_token(url, None, None, env, str(default)) == "from-env"
    assert find_token(url, None, None, {}, str(default)) == "from-default"
    assert find_token("http://localhost:8640", None, None, {}, str(default)) == "from-default"
    assert find_token("http://[::1]:8640", None, None, {}, str(default)) == "from-default"
    # The default file never goes to another machine.
    assert find_token("http://10.0.0.7:8640", None, None, {}, str(default)) is None
    assert find_token(url, None, None, {}, str(tmp_path / "absent")) is None


def test_defaults_are_the_clis():
    # Two languages, one rule: the C++ constants the CLI uses, read from this source tree.
    import re

    from sandswim import token

    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..")
    with open(os.path.join(root, "platform", "http_client.h"), encoding="utf-8") as f:
        server = re.search(r'kDefaultServer = "([^"]+)"', f.read()).group(1)
    with open(os.path.join(root, "platform", "token.h"), encoding="utf-8") as f:
        data_dir = re.search(r'kDefaultDataDir = "([^"]+)"', f.read()).group(1)
    assert token.DEFAULT_SERVER == server
    assert os.path.normpath(token.DEFAULT_TOKEN_FILE) == os.path.normpath(os.path.join(data_dir, "token"))


def test_an_unreadable_or_empty_token_file_is_an_error_naming_it(tmp_path):
    empty = tmp_path / "empty"
    empty.write_text("\n")
    with pytest.raises(SandswimError) as e:
        find_token("http://127.0.0.1:1", None, str(empty), {})
    assert e.value.field == "token_file" and "empty" in str(e.value)
    with pytest.raises(SandswimError) as e:
        find_token("http://127.0.0.1:1", None, str(tmp_path / "absent"), {})
    assert e.value.field == "token_file"


def test_client_finds_the_daemons_token_file_from_its_directory(service, monkeypatch):
    monkeypatch.delenv("SANDSWIM_TOKEN", raising=False)
    monkeypatch.chdir(service.root)  # ./var/data/token is the daemon's
    Client(service.url).sweeps()  # a 401 without the token


def test_without_the_token_the_refusal_names_authorization_and_what_to_do(service, monkeypatch, tmp_path):
    monkeypatch.delenv("SANDSWIM_TOKEN", raising=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SandswimError) as e:
        Client(service.url).sweeps()
    assert e.value.status == 401
    assert e.value.field == "Authorization"
    assert "token_file" in str(e.value) and "SANDSWIM_TOKEN" in str(e.value)


def test_an_unreachable_daemon_says_so():
    with pytest.raises(SandswimError) as e:
        Client("http://127.0.0.1:9", token="x", timeout=5).sweeps()
    assert e.value.status is None
    assert "cannot reach sandswimd at http://127.0.0.1:9" in str(e.value)


# ---- bad input: the daemon's refusal, unchanged ----------------------------------------------------

def test_a_bad_sweep_is_the_daemons_refusal_naming_the_field_and_nothing_is_stored(client):
    before = len(client.sweeps())
    bad = json.loads(json.dumps(BASELINE))
    bad["base"]["A"] = -0.03
    with pytest.raises(SandswimError) as e:
        client.submit(bad)
    assert e.value.status == 400
    assert e.value.field == "base.A"
    assert str(e.value) == "base.A: must be > 0 m, got -0.03"
    assert e.value.problem["type"].startswith("urn:sandswim:problem:")
    assert len(client.sweeps()) == before


def test_a_missing_file_or_bad_target_is_named():
    c = Client("http://127.0.0.1:9", token="x")
    with pytest.raises(SandswimError) as e:
        c.submit("no/such/sweep.json")
    assert e.value.field == "what"
    with pytest.raises(SandswimError) as e:
        c.status("twelve")
    assert e.value.field == "target"


# ---- submit, wait, results ----------------------------------------------------------------------

def test_wait_shows_progress_and_returns_when_nothing_is_queued_or_running(client):
    job = client.submit(dict(BASELINE, name="baseline-progress", replicates=1))
    assert isinstance(job, Submission) and len(job.sweeps) == 1 and job.campaign_run is None
    out = io.StringIO()
    import sandswim.client as module
    bar = module._Progress("sweep", True, out)
    bar._bar = None  # the plain line (tqdm, when installed, draws a bar instead)
    counts = client.status(job)
    bar.update(counts)
    final = client.wait(job, timeout=300, progress=False)
    assert final["queued"] == 0 and final["running"] == 0
    assert final["done"] + final["failed"] + final["cancelled"] == job.runs
    assert f"/{job.runs} finished" in out.getvalue()


def test_wait_times_out_with_what_is_left():
    class Stuck(Client):
        def status(self, target):
            return {"queued": 3, "running": 1, "done": 0, "failed": 0, "cancelled": 0}

    with pytest.raises(SandswimError) as e:
        Stuck("http://127.0.0.1:9", token="x").wait(5, timeout=0.0, progress=False, sleep=lambda s: None)
    assert e.value.field == "timeout"
    assert "3 queued and 1 running" in str(e.value)


def test_results_have_units_in_names_errors_beside_values_and_the_daemons_numbers(service, client, baseline):
    frame = client.results(baseline)
    reply = raw(service, f"/api/v1/sweeps/{baseline.sweeps[0]}/results").json()
    assert len(frame) == len(reply["results"]) == 6
    columns = list(frame.columns)
    for name in ("A [m]", "f [Hz]", "Omega [rad/s]", "Uz [m/s]", "Uz_stderr [m/s]", "Uz_ci95 [m/s]", "dz [m]"):
        assert name in columns
    uz = columns.index("Uz [m/s]")
    assert columns[uz + 1: uz + 3] == ["Uz_stderr [m/s]", "Uz_ci95 [m/s]"]
    # Every cell is the daemon's JSON value (the frame is read from its CSV): numbers to the bit,
    # strings, booleans; null is NaN.
    for row, want in zip(frame.to_dict("records"), reply["results"]):
        for name, value in row.items():
            field = name.split(" [")[0]
            expected = want.get(field)
            if expected is None:
                assert value != value or value is None, (field, value)
            else:
                assert value == expected, (field, value, expected)
                assert isinstance(value, str) == isinstance(expected, str), (field, value, expected)
    # The CSV the daemon serves has the same columns in the same order, without the units, then the
    # ten materials of the point, each named with its unit (core/result_table.h), which the frame
    # carries inside the point where they are not Table 1's.
    header = raw(service, f"/api/v1/sweeps/{baseline.sweeps[0]}/results?format=csv").text.splitlines()[0].split(",")
    assert [c.split(" [")[0] for c in columns] == header[: len(columns)]
    materials = header[len(columns):]
    assert len(materials) == 10 and "so_density_kg_m3" in materials and "so_diameter_m" in materials, materials


def test_aggregates_one_row_a_point_over_three_beds(service, client, baseline):
    frame = client.aggregates(baseline)
    reply = raw(service, f"/api/v1/sweeps/{baseline.sweeps[0]}/results").json()["aggregates"]
    assert len(frame) == len(reply) == 2
    assert list(frame["replicates"]) == [a["replicates"] for a in reply] == [3, 3]
    columns = list(frame.columns)
    mean = columns.index("uz_mean [m/s]")
    assert {"uz_stderr [m/s]", "uz_ci95 [m/s]", "uz_sd_between [m/s]"} <= set(columns[mean + 1: mean + 4])
    assert list(frame["uz_mean [m/s]"]) == [a.get("uz_mean") for a in reply]


def test_a_sweep_over_several_pages_gives_the_same_tables(client, baseline, monkeypatch):
    # 6 runs, 3 beds a point, read 2 a page: the first page holds only the first point's runs,
    # the second one run of each (both aggregates, over all three beds); the frames are those of
    # one page.
    whole_results, whole_aggregates = client.results(baseline), client.aggregates(baseline)
    monkeypatch.setattr(sandswim_client, "RESULTS_PAGE_ROWS", 2)
    paged_aggregates = client.aggregates(baseline)
    assert list(paged_aggregates["replicates"]) == [3, 3]
    pd.testing.assert_frame_equal(paged_aggregates, whole_aggregates)
    pd.testing.assert_frame_equal(client.results(baseline), whole_results)


def test_trajectory_of_a_run_and_of_a_sweep(service, client, baseline):
    run_id = int(client.results(baseline)["run_id"].iloc[0])
    path = client.trajectory(run_id)
    detail = raw(service, f"/api/v1/runs/{run_id}").json()["trajectory"]
    assert list(path.columns) == ["t [s]", "x [m]", "y [m]", "z [m]"]
    assert len(path) == len(detail["z"]) > 10
    assert list(path["z [m]"]) == detail["z"]
    every = client.trajectories(baseline)
    assert set(every["run_id"]) == set(client.results(baseline)["run_id"])
    assert {"replicate", "Omega [rad/s]", "t [s]", "z [m]"} <= set(every.columns)


def test_figures_are_svg_and_png_bytes(client, baseline):
    sweep = baseline.sweeps[0]
    assert b"<svg" in client.figure("uz", sweep)[:400]
    assert client.figure("trajectories", sweep, "png").startswith(b"\x89PNG\r\n\x1a\n")
    run_id = int(client.results(baseline)["run_id"].iloc[0])
    assert client.figure("trajectory", run_id, "png").startswith(b"\x89PNG")
    with pytest.raises(SandswimError) as e:
        client.figure("uz", sweep, "gif")
    assert e.value.field == "format"


def test_beds_and_snapshots(service, client, baseline):
    beds = client.beds()
    assert len(beds) == len(raw(service, "/api/v1/beds").json()["beds"]) >= 3
    assert {"id", "scale", "replicate", "state"} <= set(beds.columns)
    assert client.bed(int(beds["id"].iloc[0]))["id"] == int(beds["id"].iloc[0])
    run_id = int(client.results(baseline)["run_id"].iloc[0])
    # The truth engine writes no full-bed snapshots: none listed, and asking for one is the
    # daemon's 404, not a crash.
    assert client.snapshots(run_id).empty
    with pytest.raises(SandswimError) as e:
        client.snapshot(run_id, 0, "vtk")
    assert e.value.status == 404


def test_a_sweep_from_a_file_and_paging_reads_every_run(service, client, baseline, tmp_path):
    file = tmp_path / "sweep.json"
    file.write_text(json.dumps(dict(BASELINE, name="baseline-from-file", replicates=2)))
    job = client.submit(str(file))
    client.wait(job, timeout=300, progress=False)
    assert len(client.results(job)) == 4
    paged = Client(service.url, token_file=service.token_file)
    paged.page_size = 3
    runs = paged.runs()
    total = sum(1 for _ in raw(service, "/api/v1/runs?limit=1000").json()["runs"])
    assert len(runs) == total > 3
    assert runs["id"].is_unique
    assert len(paged.runs(sweep=job.sweeps[0])) == 4


def test_a_campaign_by_name_its_fits_and_its_claims(service, client):
    job = client.submit("paper-58", scale="smoke")
    assert job.campaign_run is not None and len(job.sweeps) > 1
    client.wait(job, timeout=600, progress=False)
    results = client.results(job)
    assert len(results) == job.runs
    claims = client.claims(job)
    reply = raw(service, f"/api/v1/campaign-runs/{job.campaign_run}/claims").json()["claims"]
    assert list(claims["id"]) == [c["id"] for c in reply]
    assert list(claims["verdict"]) == [c["verdict"] for c in reply]
    assert set(claims["verdict"]) <= {"holds", "differs", "inconclusive"}
    # Nested fields stay, flattened: nothing the daemon adds to a claim is dropped.
    assert list(claims["rule.kind"]) == [c["rule"]["kind"] for c in reply]
    assert list(claims["missing"]) == [len(c["missing"]) for c in reply]
    parts = client.claim_parts(f"cr:{job.campaign_run}")
    assert len(parts) == sum(len(c["parts"]) for c in reply)
    figures = client.claim_figures(job.campaign_run)
    assert {"claim", "part", "value", "stderr", "lo", "hi", "unit"} <= set(figures.columns)
    sweeps = client.sweeps()
    omega = int(sweeps[(sweeps["campaign_run_id"] == job.campaign_run) & (sweeps["name"] == "Omega-sweep")]["id"].iloc[0])
    fits = client.fits(omega)
    want = raw(service, f"/api/v1/sweeps/{omega}/fits").json()
    assert len(fits) == len(want["branches"])
    if len(fits):
        assert "C1 [m/s]" in fits.columns and "C1_stderr [m/s]" in fits.columns
    assert fits.attrs["reason"] == want["reason"]
    report = client.report(job.campaign_run)
    assert "<html" in report.lower()
    assert "±" in report and "Â±" not in report  # read as UTF-8, not as Latin-1
    with pytest.raises(SandswimError) as e:
        client.claims(Submission(sweeps=(omega,)))
    assert e.value.field == "campaign_run"
