"""Lean-model fits: the closest OpenCV (4/5/8/12/14 coefficients) or
Kannala–Brandt (4) model to any calibration, so it can be exported to tools
that know only those, with a number and a map that say what is lost.

Rays are sampled on a grid of photo pixels wherever the calibration can
unproject them (``Calibration.rays``, principal branch) and, for the pinhole
OpenCV models, less than ``MAX_ANGLE_DEG`` off axis; the lean model is fitted
to reproduce those pixels by our Levenberg–Marquardt (``solve.py``) with the
pose held at identity: a direct least-squares fit of the projection. The fit
error is ``|lean(ray) − calibration(ray)|`` in pixels at each sample.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..calibration import Calibration
from ..errors import CalibError, SettingsError
from ..fitting.solve import Data, SolveSettings, levenberg_marquardt
from ..models import FisheyeModel, OpenCVModel
from ..models.base import ParametricModel

LEAN_MODELS: dict[str, tuple[str, int]] = {
    "opencv4": ("opencv", 4), "opencv5": ("opencv", 5), "opencv8": ("opencv", 8),
    "opencv12": ("opencv", 12), "opencv14": ("opencv", 14), "kb4": ("fisheye", 4),
}
GRID = (64, 80)  # samples across, down (W × H = 1024 × 1280 → every 16 px)
MAX_ANGLE_DEG = 85.0  # beyond this a pinhole-normalised OpenCV fit is hopeless


class LeanFitError(CalibError):
    """The lean model cannot be fitted to this calibration."""


@dataclass
class LeanFit:
    """A lean model fitted to a calibration, and how far it strays.

    ``error_map`` (grid_h, grid_w): pixel error at the grid's photo pixels
    ``u`` (grid_w,), ``v`` (grid_h,); NaN where no ray was sampled."""

    name: str
    calibration: Calibration  # the lean model in a Calibration (no views)
    rms: float
    max: float
    p99: float
    n_samples: int
    u: np.ndarray
    v: np.ndarray
    error_map: np.ndarray
    exact: bool = False  # the calibration already was this model: nothing fitted

    @property
    def model(self) -> ParametricModel:
        """The lean model itself, OpenCV's or Kannala–Brandt's: what exporters write."""
        model = self.calibration.model
        if not isinstance(model, ParametricModel):  # fit_lean only ever makes parametric ones
            raise TypeError(f"a lean fit holds a parametric model, not {model.kind!r}")
        return model

    def summary(self) -> dict[str, Any]:
        return {"model": self.name, "fit_rms_px": self.rms, "fit_max_px": self.max, "fit_p99_px": self.p99,
                "n_samples": self.n_samples, "exact": self.exact}


def parametric_part(cal: Calibration) -> Calibration | None:
    """The calibration as a parametric one, exactly, or None: itself if its model
    is ``opencv``/``fisheye``, its core if it is a hybrid whose field is held at
    zero (the B-spline method's choice on a lens a textbook model fits)."""
    parametric = cal.model.exact_parametric()
    if parametric is None:
        return None
    return cal if parametric is cal.model else dataclasses.replace(cal, model=parametric)


def exact_name(cal: Calibration) -> str | None:
    """The lean-model name ``cal`` already is (``opencv5`` …, ``kb4``), or None."""
    m = cal.model
    if isinstance(m, OpenCVModel):
        return f"opencv{len(m.coefficients)}"
    if isinstance(m, FisheyeModel) and len(m.coefficients) == 4:
        return "kb4"
    return None


def sample_grid(cal: Calibration, grid: tuple[int, int] = GRID, max_angle_deg: float = MAX_ANGLE_DEG,
                covered: np.ndarray | None = None):
    """Photo-pixel grid ``u`` (gw,), ``v`` (gh,), its rays (gh·gw, 3) and which are usable (gh·gw,).
    With ``covered`` (M, 2), observed pixels, only the grid inside their convex hull is usable."""
    w, h = cal.image_size
    u, v = np.linspace(0, w - 1, grid[0]), np.linspace(0, h - 1, grid[1])
    uu, vv = np.meshgrid(u, v)
    rays = cal.rays(np.column_stack([uu.ravel(), vv.ravel()]))
    ok = np.all(np.isfinite(rays), axis=1) & (rays[:, 2] > np.cos(np.radians(max_angle_deg)))
    if covered is not None:
        from scipy.spatial import Delaunay

        pts = np.asarray(covered, dtype=np.float64).reshape(-1, 2)
        if len(pts) < 3:
            raise LeanFitError("covered: need at least 3 observed pixels to bound the fit region")
        ok &= Delaunay(pts).find_simplex(np.column_stack([uu.ravel(), vv.ravel()])) >= 0
    return u, v, rays, ok


def fit_lean(cal: Calibration, name: str, grid: tuple[int, int] = GRID, covered: np.ndarray | None = None) -> LeanFit:
    """Fit the lean model ``name`` (a key of ``LEAN_MODELS``) to ``cal``'s projection over
    the convex hull of ``covered`` (M, 2) pixels (e.g. the observed corners: where
    the calibration has data); by default the hull the calibration recorded
    (``diagnostics.coverage_hull``), or the whole image if it has none."""
    if name not in LEAN_MODELS:
        raise SettingsError(f"lean model: expected one of {sorted(LEAN_MODELS)}, got {name!r}")
    kind, n = LEAN_MODELS[name]
    if covered is None and len(cal.diagnostics.get("coverage_hull", [])) >= 3:
        covered = np.asarray(cal.diagnostics["coverage_hull"])  # where the calibration had corners
    u, v, rays, ok = sample_grid(cal, grid, covered=covered)
    if ok.sum() < 50:
        raise LeanFitError(f"only {int(ok.sum())} rays of the image could be unprojected; too few to fit {name}")
    target = np.column_stack([a.ravel() for a in np.meshgrid(u, v)])
    if exact_name(cal) == name:
        model, exact = cal.model, True
    else:
        k = cal.model.intrinsics.copy()
        k[4] = 0.0  # OpenCV's models have no skew
        start = OpenCVModel(k, np.zeros(n)) if kind == "opencv" else FisheyeModel(k, np.zeros(n))
        candidates = [_fit(start, rays[ok], target[ok], name),
                      _fit(_radial_start(kind, n, k, rays[ok], target[ok]), rays[ok], target[ok], name)]
        if kind == "opencv" and n > 5:
            # Also a nested start: from zero the rational denominator can wander into a poor
            # minimum, and the 5-coefficient fit padded with zeros is sometimes far better
            # (and sometimes worse): keep whichever fits best.
            five = _fit(OpenCVModel(k, np.zeros(5)), rays[ok], target[ok], name)
            padded = OpenCVModel(five.intrinsics, np.concatenate([five.coefficients, np.zeros(n - 5)]))
            candidates.append(_fit(padded, rays[ok], target[ok], name))
        with np.errstate(all="ignore"):
            cost = [np.nansum((m.project(rays[ok]) - target[ok]) ** 2) for m in candidates]
        model, exact = candidates[int(np.nanargmin(cost))], False
    err = np.full(len(target), np.nan)
    with np.errstate(all="ignore"):
        err[ok] = np.linalg.norm(model.project(rays[ok]) - target[ok], axis=1)
    e = err[ok]
    if not np.all(np.isfinite(e)):
        raise LeanFitError(f"the fitted {name} model projects some sampled rays to non-finite pixels")
    lean = Calibration(model, cal.image_size, name, metrics={"fit_rms_px": float(np.sqrt(np.mean(e * e)))},
                       settings={"fitted_to": cal.method})
    return LeanFit(name, lean, float(np.sqrt(np.mean(e * e))), float(e.max()), float(np.percentile(e, 99)),
                   int(ok.sum()), u, v, err.reshape(len(v), len(u)), exact)


def _radial_start(kind: str, n: int, k: np.ndarray, rays: np.ndarray, target: np.ndarray):
    """The lean model with the calibration's intrinsics and the radial
    coefficients that fit the target pixels by linear least squares (no
    tangential terms): each model's radial law is linear in them once
    multiplied out (the rational one by its denominator). From zero, a
    rational fit of a wide Kannala-Brandt lens was measured stuck at 40 px
    rms; from here, 0.006 px."""
    xn = rays[:, :2] / rays[:, 2:]
    xd = (target - k[2:4]) / k[:2]
    coefficients = np.zeros(n)
    if kind == "fisheye":
        theta = np.arctan2(np.linalg.norm(rays[:, :2], axis=1), rays[:, 2])
        a = theta[:, None] ** (2 * np.arange(1, n + 1) + 1)
        coefficients[:] = np.linalg.lstsq(a, np.linalg.norm(xd, axis=1) - theta, rcond=None)[0]
        return FisheyeModel(k, coefficients)
    r2 = np.sum(xn * xn, axis=1)
    powers = r2[:, None] ** np.arange(1, 4)  # r², r⁴, r⁶
    radial = [0, 1] if n == 4 else [0, 1, 4]  # k1, k2 (, k3) in OpenCV's order
    rows = xn.T.reshape(-1, 1) * np.tile(powers[:, : len(radial)], (2, 1))  # x·(k1 r² + …), both axes stacked
    if n >= 8:  # · 1/(1 + k4 r² + k5 r⁴ + k6 r⁶): move the denominator to the left-hand side
        rows = np.hstack([rows, -xd.T.reshape(-1, 1) * np.tile(powers, (2, 1))])
        radial += [5, 6, 7]
    coefficients[radial] = np.linalg.lstsq(rows, (xd - xn).T.ravel(), rcond=None)[0]
    return OpenCVModel(k, coefficients)


def _fit(model, rays: np.ndarray, target: np.ndarray, name: str):
    """LM with continuation: fit the rays within 30°, then 50°, then all. From
    zero coefficients the full field of a wide lens drags LM into poor local
    minima (the outer rays dominate while the centre is still wrong)."""
    theta = np.degrees(np.arccos(np.clip(rays[:, 2], -1.0, 1.0)))
    for limit in (30.0, 50.0, 90.0):
        use = theta <= limit
        if use.sum() < 30:
            continue
        data = Data(rays[use], target[use], np.zeros(int(use.sum()), dtype=np.int64), 1)
        try:
            model = levenberg_marquardt(model, np.zeros((1, 6)), data,
                                        SolveSettings(max_iterations=300, fix_poses=True)).model
        except FloatingPointError as exc:
            raise LeanFitError(f"fitting {name} failed: {exc}") from None
    return model


def save_error_map(path, fit: LeanFit) -> None:
    """``.npz`` with ``error_px`` (gh, gw), ``u`` (gw,), ``v`` (gh,) and the summary numbers."""
    np.savez_compressed(path, error_px=fit.error_map, u=fit.u, v=fit.v, rms=fit.rms, max=fit.max, p99=fit.p99)
