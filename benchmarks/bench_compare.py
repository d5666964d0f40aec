"""Every method side by side on the paper's synthetic protocol: Tables 4, 5, 8
and 9 of Wang et al. 2026 beside the paper's numbers, the synthetic hold-out
set, and the validation of the B-spline projection uncertainty.

    python -m benchmarks compare [--kinds radial,fisheye,asymmetric]
        [--sections compare,noise,uncertainty,mrcal] [--sigmas 0.1,0.3,0.5,1.0,2.0]
        [--splits 5] [--realisations 50] [--real babelcalib-ov-plane-fisheye] [--json OUT]

The mrcal side by side (``mrcal_bridge.py``) runs when mrcal's interpreter is there
(``scripts/ensure-mrcal.sh`` or ``FREECAL_MRCAL_PYTHON``: docs/methods.md, "Side by side with mrcal");
otherwise that section is skipped with a note.  ``--sections mrcal`` runs it
alone in a few minutes.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from backend.commands.output import table as print_table
from calib_core import synth
from calib_core.detection import babelcalib
from calib_core.errors import CalibError
from calib_core.evaluation.compare import compare
from calib_core.evaluation.evaluate import validation_residuals
from calib_core.evaluation.uncertainty import aligned_projection, projection_uncertainty
from calib_core.fitting import metrics
from calib_core.fitting.solve import Data, SolveSettings, levenberg_marquardt
from calib_core.observations import Observations, View
from calib_core.pipeline import calibrate, to_data

from . import mrcal_bridge
from .bench_bspline import warm_up
from .bench_detect import DATA

METHODS = ["zhang", "rational", "fisheye", "mls", "tps", "bspline"]
# Table 4 (overall rmse px; radial, fisheye, asymmetric); BabelCalib = KB 9th order, MC-Calib = rational 8.
PAPER_T4 = {"bspline": (0.393, 0.444, 0.797), "zhang": (3.42, 4.57, 16.9), "fisheye": (1.32, 1.12, 1.98),
            "rational": (1.28, 0.98, 1.60), "mls": (0.68, 0.88, 1.26), "tps": (0.64, 0.92, 1.37)}
PAPER_T8 = "ours: calibration 0.27 → validation 0.36 px (8/2 views, 5 splits)"
PAPER_T9 = "ours: centre 0.236 px, edge 0.256 px"
PAPER_T5 = "ours at σ = 0.1: 0.28 … 0.77 px; grows about linearly with σ"
SECTIONS = ("compare", "noise", "uncertainty", "mrcal")
REAL_SET = "babelcalib-ov-plane-fisheye"  # the lens past 180°: train/ → test/


def table(headers, rows) -> None:
    print_table(headers, rows)
    print()


def thin(obs: Observations, every: int) -> Observations:
    """Every ``every``-th corner of each view: the synthetic hold-out set has
    ~33k corners, and a quarter of them measures the same thing 4× faster."""
    return Observations(obs.image_size, [v.subset(np.arange(len(v)) % every == 0) for v in obs.views], obs.board)


def run_compare(kinds, splits, methods, holdout_every: int) -> dict:
    out = {}
    for kind in kinds:
        s = synth.generate(kind)
        t0 = time.perf_counter()
        out[kind] = compare(s.train, methods, splits,
                            thin(s.holdout, holdout_every) if holdout_every else None).to_json()
        out[kind]["seconds"] = time.perf_counter() - t0
        print(f"[{kind}: {out[kind]['seconds']:.0f} s]", flush=True)
    return out


def noise_sweep(kinds, sigmas, methods) -> dict:
    out = {}
    for kind in kinds:
        for sigma in sigmas:
            s = synth.generate(kind, sigma=sigma)
            for m in methods:
                try:
                    out[kind, sigma, m] = calibrate(s.train, m).metrics.rmse
                except CalibError:
                    out[kind, sigma, m] = float("nan")
    return out


def uncertainty_check(kind: str, realisations: int, sigma: float = 0.3, seed: int = 1) -> dict:
    """Predicted per-pixel projection spread (one noisy calibration, σ from its
    residuals) against the spread over ``realisations`` noise draws (the knots
    held: the covariance is of the fit, not of the knot placement). Directions
    are fixed in the boards' frames (mrcal's convention, ``calib_core/evaluation/uncertainty.py``)."""
    rng = np.random.default_rng(seed)
    clean = synth.generate(kind, sigma=0.0)
    data, _, _ = to_data(clean.train)

    def noisy() -> np.ndarray:
        return data.image_points + rng.normal(0.0, sigma, data.image_points.shape)

    first = noisy()
    views, off = [], 0
    for v in clean.train.views:
        views.append(View(v.name, v.object_points, first[off : off + len(v)], v.ids))
        off += len(v)
    cal = calibrate(Observations(clean.train.image_size, views, clean.train.board), "bspline", outlier_sigma=0)
    poses = np.array([v.pose for v in cal.views])
    d0 = Data(data.object_points, first, data.view_index, data.n_views)
    um = projection_uncertainty(cal.model, poses, d0, clean.train.image_size, step=64.0)
    rays = um.rays.reshape(-1, 3)
    ok = np.all(np.isfinite(rays), axis=1) & um.covered.reshape(-1)
    projs = []
    for _ in range(realisations):
        d = Data(data.object_points, noisy(), data.view_index, data.n_views)
        res = levenberg_marquardt(cal.model, poses, d, SolveSettings(ftol=1e-12, max_iterations=100))
        projs.append(aligned_projection(res.model, res.poses, poses, rays[ok]))
    emp = np.sqrt(0.5 * np.var(np.array(projs), axis=0, ddof=1).sum(axis=-1))
    pred = um.std_rms.reshape(-1)[ok]
    ratio = pred / emp  # NaN would mean a non-finite prediction: counted, never hidden
    if not np.all(np.isfinite(ratio)):
        print(f"warning: {int(np.sum(~np.isfinite(ratio)))} grid pixels have no finite predicted spread")
    return {"kind": kind, "sigma_true": sigma, "sigma_estimated": um.sigma, "n_pixels": int(ok.sum()),
            "predicted_median": float(np.median(pred)), "empirical_median": float(np.median(emp)),
            "ratio_median": float(np.median(ratio)), "ratio_p10": float(np.percentile(ratio, 10)),
            "ratio_p90": float(np.percentile(ratio, 90)), "within_30pct": float(np.mean(np.abs(ratio - 1) <= 0.3))}


def print_compare(results: dict, kinds, methods, splits: int, holdout_every: int) -> None:
    def val(kind, m, key):
        e = results[kind]["methods"].get(m, {})
        return e.get(key, float("nan")) if "error" not in e else float("nan")

    print("Table 4: overall rmse [px, per point], ours (paper) — synthetic, σ = 0.3, 10 views")
    table(["method"] + kinds, [[m] + [f"{val(k, m, 'rmse'):.3f} ({PAPER_T4[m][synth.PAPER_KINDS.index(k)] if k in synth.PAPER_KINDS else '—'})" for k in kinds]
                               for m in methods])
    print(f"Table 8: cross-validation over views ({splits} splits) [rmse px]: calibration → validation (+increase;"
          " four digits: on OpenCV's own lens the methods differ in the fourth)."
          f"  Paper {PAPER_T8}")
    table(["method"] + kinds, [[m] + [
        (lambda cv: f"{cv['calibration_rmse']['mean']:.3f}±{cv['calibration_rmse']['std']:.3f} → "
                    f"{cv['validation_rmse']['mean']:.4f}±{cv['validation_rmse']['std']:.3f} "
                    f"(+{cv['increase']['mean']:.3f})")(results[k]["methods"][m]["cv"])
        if "cv" in results[k]["methods"].get(m, {}) else "—" for k in kinds] for m in methods])
    print(f"Table 9: centre / edge rmse [px].  Paper {PAPER_T9}")
    table(["method"] + kinds, [[m] + [f"{val(k, m, 'rmse_center'):.3f} / {val(k, m, 'rmse_edge'):.3f}" for k in kinds]
                               for m in methods])
    if holdout_every:
        print(f"Synthetic hold-out views (noise-free, whole image, every {holdout_every}th corner; pose-only refit)"
              " [rmse px]")
        table(["method"] + kinds, [[m] + [val(k, m, "holdout_rmse") for k in kinds] for m in methods])
    print("Verdict (lowest cross-validated rmse) and the spatial-structure test of its validation residuals")
    table(["kind", "verdict", "cv rmse", "neighbour rho", "p", "structured"],
          [[k, results[k]["verdict"], results[k]["verdict_detail"]["value"],
            results[k]["verdict_detail"].get("spatial_structure", {}).get("rho", float("nan")),
            results[k]["verdict_detail"].get("spatial_structure", {}).get("p_value", float("nan")),
            str(results[k]["verdict_detail"].get("spatial_structure", {}).get("structured"))] for k in kinds])
    for k in kinds:
        for m in methods:
            if "error" in results[k]["methods"].get(m, {}):
                print(f"{k} / {m}: {results[k]['methods'][m]['error']}")


def print_uncertainty(unc: list[dict], realisations: int) -> None:
    print(f"B-spline projection uncertainty: predicted vs observed over {realisations} noise draws "
          "(per-axis rms spread, grid pixels near observed corners)")
    table(["kind", "σ est", "pixels", "pred median", "emp median", "ratio median", "p10", "p90", "within 30 %"],
          [[u["kind"], u["sigma_estimated"], u["n_pixels"], u["predicted_median"], u["empirical_median"],
            u["ratio_median"], u["ratio_p10"], u["ratio_p90"], u["within_30pct"]] for u in unc])


def side_by_side_sets(kinds, holdout_every: int, real: str):
    """(name, train, hold-out) for the mrcal comparison: the synthetic kinds
    (the hold-out thinned as for the compare tables) and the real set, if present."""
    for k in kinds:
        s = synth.generate(k)
        yield k, s.train, thin(s.holdout, holdout_every) if holdout_every else s.holdout
    if real:
        pair = load_real(real)
        if pair:
            yield (real, *pair)
        else:
            print(f"(real set {real} not found under {DATA}: skipped)")


def load_real(name: str = REAL_SET) -> tuple[Observations, Observations] | None:
    """(train, test) of a BabelCalib set of ../shared/data (its authors' split), or None if absent."""
    folder = DATA / name
    if not folder.is_dir():
        return None
    board = next(folder.glob("*.dsc"))
    return babelcalib.load(folder / "train", board), babelcalib.load(folder / "test", board)


def freecal_fit(train, test, method: str, **settings) -> dict:
    """One freecal calibration of ``train``: its CPU seconds, training and hold-out rmse, and its model in words."""
    t0 = time.process_time()  # CPU time, as mrcal_fit.py measures: the machine may be shared
    cal = calibrate(train, method, **settings)
    seconds = time.process_time() - t0
    r, _, _ = validation_residuals(cal, test)  # pose-only refit, as mrcal_fit.holdout does
    return {"seconds": seconds, "train_rmse": cal.metrics.rmse, "train_rmse_axis": cal.metrics.rmse_axis,
            "test_rmse": metrics.rmse(r), "test_rmse_axis": metrics.rmse_axis(r),
            "outliers": cal.diagnostics.excluded_points.outliers, "model": in_words(cal.settings)}


def in_words(st: dict) -> str:
    """A freecal calibration's model, from its settings: the parametric model chosen, or its field."""
    if "intervals_used" not in st:
        return f"{st['chosen']} alone"
    field = (f"a field over the {st['core_used']} model" if st["core_used"] != "none"
             else f"the paper's field on the {st['base_used']} base")
    return f"{field}, {'x'.join(map(str, st['intervals_used']))} intervals"


def mrcal_side_by_side(kinds, holdout_every: int, real: str, python: str) -> dict:
    """freecal's default (and, for contrast, the paper's model on a fixed grid)
    against mrcal's OPENCV8 and splined models on the same corners; ratios are
    each row / freecal's default."""
    out, rows = {}, []
    warm_up()  # mrcal's timed solves run in a process that has loaded mrcal already
    for name, train, test in side_by_side_sets(kinds, holdout_every, real):
        ours = freecal_fit(train, test, "auto")
        # For contrast, the paper's model as the paper runs it: no model choice, a fixed
        # 10 x 10 grid and smoothing, on the base the lens wants (--base auto).
        paper = freecal_fit(train, test, "bspline", core="none", intervals=10, lambda_smooth=1.0)
        res = {"freecal default": ours, "freecal paper model": paper}
        res.update({f"mrcal {m}": r for m, r in mrcal_bridge.run(train, test, python).items()})
        for method, r in res.items():
            if "error" in r:
                rows.append([name, method, r["error"], "", "", "", "", ""])
                continue
            rows.append([name, method, r["train_rmse"], r["test_rmse"], r["test_rmse_axis"], r["seconds"],
                         r["test_rmse"] / ours["test_rmse"], r["seconds"] / ours["seconds"]])
        out[name] = res
        print(f"[{name} done]", flush=True)
    print("Side by side with mrcal, same corners: rmse [px, per point; hold-out also per axis, mrcal's figure] "
          "after a pose-only refit of the fixed model; seconds = CPU time of one calibration (seed included)")
    table(["set", "method", "train", "hold-out", "hold-out axis", "seconds", "hold-out / freecal",
           "time / freecal"], rows)
    for name, res in out.items():
        for m, r in res.items():
            if "error" not in r:
                print(f"{name} / {m}: {r.get('lensmodel') or r.get('model')} ({r['outliers']} outliers rejected)")
    return out


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks compare")
    ap.add_argument("--kinds", default=",".join(synth.PAPER_KINDS), help=f"any of {', '.join(synth.KINDS)}")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--sections", default=",".join(SECTIONS), help=f"any of {', '.join(SECTIONS)}")
    ap.add_argument("--sigmas", default="0.1,0.3,0.5,1.0,2.0")
    ap.add_argument("--splits", type=int, default=5)
    ap.add_argument("--realisations", type=int, default=50)
    ap.add_argument("--holdout-every", type=int, default=4, help="use every N-th hold-out corner (0: compare skips the hold-out set, mrcal uses all)")
    ap.add_argument("--real", default=REAL_SET, help="real set of ../shared/data for the mrcal section ('' to skip)")
    ap.add_argument("--json", help="also write every number here")
    a = ap.parse_args(argv)
    kinds, methods, sections = a.kinds.split(","), a.methods.split(","), a.sections.split(",")
    unknown = set(sections) - set(SECTIONS)
    if unknown:
        ap.error(f"unknown section(s) {sorted(unknown)}; expected {', '.join(SECTIONS)}")
    sigmas = [float(x) for x in a.sigmas.split(",") if x]
    sys.stdout.reconfigure(line_buffering=True)  # tables appear as they are ready
    out: dict = {}
    if "compare" in sections:
        out["compare"] = run_compare(kinds, a.splits, methods, a.holdout_every)
        print_compare(out["compare"], kinds, methods, a.splits, a.holdout_every)

    if "noise" in sections and sigmas:
        sweep = noise_sweep(kinds, sigmas, methods)
        print(f"Table 5: noise sweep, overall rmse [px].  Paper {PAPER_T5}")
        table(["kind", "σ"] + methods, [[k, s] + [sweep[k, s, m] for m in methods] for k in kinds for s in sigmas])
        out["noise_sweep"] = [{"kind": k, "sigma": s, "method": m, "rmse": v} for (k, s, m), v in sweep.items()]

    if "uncertainty" in sections and a.realisations > 0:
        out["uncertainty"] = [uncertainty_check(k, a.realisations) for k in kinds]
        print_uncertainty(out["uncertainty"], a.realisations)

    if "mrcal" in sections:
        python = mrcal_bridge.interpreter()
        if python:
            out["mrcal"] = mrcal_side_by_side(kinds, a.holdout_every, a.real, python)
        else:
            print("mrcal: skipped (run scripts/ensure-mrcal.sh, or set FREECAL_MRCAL_PYTHON to the python of a venv with mrcal; docs/methods.md)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1, default=float)
    return 0
