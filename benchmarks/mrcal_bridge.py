"""mrcal on the same corners as freecal: hand the corners to ``mrcal_fit.py``
under mrcal's interpreter and read back its residuals.

mrcal's wheels need Python ≥ 3.12 and this project runs on 3.11, so mrcal
lives in its own venv (docs/methods.md, "Side by side with mrcal"), named by
``FREECAL_MRCAL_PYTHON``; the two talk through an npz file.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from calib_core.fitting import metrics
from calib_core.observations import Observations

SCRIPT = Path(__file__).with_name("mrcal_fit.py")
MODELS = ("opencv8", "splined", "splined_direct")  # see mrcal_fit.fit_all


LOCAL_VENV = Path(__file__).resolve().parent.parent / ".mrcal-venv" / "bin" / "python"  # scripts/ensure-mrcal.sh


def interpreter() -> str | None:
    """mrcal's Python: ``FREECAL_MRCAL_PYTHON``, else the venv ``make test`` makes
    (scripts/ensure-mrcal.sh); None when neither exists (the benchmark and the
    tests then skip mrcal)."""
    path = os.environ.get("FREECAL_MRCAL_PYTHON") or str(LOCAL_VENV)
    return path if os.path.exists(path) else None


def lattice(obs: Observations) -> tuple[float, np.ndarray, tuple[int, int]]:
    """mrcal knows only a flat grid board of square spacing: the spacing, the
    grid origin and (W, H) of the corners seen in ``obs`` (a grid no larger than
    needed: mrcal's problem size, and so its time, counts missing corners too)."""
    pts = np.concatenate([v.object_points for v in obs.views])
    if np.any(np.abs(pts[:, 2]) > 1e-9):
        raise ValueError("mrcal needs a planar board (Z = 0)")
    spacing = float((obs.board or {}).get("square_size") or 0)
    if not spacing:  # e.g. BabelCalib boards: the smallest step between distinct coordinates
        steps = np.concatenate([np.diff(np.unique(np.round(pts[:, a], 9))) for a in (0, 1)])
        spacing = float(steps.min())
    origin = pts[:, :2].min(axis=0)
    idx = (pts[:, :2] - origin) / spacing
    if np.max(np.abs(idx - np.round(idx))) > 1e-6:
        raise ValueError("board corners are not on a square grid")
    w, h = (np.round(idx).max(axis=0) + 1).astype(int)
    return spacing, origin, (int(w), int(h))


def to_grid(obs: Observations) -> tuple[np.ndarray, float]:
    """(views, H, W, 3) of (x, y, weight), missing corners at weight −1; and the spacing."""
    spacing, origin, (w, h) = lattice(obs)
    out = np.full((len(obs.views), h, w, 3), -1.0)
    for k, v in enumerate(obs.views):
        ix, iy = np.round((v.object_points[:, :2] - origin) / spacing).astype(int).T
        out[k, iy, ix, :2] = v.image_points
        out[k, iy, ix, 2] = 1.0
    return out, spacing


def run(train: Observations, test: Observations, python: str, timeout: float = 3600.0) -> dict[str, dict]:
    """{model: {"lensmodel", "train_rmse", "train_rmse_axis", "test_rmse", "test_rmse_axis",
    "seconds", "n_train", "outliers"} or {"error": ...}} for mrcal's models (``MODELS``).
    The rmse is freecal's (``metrics``) over the corners observed (train: not rejected)."""
    with tempfile.TemporaryDirectory() as tmp:
        src, dst = Path(tmp, "in.npz"), Path(tmp, "out.npz")
        (g_train, s_train), (g_test, s_test) = to_grid(train), to_grid(test)
        np.savez(src, train=g_train, test=g_test, train_spacing=s_train, test_spacing=s_test,
                 imagersize=np.array(train.image_size))
        proc = subprocess.run([python, str(SCRIPT), str(src), str(dst)], capture_output=True, text=True,
                              timeout=timeout, env={**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"})
        if proc.returncode != 0:
            err = f"mrcal_fit.py failed: {proc.stderr.strip().splitlines()[-1:]}"
            return {m: {"error": err} for m in MODELS}
        if proc.stderr.strip():
            print(proc.stderr.strip(), file=sys.stderr)
        d = dict(np.load(dst))
    out = {}
    for m in MODELS:
        if "error" in d or f"{m}_error" in d:
            out[m] = {"error": str(d.get("error", d.get(f"{m}_error")))}
            continue
        r_train = d[f"{m}_train"][d[f"{m}_train_used"]]
        r_test = d[f"{m}_test"][d[f"{m}_test_used"]]
        out[m] = {"lensmodel": str(d[f"{m}_lensmodel"]), "seconds": float(d[f"{m}_seconds"]),
                  "train_rmse": metrics.rmse(r_train), "train_rmse_axis": metrics.rmse_axis(r_train),
                  "test_rmse": metrics.rmse(r_test), "test_rmse_axis": metrics.rmse_axis(r_test),
                  "n_train": int(len(r_train)), "outliers": int(train.n_points - len(r_train))}
    return out
