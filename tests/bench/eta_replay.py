#!/usr/bin/env python3
"""Replays candidate ETA rate rules on a real daemon's record and prints each rule's error rates.

The record: a status log (`sandswim status CR` every few minutes, each reading headed
"=== ISO-time epoch", as /work/realrun/eta-log.sh writes it), the daemon's log (when each run was
leased and completed) and a copy of its database (the done runs' results: steps, grains, wall time).
For every run whose end is known, at every reading more than --horizon seconds before that end, each
rule predicts the wall time the run needs to reach the step it really ended at (so the replay
measures the rate rule, not the guess of where a run stops) and states a relative 1-sigma error.
The truth is the time it really took. Printed per rule: predictions, median |error|, the share
within +-25 %, and how often the truth lay within the stated 1 sigma. The stated error r is a
half-range on a log scale (the share's |ln f| / 2), and the ETA's band is pred / e^r .. pred x e^r
(server/store/cost_model.cc EtaJson), so the truth is covered when |ln(truth / pred)| <= r.

The rules (core/cost.h names: M = the cost model's pooled rate with its FitRate error e_M, f = the
live running runs' pooled wall per particle-step over the last 10 minutes / M's, f_b = the same for
the 10 minutes before, or their attempts so far):
  old        M, e_M                                    (main before issue 30)
  a          M, hypot(e_M, |ln f|)                     (the old point, the share's pull as error)
  b          the running runs' pooled rate over their attempts so far, hypot(e_M, |ln(f x M / b)|)
  c          M x sqrt(f), hypot(e_M, |ln f| / 2, |ln(f / f_b)|)   (the ETA's rule: core/cost.h Share)
  d          M x f, hypot(e_M, |ln(f / f_b)|)          (the last 10 minutes alone)
A rule is chosen for the smallest median error among those whose 1 sigma holds the truth at least
60 % of the time (CHOSEN_MIN_COVERAGE; none qualifying: the best covered). Readings of two runs at
once share one machine: their errors are not independent.

--leave-one-out: for each run, the rule is chosen on the other runs and scored on that run alone,
so the score is out of sample (the table above it is in-sample: chosen and scored on the same runs).

--campaign-sweep S: the campaign-level score (the ETA as `status` printed it, not a replayed rule).
Each logged ETA of the campaign run that sweep S belongs to predicts when all the campaign run's
work left ends. When the campaign run did not finish (cancelled), that end never came, so the
score is on sweep S, which finished: the logged ETA times S's share of the work left (in run
equivalents: a queued run of S counts 1, a running one the part of its expected length still to
go -- expected as the daemon does, the mean length of the campaign run's runs done by then, before
any the middle of its target's range; the range's lower end is read as min_periods / f), so
S's predicted end = t + ETA x share, its band the logged band times the same share. That share
is right when the ETA is the work left over the engines, as it is until the last runs (the
"never less than the longest run" floor): near S's end the split is cruder. The truth: when S's
last run finished. Printed: median |error| (of the time left), the share within +-25 %, and how
often the truth lay inside the band (s / e^r .. s x e^r, r read from "± d" as d / s, or the band
printed as "(low-high)").

Usage: eta_replay.py --status eta.log --daemon-log sandswimd.log --db copy.db [--leave-one-out]
       eta_replay.py --status eta.log --db copy.db --campaign-sweep 3 [--per-reading]
"""
import argparse
import datetime
import json
import math
import re
import sqlite3
import statistics

DT = 1e-5  # s of simulated time per step (the smoke decks: 200000 steps for 2 s)
WINDOW = 600.0
MIN_STRETCH = 120.0  # core/cost.h kMinShareStretchS
RUNNING_MIN_WALL = 20.0  # a running run joins the model once it has run this long
MIN_REL = 0.1  # core/cost.h kMinRateRelError
CHOSEN_MIN_COVERAGE = 0.6  # a rule's 1 sigma must hold the truth this often to be chosen


def parse_time(text):
    return datetime.datetime.strptime(text, "%Y-%m-%d %H:%M:%S.%f").replace(
        tzinfo=datetime.timezone.utc).timestamp()


def read_daemon_log(path):
    leases, completed = {}, {}
    pat = re.compile(r"^\[(\S+ \S+)\] \[info\] run (\d+) attempt \d+: (leased|completed \(done\))")
    for line in open(path, encoding="utf-8", errors="replace"):
        m = pat.match(line)
        if not m:
            continue
        at, run = parse_time(m.group(1)), int(m.group(2))
        if m.group(3) == "leased":
            leases.setdefault(run, []).append(at)
        else:
            completed[run] = at
    return leases, completed


def read_status(path):
    readings = []
    run_pat = re.compile(r"^\s+run (\d+)\s+\[.*?\]\s+\d+%\s+([0-9.]+)/")
    for line in open(path, encoding="utf-8", errors="replace"):
        if line.startswith("=== "):
            readings.append((float(line.split()[2]), {}))
        else:
            m = run_pat.match(line)
            if m and readings:
                readings[-1][1][int(m.group(1))] = round(float(m.group(2)) / DT)
    return readings


def fit_rate(samples):
    """core/cost.cc FitRate: pooled wall/work, error = spread of log rates / sqrt(n), >= MIN_REL."""
    samples = [(w, s) for w, s in samples if w > 0 and s > 0]
    if not samples:
        return None, None
    rate = sum(s for _, s in samples) / sum(w for w, _ in samples)
    logs = [math.log(s / w) for w, s in samples]
    if len(logs) == 1:
        return rate, max(MIN_REL, 0.25)
    return rate, max(MIN_REL, statistics.stdev(logs) / math.sqrt(len(logs)))


def pooled(samples, min_wall=0.0):
    samples = [(w, s) for w, s in samples if w > 0 and s >= min_wall]
    return sum(s for _, s in samples) / sum(w for w, _ in samples) if samples else None


def parse_duration(text):
    """FormatDuration's "5h00m", "58m18s", "45s", "1d02h" -> seconds."""
    units = {"d": 86400, "h": 3600, "m": 60, "s": 1}
    parts = re.findall(r"(\d+)([dhms])", text)
    return sum(int(n) * units[u] for n, u in parts) if parts else None


def read_campaign_status(path):
    """Readings of `status CR`: (t, title, eta_s, low_s, high_s, {run: sim_time_s}); eta None when none."""
    readings = []
    eta_pm = re.compile(r"^\s+ETA (\S+) ± (\S+)")
    eta_band = re.compile(r"^\s+ETA (\S+) \((\S+)-(\S+)\)")
    run_pat = re.compile(r"^\s+run (\d+)\s+\[.*?\]\s+\d+%\s+([0-9.]+)/")
    for line in open(path, encoding="utf-8", errors="replace"):
        if line.startswith("=== "):
            readings.append({"t": float(line.split()[2]), "title": "", "eta": None, "running": {}})
            continue
        if not readings:
            continue
        r = readings[-1]
        if not r["title"] and line.strip():
            r["title"] = line.strip()
        m = re.search(r"(\d+) engines?\)", line)
        if m and "engines" not in r:
            r["engines"] = int(m.group(1))
        m = eta_band.match(line)
        if m:
            r["eta"] = (parse_duration(m.group(1)), parse_duration(m.group(2)), parse_duration(m.group(3)))
            continue
        m = eta_pm.match(line)
        if m:
            s, d = parse_duration(m.group(1)), parse_duration(m.group(2))
            rel = d / s if s else 0.0
            r["eta"] = (s, s / math.exp(rel), s * math.exp(rel))
            continue
        m = run_pat.match(line)
        if m:
            r["running"][int(m.group(1))] = float(m.group(2))
    return readings


def campaign_sweep_score(args):
    db = sqlite3.connect(args.db)
    (campaign_run,) = db.execute("SELECT campaign_run_id FROM sweeps WHERE id = ?", (args.campaign_sweep,)).fetchone()
    runs = {}  # id -> (sweep, state, finished_at, final sim time, deck end, earliest stop)
    for rid, sweep, state, fin, sim, dur, prec, f in db.execute(
            "SELECT r.id, sr.sweep_id, r.state, r.finished_at, r.sim_time_s, r.run_duration_s, r.precision, r.f "
            "FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id JOIN sweeps s ON s.id = sr.sweep_id "
            "WHERE s.campaign_run_id = ?", (campaign_run,)):
        earliest = dur
        if prec:
            p = json.loads(prec)
            if p.get("min_periods") and f:
                earliest = min(dur, p["min_periods"] / f)
        runs[rid] = (sweep, state, fin, sim, dur, earliest)
    mine = {r for r, v in runs.items() if v[0] == args.campaign_sweep}
    if any(runs[r][1] != "done" for r in mine):
        raise SystemExit(f"sweep {args.campaign_sweep} did not finish: no truth to score against")
    truth_end = max(runs[r][2] for r in mine)
    rows, implied = [], []
    for rd in read_campaign_status(args.status):
        if f"cr:{campaign_run} " not in rd["title"] or not rd["eta"] or rd["eta"][0] is None:
            continue
        t = rd["t"]
        if t >= truth_end:
            continue
        done = [v for v in runs.values() if v[1] == "done" and v[2] is not None and v[2] < t]
        expected = (statistics.mean(v[3] for v in done) if done else None)

        def left(rid, sim):
            v = runs[rid]
            end = expected if expected else (v[5] + v[4]) / 2
            if sim < end:
                return (end - sim) / end
            return (v[4] - sim) / 2 / end  # outlived the expectation: the middle of the rest

        running = {r: sim for r, sim in rd["running"].items() if r in runs}
        done_ids = {r for r, v in runs.items() if v[1] == "done" and v[2] is not None and v[2] < t}
        # Queued: neither done by t nor running at t (runs cancelled later were queued or running then).
        queued = [r for r in runs if r not in done_ids and r not in running]
        w_all = len(queued) + sum(left(r, sim) for r, sim in running.items())
        w_mine = len([r for r in queued if r in mine]) + sum(left(r, sim) for r, sim in running.items() if r in mine)
        if w_all <= 0 or w_mine <= 0:
            continue
        share = w_mine / w_all
        s, low, high = (x * share for x in rd["eta"])
        truth = truth_end - t
        rows.append((t, s, low, high, truth, share))
        if rd.get("engines"):
            implied.append(rd["eta"][0] * rd["engines"] / w_all)
    if not rows:
        print("no readings to score")
        return

    def report(label, sub):
        if not sub:
            print(f"{label}: no readings")
            return
        errs = [abs(s / tr - 1) for _, s, _, _, tr, _ in sub]
        covered = sum(lo <= tr <= hi for _, _, lo, hi, tr, _ in sub)
        signed = statistics.median(s / tr - 1 for _, s, _, _, tr, _ in sub)
        print(f"{label}: {len(sub)} readings, median |error| {100 * statistics.median(errs):.1f}% "
              f"(median signed {100 * signed:+.1f}%), within 25 % {sum(e <= 0.25 for e in errs)} "
              f"({100 * sum(e <= 0.25 for e in errs) / len(sub):.0f}%), truth inside the band {covered} "
              f"({100 * covered / len(sub):.0f}%)")

    print(f"campaign run cr:{campaign_run}, scored on sweep {args.campaign_sweep} ({len(mine)} runs), which ended "
          f"{datetime.datetime.fromtimestamp(truth_end, datetime.timezone.utc):%Y-%m-%d %H:%M:%S} UTC")
    report("all readings", rows)
    # What the ETA rested on, against what happened: the wall time of one run on one engine it
    # implied (ETA x engines / run equivalents left), and each done run's last attempt.
    lengths = []
    for rid, started, fin in db.execute(
            "SELECT r.id, r.started_at, r.finished_at FROM sweep_runs sr JOIN runs r ON r.id = sr.run_id "
            "JOIN sweeps s ON s.id = sr.sweep_id WHERE s.campaign_run_id = ? AND r.state = 'done' ORDER BY r.id",
            (campaign_run,)):
        lengths.append(f"{rid}: {(fin - started) / 60:.0f}")
    if implied:
        print(f"one run on one engine, as the ETA implied: median {statistics.median(implied) / 60:.0f} min "
              f"(range {min(implied) / 60:.0f}-{max(implied) / 60:.0f}); the done runs' last attempts took (min) "
              + ", ".join(lengths))
    if args.after:
        report(f"readings from {args.after} on", [r for r in rows if r[0] >= parse_iso(args.after)])
        report(f"readings before {args.after}", [r for r in rows if r[0] < parse_iso(args.after)])
    if args.per_reading:
        print("reading (UTC)         share  predicted_left  band              truth_left  error")
        for t, s, lo, hi, tr, share in rows:
            when = datetime.datetime.fromtimestamp(t, datetime.timezone.utc)
            print(f"{when:%Y-%m-%d %H:%M}  {share:5.2f}  {s / 60:10.0f} min  {lo / 60:5.0f}-{hi / 60:<5.0f} min  "
                  f"{tr / 60:7.0f} min  {100 * (s / tr - 1):+5.0f}%")


def parse_iso(text):
    return datetime.datetime.strptime(text, "%Y-%m-%dT%H:%M:%SZ").replace(tzinfo=datetime.timezone.utc).timestamp()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--status", required=True)
    ap.add_argument("--daemon-log")
    ap.add_argument("--campaign-sweep", type=int,
                    help="score the logged campaign ETA on this finished sweep of its campaign run (see above)")
    ap.add_argument("--per-reading", action="store_true", help="with --campaign-sweep: one line per reading")
    ap.add_argument("--after", help="with --campaign-sweep: also score readings from this time (e.g. "
                                    "2026-11-27T02:27:52Z, after an outage) and before it apart")
    ap.add_argument("--db", required=True)
    ap.add_argument("--horizon", type=float, default=300, help="predict only this long before a run's end")
    ap.add_argument("--slack", type=float, default=30, help="a reading this much older than a window still opens it")
    ap.add_argument("--per-run", action="store_true")
    ap.add_argument("--runs", help="only these runs' predictions, e.g. 49,50,51")
    ap.add_argument("--leave-one-out", action="store_true",
                    help="also choose the rule on all runs but one and score it on that one, for each run")
    args = ap.parse_args()
    if args.campaign_sweep is not None:
        return campaign_sweep_score(args)
    if not args.daemon_log:
        ap.error("--daemon-log is required (except with --campaign-sweep)")

    leases, completed = read_daemon_log(args.daemon_log)
    readings = read_status(args.status)
    db = sqlite3.connect(args.db)
    results = {r: (steps * (grains + 1.0), wall) for r, steps, grains, wall in db.execute(
        "SELECT run_id, steps, grains, wall_s FROM results WHERE wall_s > 0")}
    final_step = {r: s for r, s in db.execute("SELECT run_id, steps FROM results")}
    particles = {r: g + 1.0 for r, g in db.execute(
        "SELECT r.id, b.grains FROM runs r JOIN beds b ON b.id = r.bed_id WHERE b.grains > 0")}

    def started(run, at):
        past = [t for t in leases.get(run, []) if t <= at]
        return past[-1] if past else None

    def step_at(run, at):
        """The run's step at the newest reading at or before `at` within the attempt live at `at`."""
        for t, runs in reversed(readings):
            if t <= at and run in runs:
                return t, runs[run]
        return None

    def stretch(run, begin, end, start):
        """(work, wall) from the oldest reading at or after `begin` - slack to the reading at `end`."""
        first = None
        for t, runs in readings:
            if t >= begin - args.slack and t >= start and t <= end and run in runs:
                first = (t, runs[run])
                break
        if first is None or first[0] >= end:
            return None
        last = step_at(run, end)
        return ((last[1] - first[1]) * particles[run], end - first[0]), first[0]

    rules = ["old", "a", "b", "c", "d"]
    preds = {r: [] for r in rules}
    for t, runs in readings:
        live = {run: step for run, step in runs.items() if started(run, t) is not None and run in particles}
        done = [results[r] for r, at in completed.items() if at < t and r in results]
        so_far = [(step * particles[run], t - started(run, t)) for run, step in live.items()]
        model, e_model = fit_rate(done + [s for s in so_far if s[1] >= RUNNING_MIN_WALL])
        if model is None:
            continue
        recent, before = [], []
        for run in live:
            got = stretch(run, t - WINDOW, t, started(run, t))
            if got is None:
                continue
            recent.append(got[0])
            prior = stretch(run, got[1] - WINDOW, got[1], started(run, t))
            if prior is not None:
                before.append(prior[0])
        now = pooled(recent, MIN_STRETCH)
        then = pooled(before, MIN_STRETCH) or pooled(so_far)
        attempt = pooled(so_far)
        f = now / model if now else 1.0
        change = abs(math.log(now / then)) if now and then else 0.0
        est = {
            "old": (model, e_model),
            "a": (model, math.hypot(e_model, abs(math.log(f)))),
            "b": (attempt, math.hypot(e_model, abs(math.log(now / attempt)) if now else 0.0)) if attempt else
                 (model, e_model),
            "c": (model * math.sqrt(f), math.hypot(e_model, abs(math.log(f)) / 2, change)),
            "d": (model * f, math.hypot(e_model, change)),
        }
        for run, step in live.items():
            if args.runs and str(run) not in args.runs.split(","):
                continue
            if run not in completed or run not in final_step or completed[run] <= t:
                continue
            truth = completed[run] - t
            if truth <= args.horizon:
                continue
            work = (final_step[run] - step) * particles[run]
            for rule, (rate, err) in est.items():
                pred = work * rate
                preds[rule].append((run, t, pred, truth, err))

    print("rule  predictions  median|err|  within25%  covered1sigma  median_stated  median|ln(pred/truth)|")
    for rule in rules:
        rows = preds[rule]
        if not rows:
            print(f"{rule:5} {0:11d}  (no predictions)")
            continue
        m = score(rows)
        print(f"{rule:5} {m['n']:11d}  {100 * m['median_err']:10.1f}%  {m['within']:4d} ({100 * m['within'] / m['n']:3.0f}%)"
              f"  {m['covered']:4d} ({100 * m['coverage']:3.0f}%)  {100 * m['median_stated']:8.0f}%"
              f"  {m['median_ln']:10.3f}")
        if args.per_run:
            for run in sorted({r for r, *_ in rows}):
                sub = score([x for x in rows if x[0] == run])
                print(f"        run {run}: {sub['n']} predictions, median |err| {100 * sub['median_err']:.0f}%, "
                      f"covered {sub['covered']}")
    chosen = choose({rule: preds[rule] for rule in rules})
    if chosen[1]:
        print(f"chosen in-sample (the smallest median |err| among rules covering >= {100 * CHOSEN_MIN_COVERAGE:.0f} %): "
              f"{chosen[0]}")
    else:
        print(f"no rule covers >= {100 * CHOSEN_MIN_COVERAGE:.0f} % in-sample; the best covered: {chosen[0] or 'none'}")

    if args.leave_one_out:
        runs = sorted({r for rows in preds.values() for r, *_ in rows})
        print("\nleave one run out: the rule chosen on the other runs, scored on the run left out")
        print("left_out  chosen  meets_criterion_on_others  predictions  median|err|  within25%  covered1sigma")
        pooled_rows = []
        for out in runs:
            train = {rule: [x for x in preds[rule] if x[0] != out] for rule in rules}
            rule, meets = choose(train)
            if rule is None:
                print(f"run {out:4d}  none")
                continue
            test = [x for x in preds[rule] if x[0] == out]
            pooled_rows.extend(test)
            m = score(test)
            print(f"run {out:4d}  {rule:6}  {'yes' if meets else 'no':25}  {m['n']:11d}  {100 * m['median_err']:10.1f}%"
                  f"  {m['within']:4d} ({100 * m['within'] / m['n']:3.0f}%)  {m['covered']:4d} ({100 * m['coverage']:3.0f}%)")
        if pooled_rows:
            m = score(pooled_rows)
            print(f"all held-out predictions: {m['n']}, median |err| {100 * m['median_err']:.1f}%, within 25 % "
                  f"{100 * m['within'] / m['n']:.0f}%, covered by 1 sigma {100 * m['coverage']:.0f}%")


def score(rows):
    """The error rates of (run, t, pred, truth, err) rows; coverage on a log scale."""
    errs = [abs(p / tr - 1) for _, _, p, tr, _ in rows]
    covered = sum(abs(math.log(tr / p)) <= e for _, _, p, tr, e in rows)
    return {"n": len(rows), "median_err": statistics.median(errs), "within": sum(e <= 0.25 for e in errs),
            "covered": covered, "coverage": covered / len(rows),
            "median_stated": statistics.median(e for *_, e in rows),
            "median_ln": statistics.median(abs(math.log(p / tr)) for _, _, p, tr, _ in rows)}


def choose(preds_by_rule):
    """(rule, meets): the smallest median error among rules covering >= CHOSEN_MIN_COVERAGE; when none
    does, the best-covered rule and meets = False."""
    scored = {rule: score(rows) for rule, rows in preds_by_rule.items() if rows}
    if not scored:
        return None, False
    ok = [r for r, m in scored.items() if m["coverage"] >= CHOSEN_MIN_COVERAGE]
    if ok:
        return min(ok, key=lambda r: scored[r]["median_err"]), True
    return max(scored, key=lambda r: scored[r]["coverage"]), False


if __name__ == "__main__":
    main()
