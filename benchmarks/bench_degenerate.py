"""Corner sets nobody chose: every method on degenerate but valid observations.

python -m benchmarks degenerate [--trials N] [--first SEED] [--workers N] [--uses]

Trial ``s`` draws, from its own seed, a synthetic set (one of ``synth.KINDS`` and the 200°
fisheye, σ = 0, 0.3 or 3 px, 2-8 views) and does one of these to each view:

- keep it; keep 4-11 of its corners at random (``few``); one row (``row``); two rows
  (``strip``); a half of the board (``halfview``); the 6-14 corners nearest one corner
  (``cluster``);
- add noise of 5 or 50 px to every corner (``noise``); give a fifth of its corners each
  other's places (``shuffle``, wrong ids); throw a tenth of them 5 000 px off (``outside``);
  give one corner in twenty a second pixel 20 px away (``dupid``); move the board points off
  their grid by 0.5 units (``jitterobj``, a board measured badly); add a copy of the view
  (``dup``);

and a fifth of the sets get their board in other units (× 1000 or ÷ 1000). Each method
then calibrates the set, as ``calibrate`` in Python (the readers of files refuse some of
these before). A calibration must come back with finite figures, or be refused with a
``CalibError`` saying why; anything else is a crash. ``--uses`` also runs what follows a
calibration: ``evaluate`` on the lens's hold-out views, a JSON round trip, every export.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import traceback
from collections import Counter
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from calib_core import calibrate, synth
from calib_core.calibration import Calibration
from calib_core.errors import CalibError
from calib_core.evaluation.evaluate import evaluate
from calib_core.exports import TARGETS, export
from calib_core.methods import METHODS
from calib_core.observations import Observations, View

from .bench_detect import _print_table

KINDS = (*synth.KINDS, "fisheye200")
OPS = ("keep", "keep", "few", "row", "strip", "halfview", "cluster", "noise", "shuffle", "outside", "dupid",
       "jitterobj", "dup")
TIME_LIMIT_S = 120


def degenerate_set(seed: int) -> tuple[str, list[str], Observations]:
    """(lens kind, what was done to each view, the observations) of trial ``seed``."""
    rng = np.random.default_rng(seed)
    kind = KINDS[seed % len(KINDS)]
    s = synth.generate(kind, float(rng.choice([0.0, 0.3, 3.0])), int(rng.integers(0, 50)),
                       n_views=int(rng.integers(2, 9)))
    ops, views = [], []
    for v in s.train.views:
        op = str(rng.choice(OPS))
        ops.append(op)
        n = len(v)
        obj, img, ids = v.object_points.copy(), v.image_points.copy(), None if v.ids is None else v.ids.copy()
        keep = np.arange(n)
        if op == "few":
            keep = np.sort(rng.choice(n, min(n, int(rng.integers(4, 12))), replace=False))
        elif op == "row":
            keep = np.flatnonzero(obj[:, 1] == rng.choice(np.unique(obj[:, 1])))
        elif op == "strip":
            keep = np.flatnonzero(np.isin(obj[:, 1], np.unique(obj[:, 1])[:2]))
        elif op == "halfview":
            keep = np.flatnonzero(obj[:, 0] <= np.median(obj[:, 0]))
        elif op == "cluster":
            keep = np.argsort(np.linalg.norm(obj[:, :2] - obj[rng.integers(n), :2], axis=1))[: int(rng.integers(6, 15))]
        elif op == "noise":
            img += rng.normal(0, float(rng.choice([5, 50])), img.shape)
        elif op == "shuffle":
            j = rng.choice(n, max(2, n // 5), replace=False)
            img[j] = img[rng.permutation(j)]
        elif op == "outside":
            j = rng.choice(n, max(1, n // 10), replace=False)
            img[j] += rng.choice([-1, 1], (len(j), 2)) * 5000.0
        elif op == "dupid":
            j = rng.choice(n, max(1, n // 20), replace=False)
            obj, img = np.vstack([obj, obj[j]]), np.vstack([img, img[j] + rng.normal(0, 20, (len(j), 2))])
            ids = None if ids is None else np.concatenate([ids, ids[j]])
            keep = np.arange(len(obj))
        elif op == "jitterobj":
            obj[:, :2] += rng.normal(0, 0.5, (n, 2))
        if len(keep):
            views.append(View(v.name, obj[keep], img[keep], None if ids is None else ids[keep]))
            if op == "dup":
                views.append(View(v.name + "_dup", obj[keep].copy(), img[keep].copy(),
                                  None if ids is None else ids[keep].copy()))
    if rng.random() < 0.2:
        scale = float(rng.choice([1e-3, 1e3]))
        views = [View(v.name, v.object_points * scale, v.image_points, v.ids) for v in views]
        ops.append(f"units x{scale:g}")
    return kind, ops, Observations(s.train.image_size, views, s.train.board)


class _TimeLimit(Exception):
    pass


def _alarm(*_) -> None:
    raise _TimeLimit


def run(job: tuple[int, str, bool]) -> dict:
    """One method on one trial's set: its outcome, rms, and the uses' failures."""
    seed, method, uses = job
    kind, ops, obs = degenerate_set(seed)
    out = {"seed": seed, "method": method, "kind": kind, "ops": ops, "problems": []}
    signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(TIME_LIMIT_S)
    try:
        cal = calibrate(obs, method)
        doc = cal.to_json()
        text = json.dumps(doc)
        finite = "NaN" not in text and "Infinity" not in text
        out.update(outcome="calibrated" if finite else "non-finite", rmse=doc["metrics"]["rmse"])
    except CalibError as e:
        return {**out, "outcome": "refused", "reason": str(e)}
    except _TimeLimit:
        return {**out, "outcome": f"over {TIME_LIMIT_S} s"}
    except Exception as e:  # what this benchmark looks for
        return {**out, "outcome": "crashed", "reason": f"{type(e).__name__}: {e}",
                "where": traceback.format_exc().strip().splitlines()[-3].strip()}
    finally:
        signal.alarm(0)
    if uses:
        holdout = synth.generate(kind, 0.0, 0).holdout
        steps = [("evaluate", lambda: evaluate(cal, holdout)),
                 ("round trip", lambda: Calibration.from_json(json.loads(json.dumps(cal.to_json()))))]
        steps += [(f"export {t}", lambda t=t: export(cal, t)) for t in TARGETS]
        for name, step in steps:
            try:
                step()
            except CalibError:
                pass  # refused with a reason: what a user gets
            except Exception as e:
                out["problems"].append(f"{name}: {type(e).__name__}: {e}")
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks degenerate", description=__doc__.split("\n\n")[0])
    ap.add_argument("--trials", type=int, default=40, help="docs/method.md's table is of trials 0-39")
    ap.add_argument("--first", type=int, default=0, help="the first trial's seed")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--uses", action="store_true", help="also evaluate, round-trip and export each calibration")
    a = ap.parse_args(argv)
    jobs = [(s, m, a.uses) for s in range(a.first, a.first + a.trials) for m in METHODS]
    with ProcessPoolExecutor(a.workers) as pool:
        results = list(pool.map(run, jobs))
    print(f"## Degenerate sets, trials {a.first}-{a.first + a.trials - 1}, every method\n")
    print("rms: of the calibrations whose views hold no 5-50 px noise (which a calibration should report as such).\n")
    rows = []
    for method in [*METHODS, "all"]:
        rs = [r for r in results if method in ("all", r["method"])]
        counts = Counter(r["outcome"] for r in rs)
        rms = np.array([r["rmse"] for r in rs if r["outcome"] == "calibrated" and "noise" not in r["ops"]])
        rows.append((method, len(rs), counts["calibrated"], counts["refused"], counts["crashed"],
                     counts["non-finite"] + counts[f"over {TIME_LIMIT_S} s"],
                     f"{np.median(rms):.3f}" if rms.size else "—", f"{rms.max():.2f}" if rms.size else "—",
                     sum(len(r["problems"]) for r in rs) if a.uses else "not run"))
    _print_table(["method", "runs", "calibrated", "refused", "crashed", "non-finite or over time",
                  "median rms px", "worst rms px", "failed uses"], rows)
    print("\nRefused, by reason (its first words):\n")
    for reason, n in Counter(r["reason"][:90] for r in results if r["outcome"] == "refused").most_common():
        print(f"- {n} × {reason}")
    print()
    for r in results:
        if r["outcome"] not in ("calibrated", "refused") or r["problems"]:
            print(f"- trial {r['seed']} {r['method']} ({r['kind']}: {', '.join(r['ops'])}): {r['outcome']} "
                  f"{r.get('reason', '')} {r.get('where', '')} {'; '.join(r['problems'])}")
    return 0
