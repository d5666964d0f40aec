"""freecal's default, ``calibrate(obs, "auto")``: its accuracy against the best
fixed configuration in hindsight, on BabelCalib's fisheye, its speed beside the
paper's fixed grid and mrcal's splined model, and how its time scales.

    python -m benchmarks default [--sections accuracy,babelcalib,speed,scaling,screen]
        [--kinds radial,...] [--seeds 0,1,2] [--views 10] [--sigma 0.3] [--quick] [--repeat 3]
        [--screen-kinds ...] [--screen-seeds 7,8,9] [--screen-views 3,5,7,10] [--screen-sigmas 0.1,1]

- accuracy: per synthetic kind and seed, the default's hold-out rmse (model held,
  poses refit: ``calib_core.evaluation.evaluate``) against a grid search of every fixed
  configuration (the parametric models, and the B-spline field on cores none and
  rational × intervals × λ_smooth), run on two processes. Targets: default / best
  fixed ≤ 1.10; default / best parametric ≤ 1.05 on the lenses a parametric model
  represents (radial, fisheye).
- babelcalib: train/ → test/ of BabelCalib's OV fisheye (target ≤ 0.415 px).
- speed: CPU seconds of one calibration after a warm-up (the lowest of ``--repeat`` rounds),
  the default and the paper's fixed 10 × 10 grid against mrcal's splined model, both its routes
  (``mrcal_bridge``; skipped without mrcal's venv: ``scripts/ensure-mrcal.sh``). Targets: the
  default no slower than mrcal's quicker route; the fixed grid ≥ 3× faster than it.
- screen: the default with the field screen on any number of views against every field
  fitted, by the number of views (seeds the tables never use): where the screen turns away
  fields that would predict the views held out better (``auto.SCREEN_MIN_VIEWS``).
- scaling: the fixed grid and the default from 10 to 160 views of the asymmetric
  lens. Targets: 100 views under 5 s for the default; the fixed grid's time linear
  in corners (log-log slope ≤ 1.1).

Seconds are ``time.process_time``: CPU time of every thread of the process (the
default's smoothing search runs two threads, so its CPU time can exceed its wall
time), which a busy machine inflates less than wall time.
"""
from __future__ import annotations

import argparse
import concurrent.futures as cf
import functools
import multiprocessing as mp
import os
import sys
import time

import numpy as np
from threadpoolctl import threadpool_limits

from calib_core import synth
from calib_core.errors import CalibError
from calib_core.evaluation.evaluate import evaluate
from calib_core.fitting.metrics import noise_floor
from calib_core.pipeline import calibrate

from . import mrcal_bridge
from .bench_bspline import warm_up
from .bench_compare import REAL_SET, load_real, side_by_side_sets

PARAMETRIC = ("zhang", "fisheye", "rational")
PARAMETRIC_KINDS = ("radial", "fisheye")  # lenses a parametric model represents
GRID = {"intervals": (6, 8, 10, 12, 15), "lambda_smooth": (0.1, 1, 10, 100, 1000)}
QUICK_GRID = {"intervals": (6, 10, 15), "lambda_smooth": (1, 100)}
PAPER_GRID = dict(core="none", intervals=10, lambda_smooth=1.0)  # the paper's model on a fixed grid (base: auto)
SPEED_KINDS = ("radial", "fisheye", "asymmetric")
SCALING_VIEWS = (10, 20, 40, 80, 100, 160)
TARGET_BEST, TARGET_PARAMETRIC, TARGET_BABELCALIB = 1.10, 1.05, 0.415
TARGET_100_VIEWS, TARGET_SPEEDUP, TARGET_SLOPE = 5.0, 3.0, 1.1


def markdown(headers, rows) -> None:
    """A markdown table; floats with 3 decimals, NaN and None as "—"."""
    def cell(v):
        if v is None or (isinstance(v, float) and v != v):
            return "—"
        return f"{v:.3f}" if isinstance(v, float) else str(v)

    print("| " + " | ".join(headers) + " |")
    print("|" + "---|" * len(headers))
    for r in rows:
        print("| " + " | ".join(cell(v) for v in r) + " |")
    print()


def verdict(ok: bool) -> str:
    return "pass" if ok else "**fail**"


def timed(obs, method: str, **settings):
    """(calibration, CPU seconds of the calibrate call)."""
    cpu = time.process_time()
    cal = calibrate(obs, method, **settings)
    return cal, time.process_time() - cpu


# -- accuracy -------------------------------------------------------------------

def fixed_configs(grid: dict) -> dict[str, tuple[str, dict]]:
    """Every fixed configuration: name → (method, settings)."""
    out = {m: (m, {}) for m in PARAMETRIC}
    for core in ("none", "rational"):
        for n in grid["intervals"]:
            for lam in grid["lambda_smooth"]:
                out[f"bspline/{core} {n}x{n} λ={lam:g}"] = ("bspline", dict(core=core, intervals=n, lambda_smooth=lam))
    return out


@functools.lru_cache(maxsize=4)
def dataset(kind: str, seed: int, views: int, sigma: float):
    return synth.generate(kind, sigma=sigma, seed=seed, n_views=views)


def job(kind: str, seed: int, views: int, sigma: float, method: str, settings: dict) -> dict:
    """One calibration of the synthetic set and its hold-out rmse; a
    configuration that cannot fit (CalibError) is marked failed."""
    s = dataset(kind, seed, views, sigma)
    try:
        cal, cpu = timed(s.train, method, **settings)
        holdout = evaluate(cal, s.holdout)["rmse"]
    except CalibError as exc:
        return {"failed": f"{type(exc).__name__}: {exc}"}
    except Exception as exc:  # a bug, not a verdict on the configuration: listed under the table
        return {"failed": f"{type(exc).__name__}: {exc}", "crash": True}
    floor = noise_floor(sigma, cal.diagnostics.solver.n_unknowns, cal.metrics.n_points)
    return {"holdout": holdout, "cpu": cpu, "chosen": cal.settings.get("chosen"),
            "floor_ratio": cal.metrics.rmse_axis / floor}


def one_thread() -> None:
    threadpool_limits(limits=1)  # BLAS and OpenMP, for the whole life of the worker


def run_grid(kinds, seeds, views: int, sigma: float, configs: dict) -> dict:
    """{(kind, seed, name): job result} for the default ("default") and every
    fixed configuration, on two processes with one BLAS thread each."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"  # for the workers, before they import numpy
    jobs = {(k, sd, "default"): ("auto", {}) for k in kinds for sd in seeds}  # the longest first
    jobs.update({(k, sd, name): c for k in kinds for sd in seeds for name, c in configs.items()})
    out = {}
    with cf.ProcessPoolExecutor(2, mp_context=mp.get_context("spawn"), initializer=one_thread) as pool:
        futures = {pool.submit(job, k, sd, views, sigma, m, st): (k, sd, name) for (k, sd, name), (m, st) in jobs.items()}
        for i, f in enumerate(cf.as_completed(futures), 1):
            out[futures[f]] = f.result()
            if i % 100 == 0 or i == len(futures):
                print(f"[{i}/{len(futures)} calibrations]", file=sys.stderr, flush=True)
    return out


def best_of(results: dict, kind: str, seed: int, names) -> tuple[str | None, float]:
    scores = {n: results[kind, seed, n]["holdout"] for n in names if "holdout" in results[kind, seed, n]}
    if not scores:
        return None, float("nan")
    name = min(scores, key=scores.get)
    return name, scores[name]


def accuracy(a) -> None:
    grid = QUICK_GRID if a.quick else GRID
    configs = fixed_configs(grid)
    print(f"## Accuracy of the default against hindsight (σ = {a.sigma} px, {a.views} views; hold-out: "
          "noise-free views over the whole image, model held, poses refit)\n")
    print(f"Grid search: {len(configs)} fixed configurations — {', '.join(PARAMETRIC)}, and bspline with core none / "
          f"rational × intervals {grid['intervals']} × λ_smooth {grid['lambda_smooth']}.\n")
    wall = time.perf_counter()
    results = run_grid(a.kinds, a.seeds, a.views, a.sigma, configs)
    rows, passed = [], 0
    for k in a.kinds:
        for sd in a.seeds:
            d = results[k, sd, "default"]
            best, best_h = best_of(results, k, sd, configs)
            param, param_h = best_of(results, k, sd, PARAMETRIC)
            h = d.get("holdout", float("nan"))
            r_best, r_param = h / best_h, h / param_h
            ok = r_best <= TARGET_BEST and (k not in PARAMETRIC_KINDS or r_param <= TARGET_PARAMETRIC)
            passed += ok
            rows.append([k, sd, h, d.get("chosen", "—"), f"{d.get('cpu', float('nan')):.2f}", d.get("floor_ratio"),
                         best, best_h, r_best, param, param_h,
                         r_param if k in PARAMETRIC_KINDS else f"({r_param:.2f})", verdict(ok)])
    markdown(["kind", "seed", "default hold-out", "chosen", "CPU s", "train axis / floor", "best fixed (hindsight)",
              "its hold-out", f"default / best (≤ {TARGET_BEST})", "best parametric", "its hold-out",
              f"default / parametric (≤ {TARGET_PARAMETRIC})", "verdict"], rows)
    print(f"{passed}/{len(rows)} pass. Parametric ratio in parentheses: no target (no parametric model represents "
          f"the lens). Grid search {time.perf_counter() - wall:.0f} s wall on 2 processes.\n")

    print("Grid search, hold-out rmse [px] (mean over seeds; — : some seed failed)\n")
    def mean(k, name):
        return float(np.mean([results[k, sd, name].get("holdout", np.nan) for sd in a.seeds]))
    names = list(PARAMETRIC) + [f"bspline/{c} {n}x{n}" for c in ("none", "rational") for n in grid["intervals"]]
    cols = [f"λ={lam:g}" for lam in grid["lambda_smooth"]]
    rows = [[k, n] + ([mean(k, n)] + [""] * (len(cols) - 1) if n in PARAMETRIC else [mean(k, f"{n} {c}") for c in cols])
            for k in a.kinds for n in names]
    markdown(["kind", "configuration"] + cols, rows)
    for key, r in results.items():
        if "failed" in r:
            print(f"{'CRASH' if r.get('crash') else 'failed'}: {key}: {r['failed']}")
    print()


# -- BabelCalib -------------------------------------------------------------------

def babelcalib_section(a) -> None:
    print(f"## BabelCalib {REAL_SET}: train/ → test/ with the default\n")
    pair = load_real(REAL_SET)
    if pair is None:
        print(f"skipped: {REAL_SET} not found under ../shared/data (see its README)\n")
        return
    train, test = pair
    cal, cpu = timed(train, "auto")
    e = evaluate(cal, test)
    markdown(["train views / corners", "test views / corners", "chosen", "train rmse", "test rmse",
              f"target ≤ {TARGET_BABELCALIB}", "CPU s"],
             [[f"{len(train.views)} / {train.n_points}", f"{len(test.views)} / {test.n_points}", cal.settings["chosen"],
               cal.metrics.rmse, e["rmse"], verdict(e["rmse"] <= TARGET_BABELCALIB), f"{cpu:.2f}"]])


# -- speed --------------------------------------------------------------------------

def speed(a) -> None:
    """Each figure is the lowest of ``a.repeat`` rounds, each round timing the default, the
    fixed grid and mrcal in turn: the machine's speed drifts by up to 2x over minutes, and a
    ratio of figures taken in one round each is only as good as that drift allows."""
    python = mrcal_bridge.interpreter()
    print("## Speed: CPU seconds of one calibration (after a warm-up), same corners\n")
    print(f"Warm-up calibration: {warm_up():.2f} s CPU; each figure the lowest of {a.repeat} rounds.\n")
    rows = []
    for name, train, test in side_by_side_sets(SPEED_KINDS, 4, REAL_SET):
        best: dict[str, float] = {}
        for _ in range(a.repeat):
            wall = time.perf_counter()
            cal, cpu = timed(train, "auto")
            times = {"default": cpu, "wall": time.perf_counter() - wall}
            fixed, times["fixed"] = timed(train, "bspline", **PAPER_GRID)
            if python:
                m = mrcal_bridge.run(train, test, python)
                times.update({k: m[k].get("seconds", float("nan")) for k in ("splined", "splined_direct")})
            best = {k: min(v, best.get(k, v)) for k, v in times.items()}  # NaN (a failed route) stays NaN
        row = [name, train.n_points, cal.settings["chosen"], f"{best['default']:.2f}", f"{best['wall']:.2f}",
               fixed.settings["base_used"], f"{best['fixed']:.2f}"]
        if python:
            quick = min((best[k] for k in ("splined", "splined_direct") if best[k] == best[k]), default=float("nan"))
            row += [f"{best['splined']:.2f}", f"{best['splined_direct']:.2f}", best["default"] / quick,
                    quick / best["fixed"], verdict(best["default"] <= quick and quick / best["fixed"] >= TARGET_SPEEDUP)]
        rows.append(row)
    headers = ["set", "corners", "default chose", "default CPU s", "default wall s", "fixed 10x10 base", "fixed 10x10 CPU s"]
    if python:
        headers += ["mrcal splined CPU s", "mrcal splined direct CPU s", "default / quicker mrcal (≤ 1)",
                    f"quicker mrcal / fixed (≥ {TARGET_SPEEDUP:g})", "verdict"]
    markdown(headers, rows)
    if not python:
        print("mrcal: skipped (run scripts/ensure-mrcal.sh, or set FREECAL_MRCAL_PYTHON to the python of a venv with mrcal; docs/methods.md, "
              "\"Side by side with mrcal\")\n")
    else:
        print("mrcal splined: SPLINED_STEREOGRAPHIC from OPENCV8's poses (its time includes OPENCV8's); "
              "direct: from the stereographic seed. Fixed 10x10: the paper's model (core none, λ = 1) on the base "
              "--base auto takes.\n")


# -- scaling ------------------------------------------------------------------------

def scaling(a) -> None:
    print("## Scaling: asymmetric lens, σ = 0.3 px, seed 0\n")
    warm_up()
    configs = {"fixed 10x10, λ = 1": ("bspline", PAPER_GRID), "default": ("auto", {})}
    rows, times = [], {c: {} for c in configs}  # label → {views: (corners, CPU s)}
    for views in SCALING_VIEWS:
        s = synth.generate("asymmetric", 0.3, 0, n_views=views)
        for label, (method, settings) in configs.items():
            cal, cpu = timed(s.train, method, **settings)
            times[label][views] = (s.train.n_points, cpu)
            rows.append([views, s.train.n_points, label, cal.settings.get("chosen", "—"),
                         cal.diagnostics.solver.iterations, f"{cpu:.2f}", f"{1000 * cpu / s.train.n_points:.3f}"])
    markdown(["views", "corners", "configuration", "chosen", "final solver iterations", "CPU s",
              "CPU s per 1000 corners"], rows)
    n, t = np.array(list(times["fixed 10x10, λ = 1"].values())).T
    slope = float(np.polyfit(np.log(n), np.log(t), 1)[0])
    at100 = times["default"][100][1]
    print(f"- fixed grid: time ∝ corners^{slope:.2f} (log-log fit; linear ≤ {TARGET_SLOPE}): {verdict(slope <= TARGET_SLOPE)}")
    print(f"- default at 100 views: {at100:.2f} s CPU (≤ {TARGET_100_VIEWS:g} s): {verdict(at100 <= TARGET_100_VIEWS)}\n")


# -- the field screen on few views ------------------------------------------------------

def screened_and_not(kind: str, seed: int, views: int, sigma: float) -> dict:
    """The default's hold-out rmse, choice and CPU on one set, with the field screen on any
    number of views ("screened") and with every field fitted ("every field")."""
    from calib_core.methods import auto
    s = dataset(kind, seed, views, sigma)
    out = {}
    kept = auto.SCREEN_MIN_VIEWS
    for label, min_views in (("screened", 0), ("every field", 10**9)):
        auto.SCREEN_MIN_VIEWS = min_views
        try:
            cal, cpu = timed(s.train, "auto")
            out[label] = (evaluate(cal, s.holdout)["rmse"], cal.settings["chosen"], cpu)
        finally:
            auto.SCREEN_MIN_VIEWS = kept
    return out


def screen_section(a) -> None:
    """Whether the field screen turns away fields that pay, by the number of views."""
    from calib_core.methods.auto import SCREEN_MIN_VIEWS
    print(f"## The field screen by views: kinds {', '.join(a.screen_kinds)}, seeds {a.screen_seeds}, "
          f"views {a.screen_views}, σ {a.screen_sigmas} px\n")
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = "1"
    sets = [(k, sd, v, sg) for k in a.screen_kinds for sd in a.screen_seeds for v in a.screen_views
            for sg in a.screen_sigmas]
    with cf.ProcessPoolExecutor(2, mp_context=mp.get_context("spawn"), initializer=one_thread) as pool:
        results = dict(zip(sets, pool.map(screened_and_not, *map(list, zip(*sets, strict=True))), strict=True))
    rows, changed = [], []
    for views in sorted(set(a.screen_views)):
        part = {key: r for key, r in results.items() if key[2] == views}
        ratio = np.array([r["every field"][0] / r["screened"][0] for r in part.values()])
        better, worse = int(np.sum(ratio < 0.95)), int(np.sum(ratio > 1.05))
        cpu = [sum(r[label][2] for r in part.values()) for label in ("screened", "every field")]
        rows.append([views, len(part), sum(r["every field"][1] != r["screened"][1] for r in part.values()), better,
                     worse, f"{np.exp(np.mean(np.log(ratio))):.3f}", f"{cpu[0]:.0f} → {cpu[1]:.0f}",
                     "every field" if views < SCREEN_MIN_VIEWS else "screened"])
        changed += [(key, r) for key, r in part.items() if r["every field"][1] != r["screened"][1]]
    markdown(["views", "sets", "choice changed", "every field better (> 5 %)", "every field worse (> 5 %)",
              "hold-out, every field / screened (geometric mean)", "CPU s, screened → every field",
              "the default"], rows)
    for (k, sd, v, sg), r in changed:
        print(f"- {k}, seed {sd}, {v} views, σ = {sg:g}: screened {r['screened'][1]} {r['screened'][0]:.4f} px, "
              f"every field {r['every field'][1]} {r['every field'][0]:.4f} px")
    print()


SECTIONS = {"accuracy": accuracy, "babelcalib": babelcalib_section, "speed": speed, "scaling": scaling,
            "screen": screen_section}


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks default")
    ap.add_argument("--sections", default=",".join(SECTIONS), help=f"any of {', '.join(SECTIONS)}")
    ap.add_argument("--kinds", default=",".join(synth.KINDS), help="accuracy: synthetic kinds")
    ap.add_argument("--seeds", default="0,1,2", help="accuracy: seeds")
    ap.add_argument("--views", type=int, default=10, help="accuracy: training views")
    ap.add_argument("--sigma", type=float, default=0.3, help="accuracy: corner noise [px]")
    ap.add_argument("--quick", action="store_true", help="accuracy: intervals {6, 10, 15} × λ {1, 100} only")
    ap.add_argument("--repeat", type=int, default=3, help="speed: rounds; each figure is the lowest of them")
    ap.add_argument("--screen-kinds", default=",".join(synth.ALL_KINDS), help="screen: synthetic kinds")
    ap.add_argument("--screen-seeds", default="7,8,9", help="screen: seeds")
    ap.add_argument("--screen-views", default="3,5,7,10", help="screen: training views, each")
    ap.add_argument("--screen-sigmas", default="0.1,1", help="screen: corner noise [px], each")
    a = ap.parse_args(argv)
    sections = a.sections.split(",")
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        ap.error(f"unknown section(s) {sorted(unknown)}; expected {', '.join(SECTIONS)}")
    a.kinds, a.seeds = a.kinds.split(","), [int(s) for s in a.seeds.split(",")]
    a.screen_kinds, a.screen_seeds = a.screen_kinds.split(","), [int(s) for s in a.screen_seeds.split(",")]
    a.screen_views = [int(v) for v in a.screen_views.split(",")]
    a.screen_sigmas = [float(v) for v in a.screen_sigmas.split(",")]
    bad = set(a.kinds) - set(synth.KINDS)
    if bad:
        ap.error(f"unknown kind(s) {sorted(bad)}; expected {', '.join(synth.KINDS)}")
    sys.stdout.reconfigure(line_buffering=True)  # tables appear as they are ready
    for name, run in SECTIONS.items():
        if name in sections:
            run(a)
    return 0
