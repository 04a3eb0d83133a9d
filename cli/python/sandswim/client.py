"""Client: sandswimd's REST API (schema/openapi.json) from Python, tables as pandas DataFrames.

    from sandswim import Client
    c = Client("http://127.0.0.1:8640")             # the token as the CLI finds it
    job = c.submit("paper-58", scale="smoke")        # a campaign by name, a sweep dict or a file
    c.wait(job)                                      # a progress bar until nothing is queued or running
    c.results(job)                                   # one row per run: "Uz [m/s]", "Uz_stderr [m/s]", ...

The client checks nothing the daemon checks: what the daemon refuses comes back as a
SandswimError naming the field ("base.A: must be > 0 m, got -0.03"). Lists that the daemon pages
(sweeps, runs) are read to their end. One Client holds one HTTP session (keep-alive); it is not
meant to be shared between threads.
"""

from __future__ import annotations

import json
import os
import re
import sys
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Mapping, Optional, Union

import pandas as pd
import requests

from . import frames
from ._version import API_VERSION, __version__
from .errors import SandswimError
from .token import DEFAULT_SERVER, find_token

_NAME = re.compile(r"[A-Za-z0-9._-]{1,100}")  # a campaign's name, as the CLI tells it from a file


# Rows a results page is asked for: the most the daemon gives (pages are followed to the end).
RESULTS_PAGE_ROWS = 10000


@dataclass(frozen=True)
class Submission:
    """What one submission made: a campaign run (and its sweeps), or sweeps.

    Pass it to status(), wait(), results(), aggregates() or cancel(). `reply` is the daemon's whole
    answer (runs new, reused, shared, ...).
    """

    sweeps: tuple[int, ...]
    campaign_run: Optional[int] = None
    runs: int = 0
    reply: Mapping[str, Any] = field(default_factory=dict, compare=False, repr=False)


# A sweep id (12 or "12"), a campaign run ("cr:7"), or a Submission.
Target = Union[Submission, int, str]


def _targets(target: Target) -> list[tuple[str, int]]:
    """("sweeps", 12) or ("campaign-runs", 7) for each thing `target` names."""
    if isinstance(target, Submission):
        if target.campaign_run is not None:
            return [("campaign-runs", target.campaign_run)]
        return [("sweeps", s) for s in target.sweeps]
    if isinstance(target, bool):
        raise SandswimError("expected a sweep id (12), a campaign run (\"cr:7\") or a Submission", field="target")
    if isinstance(target, int):
        return [("sweeps", target)]
    text = str(target).strip()
    if text.startswith("cr:") and text[3:].isdigit():
        return [("campaign-runs", int(text[3:]))]
    if text.isdigit():
        return [("sweeps", int(text))]
    raise SandswimError(f"expected a sweep id (12), a campaign run (\"cr:7\") or a Submission, got {target!r}",
                        field="target")


def _submission_body(what: Union[Mapping[str, Any], str, "os.PathLike[str]"], scale: Optional[str]) -> dict[str, Any]:
    """The POST /api/v1/sweeps body: the CLI's rule (a file's JSON, else a campaign's name)."""
    if isinstance(what, Mapping):
        body = dict(what)
    elif os.path.isfile(what):
        try:
            with open(what, encoding="utf-8") as f:
                body = json.load(f)
        except ValueError as e:
            raise SandswimError(f"{os.fspath(what)}: malformed JSON: {e}", field="what") from None
        if not isinstance(body, dict):
            raise SandswimError(f"{os.fspath(what)}: expected a JSON object (a sweep, {{\"sweeps\": [...]}} "
                                "or {\"campaign\": NAME})", field="what")
    elif isinstance(what, str) and _NAME.fullmatch(what) and ".json" not in what:
        body = {"campaign": what}
    else:
        raise SandswimError(f"no such file: {os.fspath(what)} (give a sweep dict, a sweep JSON file or a "
                            "campaign name such as paper-58)", field="what")
    if scale:
        if isinstance(body.get("sweeps"), list) and "campaign" not in body:
            body["sweeps"] = [dict(s, scale=scale) if isinstance(s, Mapping) else s for s in body["sweeps"]]
        else:
            body["scale"] = scale
    return body


def _add_counts(total: dict[str, int], counts: Mapping[str, Any]) -> None:
    for state, n in counts.items():
        if isinstance(n, int):
            total[state] = total.get(state, 0) + n


class _Progress:
    """A progress bar (tqdm when it is installed: its notebook widget when ipywidgets is too), else
    a plain line on stderr each time the counts change."""

    def __init__(self, what: str, enabled: bool, out: Any = None) -> None:
        self._what = what
        self._enabled = enabled
        self._out = out if out is not None else sys.stderr
        self._bar: Any = None
        self._last = ""
        self._started = time.monotonic()
        self._finished_at_start: Optional[int] = None
        if not enabled:
            return
        try:
            try:
                import ipywidgets  # noqa: F401  (tqdm's notebook bar needs it)
                from tqdm.notebook import tqdm
            except ImportError:
                from tqdm import tqdm
            self._bar = tqdm(desc=what, unit="run", file=self._out)
        except ImportError:
            self._bar = None

    def eta_s(self, finished: int, total: int) -> Optional[float]:
        """Seconds left at the rate runs finished since the wait began; None before one did."""
        if self._finished_at_start is None:
            self._finished_at_start = finished
        done_here = finished - self._finished_at_start
        if done_here <= 0:
            return None
        return (total - finished) * (time.monotonic() - self._started) / done_here

    def update(self, counts: Mapping[str, int]) -> None:
        total = sum(counts.values())
        finished = total - counts.get("queued", 0) - counts.get("running", 0)
        eta = self.eta_s(finished, total)
        if not self._enabled:
            return
        detail = f"{counts.get('running', 0)} running, {counts.get('failed', 0)} failed"
        if self._bar is not None:
            self._bar.total = total
            self._bar.n = finished
            self._bar.set_postfix_str(detail, refresh=False)
            self._bar.refresh()
            return
        line = f"{self._what}: {finished}/{total} finished, {detail}"
        if line != self._last:
            self._last = line
            eta_text = "" if eta is None or finished == total else f", ETA {eta:.0f} s"
            print(line + eta_text, file=self._out, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


class Client:
    """sandswimd at `url` (default $SANDSWIM_SERVER, else http://127.0.0.1:8640).

    The bearer token, when not given, is found as the CLI finds it: `token_file` (the daemon's
    DATA/token), else $SANDSWIM_TOKEN, else ./var/data/token when the daemon is on this machine's
    loopback (sandswim.token.find_token). `timeout` bounds each request, in seconds. `verify`,
    for an https:// daemon: True (the system's CAs), or the path of the CA file that signed its
    certificate.
    """

    def __init__(self, url: Optional[str] = None, token: Optional[str] = None, *,
                 token_file: Optional[str] = None, timeout: float = 120.0,
                 verify: Union[bool, str] = True) -> None:
        url = url or os.environ.get("SANDSWIM_SERVER") or DEFAULT_SERVER
        self.url = url.rstrip("/")
        self.timeout = timeout
        self._session = requests.Session()
        self._session.verify = verify
        self._session.headers["User-Agent"] = f"sandswim-python/{__version__}"
        found = find_token(self.url, token, token_file)
        if found:
            self._session.headers["Authorization"] = f"Bearer {found}"
        self._schemas: Optional[frames.Schemas] = None
        self.page_size = 1000  # items a page of a paged list asks for (the daemon's maximum)

    def __repr__(self) -> str:
        return f"Client({self.url!r})"

    def close(self) -> None:
        """Closes the HTTP session (its keep-alive connections)."""
        self._session.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---- HTTP ------------------------------------------------------------------------------------

    def _request(self, method: str, path: str, *, params: Optional[Mapping[str, Any]] = None,
                 body: Any = None, headers: Optional[Mapping[str, str]] = None) -> requests.Response:
        what = f"{method} {path}"
        try:
            response = self._session.request(method, self.url + path, params=params,
                                             json=body, headers=headers, timeout=self.timeout)
        except requests.RequestException as e:
            raise SandswimError(f"cannot reach sandswimd at {self.url} ({what}): {e.__class__.__name__}: {e} "
                                "(is it running? start it with sandswimd, or give Client its URL)") from None
        if response.status_code >= 400:
            raise SandswimError.from_response(response.status_code, response.content,
                                              response.headers.get("Content-Type", ""), what)
        return response

    def _json(self, method: str, path: str, **kwargs: Any) -> Any:
        response = self._request(method, path, **kwargs)
        if not response.content:
            return {}
        try:
            return response.json()
        except ValueError:
            raise SandswimError(f"the daemon's answer to {method} {path} is not JSON") from None

    def _object(self, path: str) -> dict[str, Any]:
        """GET `path`, whose answer is a JSON object."""
        answer = self._json("GET", path)
        if not isinstance(answer, dict):
            raise SandswimError(f"the daemon's answer to GET {path} is not a JSON object")
        return answer

    def get(self, path: str, **params: Any) -> Any:
        """GET any route of the API (path from /api/v1/...) as parsed JSON: for what has no method."""
        return self._json("GET", path, params=params or None)

    def _pages(self, path: str, key: str, params: Mapping[str, Any]) -> Iterator[dict[str, Any]]:
        """Every item of a cursor-paged list, page after page (next_cursor) to its end."""
        query = dict(params, limit=self.page_size)
        while True:
            page = self._json("GET", path, params=query)
            yield from page.get(key, [])
            cursor = page.get("next_cursor")
            if not cursor:
                return
            query["cursor"] = cursor

    def api(self) -> dict[str, Any]:
        """The daemon's API description (GET /api/v1/openapi.json)."""
        return self._object("/api/v1/openapi.json")

    def _units(self) -> frames.Schemas:
        if self._schemas is None:
            doc = self.api()
            served = str(doc.get("info", {}).get("version", ""))
            if served.split(".")[0] != API_VERSION:
                raise SandswimError(f"sandswimd at {self.url} serves API version {served}; this client "
                                    f"({__version__}) speaks version {API_VERSION}: install the client "
                                    "from the daemon's own source tree (pip install cli/python)", field="version")
            self._schemas = frames.Schemas(doc)
        return self._schemas

    # ---- submitting and following ----------------------------------------------------------------

    def submit(self, what: Union[Mapping[str, Any], str, "os.PathLike[str]"], *, scale: Optional[str] = None,
               force: bool = False, idempotency_key: Optional[str] = None) -> Submission:
        """Submits a sweep (a dict, or a JSON file: a sweep, {"sweeps": [...]} or {"campaign": NAME})
        or a campaign by name ("paper-58"). `scale` (paper, mini, smoke) overrides the file's or
        campaign's; `force` runs again what is already done; `idempotency_key` makes a retried
        submission create nothing twice."""
        body = _submission_body(what, scale)
        if force:
            body["force"] = True
        headers = {"Idempotency-Key": idempotency_key} if idempotency_key else None
        reply = self._json("POST", "/api/v1/sweeps", body=body, headers=headers)
        sweeps = tuple(int(s) for s in reply.get("sweeps", reply.get("ids", [])))
        campaign_run = reply.get("campaign_run_id")
        return Submission(sweeps=sweeps, campaign_run=int(campaign_run) if campaign_run is not None else None,
                          runs=int(reply.get("runs", 0)), reply=reply)

    def cancel(self, target: Target) -> None:
        """Cancels a sweep, or every sweep of a submission or campaign run: queued runs are dropped,
        running ones stop at their next heartbeat."""
        for sweep in self._sweep_ids(target):
            self._json("POST", f"/api/v1/sweeps/{sweep}/cancel", body={})

    def _sweep_ids(self, target: Target) -> list[int]:
        ids: list[int] = []
        for kind, ident in _targets(target):
            if kind == "sweeps":
                ids.append(ident)
            else:
                ids.extend(int(s) for s in self._json("GET", f"/api/v1/campaign-runs/{ident}").get("sweeps", []))
        return ids

    def status(self, target: Target) -> dict[str, int]:
        """Run counts by state (queued, running, done, failed, cancelled) of a sweep, a campaign run
        or a submission."""
        counts: dict[str, int] = {}
        for kind, ident in _targets(target):
            _add_counts(counts, self._json("GET", f"/api/v1/{kind}/{ident}").get("counts", {}))
        return counts

    def wait(self, target: Target, *, timeout: Optional[float] = None, poll_s: float = 1.0,
             progress: bool = True, sleep: Callable[[float], None] = time.sleep) -> dict[str, int]:
        """Polls status() until nothing is queued or running and returns the last counts, showing a
        progress bar (tqdm when installed, else a line on stderr when the counts change) with an
        ETA. Raises SandswimError when `timeout` seconds pass first (the runs go on)."""
        what = ", ".join(f"sweep {i}" if k == "sweeps" else f"campaign run {i}" for k, i in _targets(target))
        bar = _Progress(what, progress)
        deadline = None if timeout is None else time.monotonic() + timeout
        try:
            while True:
                counts = self.status(target)
                bar.update(counts)
                if counts.get("queued", 0) == 0 and counts.get("running", 0) == 0:
                    return counts
                if deadline is not None and time.monotonic() >= deadline:
                    raise SandswimError(f"{what}: still {counts.get('queued', 0)} queued and "
                                        f"{counts.get('running', 0)} running after {timeout:g} s (the runs go on; "
                                        "wait() again or cancel())", field="timeout")
                sleep(poll_s)
        finally:
            bar.close()

    # ---- tables ----------------------------------------------------------------------------------

    def _results_json(self, target: Target) -> list[dict[str, Any]]:
        return [self._all_results(f"/api/v1/{kind}/{ident}/results") for kind, ident in _targets(target)]

    def _all_results(self, path: str) -> dict[str, Any]:
        """A results read whole: the first page holding the "results" of every page, their "next"
        paths followed, the largest pages the daemon gives, and the "aggregates" of every page,
        each point once (a page has those of the points of its runs: a point whose runs two pages
        share is on both, the same; known by the smallest run id among its values)."""

        def point_of(aggregate: Mapping[str, Any]) -> int:
            return min((v["run_id"] for v in aggregate.get("values", []) if "run_id" in v), default=-1)

        reply = self._object(f"{path}?limit={RESULTS_PAGE_ROWS}")
        aggregates = list(reply.get("aggregates") or [])
        points = {point_of(a) for a in aggregates}
        next_path = reply.pop("next", None)
        seen: set[str] = set()
        while next_path:
            if next_path in seen:  # a daemon that repeats a page would loop for ever
                raise SandswimError(f"the daemon's pages repeat at GET {next_path}", field="next")
            seen.add(next_path)
            page = self._json("GET", next_path)
            if not page.get("results"):
                raise SandswimError(f"the daemon's answer to GET {next_path} has no rows", field="results")
            reply["results"].extend(page["results"])
            for a in page.get("aggregates") or []:
                if point_of(a) not in points:
                    points.add(point_of(a))
                    aggregates.append(a)
            next_path = page.get("next")
        reply["aggregates"] = aggregates
        reply.pop("next_cursor", None)
        return reply

    def results(self, target: Target) -> pd.DataFrame:
        """One row per run of a sweep, campaign run or submission (GET .../results): its point, U_z
        with its standard error and 95 % half-width beside it, why it ended, units in the column
        names ("Uz [m/s]"). Uz is NaN until a run is done, or when it is not measured; `conclusive`
        and `Uz_text` say which."""
        schemas = self._units()  # the API's version checked before a large answer is fetched
        rows = [row for reply in self._results_json(target) for row in reply.get("results", [])]
        return frames.results_frame(rows, schemas)

    def aggregates(self, target: Target) -> pd.DataFrame:
        """One row per point over its replicate beds: K beds, n conclusive, the mean U_z with its
        standard error, 95 % half-width and between-bed sd."""
        rows = [a for reply in self._results_json(target) for a in reply.get("aggregates", [])]
        return frames.aggregates_frame(rows, self._units())

    def fits(self, sweep: int) -> pd.DataFrame:
        """The paper's fit of a sweep (eq. 8, eq. 9 or f_c), one row per branch, each parameter with
        its standard error; frame.attrs["reason"] says what was fitted, or why nothing was."""
        return frames.fits_frame(self._json("GET", f"/api/v1/sweeps/{int(sweep)}/fits"))

    def _claims_json(self, campaign_run: Target) -> dict[str, Any]:
        # Claims belong to campaign runs only: a bare id here is a campaign run's.
        targets = [("campaign-runs", campaign_run)] if isinstance(campaign_run, int) else _targets(campaign_run)
        if len(targets) != 1 or targets[0][0] != "campaign-runs":
            raise SandswimError("claims belong to a campaign run: give its id (7, \"cr:7\") or its Submission",
                                field="campaign_run")
        return self._object(f"/api/v1/campaign-runs/{int(targets[0][1])}/claims")

    def claims(self, campaign_run: Target) -> pd.DataFrame:
        """The verdict of each claim of a campaign run (holds, differs, inconclusive) at its scale,
        with the reason; one row per claim. `campaign_run`: its id, "cr:ID" or its Submission."""
        return frames.claims_frame(self._claims_json(campaign_run))

    def claim_parts(self, campaign_run: Target) -> pd.DataFrame:
        """The parts each claim's verdict was decided from, one row per part."""
        return frames.claim_parts_frame(self._claims_json(campaign_run))

    def claim_figures(self, campaign_run: Target) -> pd.DataFrame:
        """The numbers the parts rest on (value, standard error, interval or bound, unit)."""
        return frames.claim_figures_frame(self._claims_json(campaign_run))

    def sweeps(self) -> pd.DataFrame:
        """Every sweep with its run counts (all pages)."""
        return frames.table_frame(list(self._pages("/api/v1/sweeps", "sweeps", {})))

    def runs(self, sweep: Optional[int] = None, state: Optional[str] = None) -> pd.DataFrame:
        """Runs (all pages), of one sweep and in one state when given; point fields as "point.A"."""
        params = {k: v for k, v in (("sweep", sweep), ("state", state)) if v is not None}
        return frames.table_frame(list(self._pages("/api/v1/runs", "runs", params)))

    def run(self, run_id: int) -> dict[str, Any]:
        """A run's whole record: point, state, deck, trajectory, result, log tail, snapshots."""
        return self._object(f"/api/v1/runs/{int(run_id)}")

    def trajectory(self, run_id: int) -> pd.DataFrame:
        """The SO's path in a run: "t [s]", "x [m]", "y [m]", "z [m]", one row per dump frame."""
        return frames.trajectory_frame(self.run(run_id).get("trajectory") or {}, self._units())

    def trajectories(self, target: Target) -> pd.DataFrame:
        """The paths of every finished run of a sweep or submission, long form: run_id, the point's
        parameters and replicate, then t, x, y, z (one request per run)."""
        table = self.results(target)
        point = set(self._units().fields(frames.POINT_SCHEMA)) - {"duration_s"}
        keys = ["run_id", "replicate"] + [c for c in table.columns
                                          if c.split(" [")[0] in point and table[c].notna().any()]
        parts = []
        for row in table.to_dict("records"):
            if row.get("state") != "done":
                continue
            path = self.trajectory(int(row["run_id"]))
            for i, key in enumerate(keys):
                path.insert(i, key, row.get(key))
            parts.append(path)
        return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=keys)

    # ---- figures, beds, snapshots ----------------------------------------------------------------

    def figure(self, kind: str, ident: int, format: str = "svg", **params: Any) -> bytes:
        """A figure the daemon draws, as SVG or PNG bytes (IPython.display.SVG(data) / Image(data)):
        kind "trajectory" (a run's z(t) and x(t)), "trajectories" (a sweep's z(t); branch=...),
        "uz" (a sweep's U_z with error bars and the fitted law), "modes" (a campaign run's drive
        modes; coordinate="x")."""
        paths = {"trajectory": "runs/{}/trajectory", "trajectories": "sweeps/{}/trajectories",
                 "uz": "sweeps/{}/uz", "modes": "campaign-runs/{}/modes"}
        if kind not in paths:
            raise SandswimError(f"no figure {kind!r} (one of {', '.join(paths)})", field="kind")
        if format not in ("svg", "png"):
            raise SandswimError(f"format must be svg or png, got {format!r}", field="format")
        path = "/api/v1/" + paths[kind].format(int(ident)) + "." + format
        return bytes(self._request("GET", path, params=params or None).content)

    def report(self, campaign_run: int) -> str:
        """A campaign run's report, a self-contained HTML page (IPython.display.HTML(text))."""
        # UTF-8 whatever the Content-Type says (requests reads text/* without a charset as Latin-1).
        return str(self._request("GET", f"/api/v1/campaign-runs/{int(campaign_run)}/report").content.decode("utf-8"))

    def beds(self) -> pd.DataFrame:
        """Every bed: scale, replicate, seeds, state, its figures once prepared ("result.grains")."""
        return frames.table_frame(self._json("GET", "/api/v1/beds").get("beds", []))

    def bed(self, bed_id: int) -> dict[str, Any]:
        """One bed's record."""
        return self._object(f"/api/v1/beds/{int(bed_id)}")

    def snapshots(self, run_id: int) -> pd.DataFrame:
        """The full-bed snapshots a run handed in: idx, t_s, grains, bytes and their links."""
        return frames.table_frame(self.run(run_id).get("snapshots_taken") or [])

    def snapshot(self, run_id: int, n: int, format: str = "vtk",
                 path: Optional[Union[str, "os.PathLike[str]"]] = None) -> Union[bytes, str]:
        """Snapshot n of a run as a legacy VTK file (ParaView opens it) or as the engine's dump
        ("dump"), or its slice figure ("slice.svg", "slice.png"): the bytes, or, given `path`, the
        file written there (streamed) and its path."""
        suffix = {"vtk": ".vtk", "dump": ".dump", "slice.svg": "/slice.svg", "slice.png": "/slice.png"}
        if format not in suffix:
            raise SandswimError(f"format must be one of {', '.join(suffix)}, got {format!r}", field="format")
        url_path = f"/api/v1/runs/{int(run_id)}/snapshots/{int(n)}{suffix[format]}"
        if path is None:
            return bytes(self._request("GET", url_path).content)
        try:
            response = self._session.get(self.url + url_path, stream=True, timeout=self.timeout)
        except requests.RequestException as e:
            raise SandswimError(f"cannot reach sandswimd at {self.url} (GET {url_path}): {e}") from None
        with response:
            if response.status_code >= 400:
                raise SandswimError.from_response(response.status_code, response.content,
                                                  response.headers.get("Content-Type", ""), f"GET {url_path}")
            with open(path, "wb") as f:
                for chunk in response.iter_content(1 << 20):
                    f.write(chunk)
        return os.fspath(path)
