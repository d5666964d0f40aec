"""The B-spline method on the paper's synthetic protocol: accuracy against the
noise floor and on held-out views, the noise sweep (Table 5), the paper's
ablations (Tables 10–14) and speed.

    python -m benchmarks bspline [SECTION ...] [--seeds N]

SECTION: accuracy, noise, knots, bandwidth, weighting, lambda, density, speed (default:
all). Every figure is measured here, in this process; nothing is copied.
"""
from __future__ import annotations

import argparse
import os
import time

import numpy as np

from backend.commands.output import table as print_table
from calib_core import calibrate, synth
from calib_core.evaluation.evaluate import evaluate
from calib_core.fitting.metrics import noise_floor

# The paper's model (no parametric core) and freecal's default, side by side: label → (method, settings).
VARIANTS = {
    "paper model, paper knots": ("bspline", dict(core="none", knots="kde-paper")),
    "paper model, freecal knots": ("bspline", dict(core="none")),
    "freecal default (method auto)": ("auto", {}),
}
PAPER_TRAIN_RMSE = {"radial": 0.393, "fisheye": 0.444, "asymmetric": 0.797}


def run(kind: str, sigma: float, seed: int, method: str = "bspline", **settings):
    s = synth.generate(kind, sigma, seed)
    t0 = time.perf_counter()
    cal = calibrate(s.train, method, **settings)
    seconds = time.perf_counter() - t0
    m = cal.metrics
    p = cal.diagnostics.solver.n_unknowns
    floor = noise_floor(sigma, p, m.n_points)
    hold = evaluate(cal, s.holdout)
    return {"cal": cal, "seconds": seconds, "floor": floor, "ratio": m.rmse_axis / floor, "holdout": hold["rmse"],
            "rmse": m.rmse, "rmse_axis": m.rmse_axis, "n": m.n_points, "p": p}


def grid_of(cal, with_factor: bool = False) -> str:
    """The field's knot grid (and Scott factor), or the core a field-less result kept."""
    st = cal.settings
    if st.get("field_held"):
        return f"{st['core_used']} alone"
    if "intervals_used" not in st:  # the default chose a parametric model
        return f"{st['chosen']} alone"
    grid = "x".join(map(str, st["intervals_used"]))
    return f"{grid} x {st['bandwidth_factor_used']}" if with_factor else grid


def mean_of(rows, key):
    return float(np.mean([r[key] for r in rows]))


def accuracy(seeds: int) -> None:
    print("\n## Accuracy at sigma = 0.3 px (mean over seeds; hold-out: noise-free views over the whole image)\n")
    rows = []
    for kind in synth.KINDS:  # the paper's three, then freeform and decentred (no paper figure)
        for name, (method, settings) in VARIANTS.items():
            rs = [run(kind, 0.3, sd, method, **settings) for sd in range(seeds)]
            cal = rs[-1]["cal"]
            rows.append((kind, name, rs[-1]["n"], rs[-1]["p"], mean_of(rs, "rmse"), PAPER_TRAIN_RMSE.get(kind, float("nan")),
                         mean_of(rs, "rmse_axis"), mean_of(rs, "floor"), mean_of(rs, "ratio"),
                         mean_of(rs, "holdout"), max(r["holdout"] for r in rs),
                         grid_of(cal), mean_of(rs, "seconds")))
    print_table(["lens", "variant", "points", "unknowns", "rmse", "paper rmse", "rmse_axis", "floor",
                 "axis/floor", "hold-out", "worst hold-out", "grid", "time [s]"], rows)


def noise(seeds: int) -> None:
    print("\n## Noise sweep (Table 5): training rmse_axis / noise floor, the paper's model (grid and λ by validation)\n")
    sigmas = (0.1, 0.3, 0.5, 1.0, 1.5, 2.0)
    rows = []
    for kind in ("radial", "asymmetric"):
        cells = []
        for sigma in sigmas:
            rs = [run(kind, sigma, sd) for sd in range(seeds)]
            cells.append(f"{mean_of(rs, 'rmse_axis'):.3f} ({mean_of(rs, 'ratio'):.3f})")
        rows.append((kind, *cells))
    print_table(["lens", *[f"sigma={s}" for s in sigmas]], rows)
    print("cells: rmse_axis [px] (ratio to the floor sigma*sqrt(1 - P/2N))")


def _design_row(label, r):
    d = r["cal"].diagnostics.extra["design"]
    return (label, f"{d['intervals'][0]}x{d['intervals'][1]}", f"{d['rank']}/{d['n_controls']}",
            d["condition_x"], d["condition_y"], d["zero_columns"], d["empty_intervals_u"] + d["empty_intervals_v"],
            r["rmse"], r["ratio"], r["holdout"])


DESIGN_HEADERS = ["knots", "grid", "rank", "cond x", "cond y", "zero cols", "empty intervals", "rmse",
                  "axis/floor", "hold-out"]


def knots(seeds: int) -> None:
    print("\n## Knot ablation (Tables 10-11), paper model (no core), asymmetric lens, seed 0\n")
    base = dict(core="none")
    rows = [_design_row("kde (freecal)", run("asymmetric", 0.3, 0, **base)),
            _design_row("kde-paper", run("asymmetric", 0.3, 0, knots="kde-paper", **base)),
            _design_row("uniform 10x10", run("asymmetric", 0.3, 0, knots="uniform", intervals=10, **base))]
    # Pathological: every interior knot crowded into 8 px at the image centre,
    # so that most tensor cells there hold no corner.
    w, h = synth.IMAGE_SIZE
    crowd = (list(np.linspace(w / 2 - 4, w / 2 + 4, 9)), list(np.linspace(h / 2 - 4, h / 2 + 4, 9)))
    rows.append(_design_row("pathological", run("asymmetric", 0.3, 0, knots="explicit", interior_knots=crowd,
                                                lambda_smooth=1e-3, **base)))
    print_table(DESIGN_HEADERS, rows)


def bandwidth(seeds: int) -> None:
    print("\n## KDE bandwidth (Section 3.5.2), paper model with the paper's knots, asymmetric lens\n")
    rows = []
    for label, kw in [("Silverman", dict(bandwidth="silverman")), *[
            (f"Scott x {f}", dict(bandwidth_factor=f)) for f in (0.8, 1.0, 1.2, 1.5)]]:
        rs = [run("asymmetric", 0.3, sd, core="none", knots="kde-paper", **kw) for sd in range(seeds)]
        rows.append(_design_row(label, rs[-1])[:2] + (mean_of(rs, "rmse"), mean_of(rs, "ratio"), mean_of(rs, "holdout")))
    print_table(["bandwidth", "grid", "rmse", "axis/floor", "hold-out"], rows)


def weighting(seeds: int) -> None:
    print("\n## Sample weighting (Table 12), paper model with the paper's knots, asymmetric lens\n")
    rows = []
    for how in ("uniform", "magnitude", "gradient", "local_std"):
        rs = [run("asymmetric", 0.3, sd, core="none", knots="kde-paper", weighting=how) for sd in range(seeds)]
        rows.append((how, "x".join(map(str, rs[-1]["cal"].settings["intervals_used"])),
                     mean_of(rs, "rmse"), mean_of(rs, "ratio"), mean_of(rs, "holdout")))
    print_table(["weighting", "grid", "rmse", "axis/floor", "hold-out"], rows)


def lambdas(seeds: int) -> None:
    print("\n## Regularisation grid (Tables 13-14): hold-out rmse [px], paper model, uniform 10x10, asymmetric\n")
    regs, smooths = (0.0, 1e-6, 1e-3, 1e-1), (0.0, 1e-2, 1.0, 1e2, 1e4)
    rows = []
    for reg in regs:
        cells = [f"{run('asymmetric', 0.3, 0, core='none', knots='uniform', intervals=10, lambda_reg=reg, lambda_smooth=sm)['holdout']:.3f}"
                 for sm in smooths]
        rows.append((f"lambda_reg={reg:g}", *cells))
    print_table(["", *[f"lambda_smooth={s:g}" for s in smooths]], rows)
    print("(lambda_smooth weighs the bending energy of the field against squared pixel residuals; "
          "the default chooses it by GCV)")


def density(seeds: int) -> None:
    """GCV's choice of (intervals, bandwidth factor) against a grid search of
    fixed pairs scored by hold-out, the issue's target being within 5 %."""
    print("\n## Knot density from the data: GCV's choice against the best fixed (grid, Scott factor) pair "
          f"(hold-out rmse [px], mean of {seeds} seeds)\n")
    grids, factors = (6, 8, 10, 12, 15), (0.8, 1.0, 1.2, 1.5)
    autos = {"auto grid, factor 1.0": dict(), "auto grid, auto factor": dict(bandwidth_factor="auto")}
    grid_rows, rows = [], []
    for kind in ("asymmetric", "radial"):
        for core in ("none", "auto"):
            def mean_run(kind=kind, core=core, **kw):
                rs = [run(kind, 0.3, sd, core=core, **kw) for sd in range(seeds)]
                picks = {grid_of(r["cal"], with_factor=True) for r in rs}
                return mean_of(rs, "holdout"), mean_of(rs, "seconds"), picks

            fixed = {(m, f): mean_run(intervals=m, bandwidth_factor=f)[0] for f in factors for m in grids}
            grid_rows += [(kind, core, f"x {f}", *[fixed[m, f] for m in grids]) for f in factors]
            (m, f), best = min(fixed.items(), key=lambda item: item[1])
            for label, kw in autos.items():
                hold, secs, picks = mean_run(**kw)
                chosen = ", ".join(sorted(picks))
                rows.append((kind, core, f"{m}x{m} x {f}", best, label, chosen, hold, hold / best, secs))
    print_table(["lens", "core", "Scott factor", *[f"{m}x{m}" for m in grids]], grid_rows)
    print()
    print_table(["lens", "core", "best fixed pair", "its hold-out", "automatic", "chosen (per seed)", "hold-out",
                 "auto / best fixed", "time [s]"], rows)


def warm_up() -> float:
    """CPU seconds of a first calibration in this process: it loads the
    compiled kernels and SciPy's lazily imported modules, once; timings after
    it are free of that."""
    s = synth.generate("asymmetric", 0.3, 0, n_views=10)
    cpu = time.process_time()
    calibrate(s.train, "bspline", core="none", intervals=10, lambda_smooth=1.0)
    return time.process_time() - cpu


def speed(seeds: int) -> None:
    print("\n## Speed (one core: OPENBLAS_NUM_THREADS=1), end to end from corners to calibration\n")
    print("CPU seconds are the process's own (a busy machine inflates wall time, not these).\n")
    print(f"First calibration in this process (paper model, 10 views, loading included): "
          f"{warm_up():.2f} s CPU; the table below is measured after it.\n")
    rows = []
    configurations = (("paper model, fixed 10x10 grid and lambda", "bspline",
                       dict(core="none", intervals=10, lambda_smooth=1.0)),
                      ("paper model, grid and lambda by validation", "bspline", dict(core="none")),
                      ("freecal default (method auto)", "auto", {}))
    for views in (10, 20, 40, 100):
        s = synth.generate("asymmetric", 0.3, 0, n_views=views)
        for label, method, settings in configurations:
            wall, cpu = time.perf_counter(), time.process_time()
            cal = calibrate(s.train, method, **settings)
            wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
            rows.append((views, s.train.n_points, label, wall, cpu, 1e6 * cpu / s.train.n_points,
                         cal.diagnostics.solver.iterations))
    print_table(["views", "points", "configuration", "wall [s]", "CPU [s]", "CPU us per point", "final LM iterations"],
                rows)


SECTIONS = {"accuracy": accuracy, "noise": noise, "knots": knots, "bandwidth": bandwidth,
            "weighting": weighting, "lambda": lambdas, "density": density, "speed": speed}


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks bspline")
    parser.add_argument("sections", nargs="*", default=[], help=", ".join(SECTIONS))
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args(argv)
    unknown = [name for name in args.sections if name not in SECTIONS]
    if unknown:
        parser.error(f"unknown section(s) {unknown}; choose from {list(SECTIONS)}")
    if os.environ.get("OPENBLAS_NUM_THREADS") != "1":
        print("note: set OPENBLAS_NUM_THREADS=1 for one-core timings")
    for name in args.sections or SECTIONS:
        SECTIONS[name](args.seeds)
    return 0
