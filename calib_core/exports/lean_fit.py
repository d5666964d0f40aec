"""Lean-model fits: the closest OpenCV (4/5/8/12/14 coefficients) or
Kannala–Brandt (4) model to any calibration, so it can be exported to tools
that know only those, with a number and a map that say what is lost.

Rays are sampled on a grid of photo pixels wherever the calibration can
unproject them (``Calibration.rays``, principal branch) and, for the pinhole
OpenCV models, less than ``MAX_ANGLE_DEG`` off axis; the lean model is fitted
to reproduce those pixels by our Levenberg–Marquardt (``solve.py``) with the
pose held at identity: a direct least-squares fit of the projection. The fit
error is ``|lean(ray) − calibration(ray)|`` in pixels at each sample, reported
twice (``evaluate``): over the covered region the fit was made on, and over
the whole image, wherever the calibration can unproject and the exported
model can represent the ray (``REACH_DEG``: a pinhole-normalised model stops
short of 90°). Any exported model (mrcal's splined one too) is scored so.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Protocol

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
# How far off axis each exported model can see a ray at all: OpenCV's models
# divide by z (85°, as the fit), Kannala–Brandt as OpenCV/COLMAP/Kalibr compute
# it takes θ = atan(r) of x/z (in front of the camera only), mrcal's splined
# stereographic model reaches almost all the way round.
REACH_DEG = {"opencv": MAX_ANGLE_DEG, "fisheye": 89.9, "splined": 179.0}


class Projector(Protocol):
    """What an exported model must do: camera-frame rays (N, 3) → pixels (N, 2)."""

    def project(self, rays: np.ndarray) -> np.ndarray: ...


class LeanFitError(CalibError):
    """The lean model cannot be fitted to this calibration."""


@dataclass(frozen=True)
class FitError:
    """``|export(ray) − calibration(ray)|`` (px) over ``n`` samples: rms, 99th percentile, max."""

    rms: float
    p99: float
    max: float
    n: int

    @classmethod
    def of(cls, err: np.ndarray) -> FitError:
        e = np.asarray(err, dtype=np.float64)
        if not len(e):
            return cls(0.0, 0.0, 0.0, 0)
        return cls(float(np.sqrt(np.mean(e * e))), float(np.percentile(e, 99)), float(e.max()), int(len(e)))

    def to_json(self) -> dict[str, Any]:
        return {"rms_px": self.rms, "p99_px": self.p99, "max_px": self.max, "n_samples": self.n}


@dataclass
class LeanFit:
    """A model fitted to a calibration for export, and how far it strays.

    ``error_map`` (grid_h, grid_w): pixel error at the grid's photo pixels
    ``u`` (grid_w,), ``v`` (grid_h,), over the whole image; NaN where the
    calibration cannot unproject or the model cannot represent the ray.
    ``covered_mask`` (grid_h, grid_w): the samples of the covered region (the fit's)."""

    name: str
    model: Any  # a Projector: a ParametricModel (OpenCV, Kannala–Brandt) or splined.SplinedStereographic
    image_size: tuple[int, int]
    fitted_to: str  # the calibration's method
    covered: FitError  # over the covered region (the corners' hull), where the fit was made
    image: FitError  # over the whole image, where the model can represent the ray
    n_beyond: int  # image samples the calibration sees but the model cannot represent (past its reach)
    u: np.ndarray
    v: np.ndarray
    error_map: np.ndarray
    covered_mask: np.ndarray
    exact: bool = False  # the calibration already was this model: nothing fitted
    region: np.ndarray | None = None  # (M, 2) the covered region's polygon in pixels, if known
    reach_deg: float = 179.0  # how far off axis the model represents rays (``evaluate``'s)
    # A fitted rational model whose denominator vanishes inside the image, outside the covered
    # region: the normalised radius of that ring (rays there project to infinity), else None.
    pole_radius: float | None = None

    # The covered region's numbers are the headline (what a user of the export can rely on).
    @property
    def rms(self) -> float:
        return self.covered.rms

    @property
    def max(self) -> float:
        return self.covered.max

    @property
    def p99(self) -> float:
        return self.covered.p99

    @property
    def n_samples(self) -> int:
        return self.covered.n

    @property
    def parametric(self) -> ParametricModel:
        """The model as OpenCV's or Kannala–Brandt's: what the OpenCV-family exporters write."""
        if not isinstance(self.model, ParametricModel):
            raise TypeError(f"{self.name} is not a parametric model")
        return self.model

    @property
    def calibration(self) -> Calibration:
        """The parametric model in a Calibration (no views, and no fit of its own: its
        error against the source is this LeanFit's ``covered`` and ``image``)."""
        return Calibration(self.parametric, self.image_size, self.name, settings={"fitted_to": self.fitted_to})

    def summary(self) -> dict[str, Any]:
        return {"model": self.name, "exact": self.exact, "fitted_to": self.fitted_to,
                "covered": self.covered.to_json(), "image": self.image.to_json(), "n_beyond_reach": self.n_beyond,
                "pole_radius": self.pole_radius,
                # the covered region's, under the names earlier versions wrote
                "fit_rms_px": self.rms, "fit_max_px": self.max, "fit_p99_px": self.p99, "n_samples": self.n_samples}


def parametric_part(cal: Calibration) -> Calibration | None:
    """The calibration as a parametric one, exactly, or None: itself if its model
    is ``opencv``/``fisheye``, its core if it is a hybrid whose field is held at
    zero (the B-spline method's choice on a lens a textbook model fits)."""
    parametric = cal.model.exact_parametric()
    if parametric is None:
        return None
    return cal if parametric is cal.model else dataclasses.replace(cal, model=parametric)


def exact_name(cal: Calibration) -> str | None:
    """The lean-model name ``cal`` already is (``opencv5`` …, ``kb4``), or None: also for a
    camera with skew (read from a file), which the consumers' OpenCV models have not."""
    m = cal.model
    if isinstance(m, (OpenCVModel, FisheyeModel)) and m.intrinsics[4] != 0:
        return None
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
    ok = reachable(rays, max_angle_deg)
    if covered is not None:
        ok &= inside_hull(np.column_stack([uu.ravel(), vv.ravel()]), covered)
    return u, v, rays, ok


def reachable(rays: np.ndarray, max_angle_deg: float) -> np.ndarray:
    """(N,) rays that exist (finite) and lie less than ``max_angle_deg`` off axis."""
    with np.errstate(invalid="ignore"):
        return np.all(np.isfinite(rays), axis=1) & (rays[:, 2] > np.cos(np.radians(max_angle_deg)))


def inside_hull(pixels: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """(N,) pixels inside the convex hull of the ``covered`` pixels (M, 2)."""
    from scipy.spatial import Delaunay

    pts = np.asarray(covered, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 3:
        raise LeanFitError("covered: need at least 3 observed pixels to bound the fit region")
    return Delaunay(pts).find_simplex(pixels) >= 0


def covered_pixels(cal: Calibration, covered: np.ndarray | None) -> np.ndarray | None:
    """The pixels bounding the covered region: ``covered`` if given, else the hull the
    calibration recorded (``diagnostics.coverage_hull``), else None (the whole image)."""
    hull = cal.diagnostics.coverage_hull or []
    if covered is None and len(hull) >= 3:
        covered = np.asarray(hull, dtype=np.float64)
    return None if covered is None else np.asarray(covered, dtype=np.float64).reshape(-1, 2)


def hull_polygon(covered: np.ndarray | None) -> np.ndarray | None:
    """The convex hull of ``covered`` pixels as a polygon (M, 2), counter-clockwise in
    the image (y down), not closed; None without pixels."""
    from scipy.spatial import ConvexHull, QhullError

    if covered is None or len(covered) < 3:
        return None
    try:
        return covered[ConvexHull(covered).vertices]
    except (QhullError, ValueError):
        return None


def evaluate(model: Projector, cal: Calibration, name: str, reach_deg: float, exact: bool = False,
             grid: tuple[int, int] = GRID, covered: np.ndarray | None = None) -> LeanFit:
    """Score an exported ``model`` against ``cal`` on the photo grid: over the covered region
    (the samples ``fit_lean`` fits, within ``MAX_ANGLE_DEG``) and over the whole image
    (every ray the model reaches, ``reach_deg``)."""
    covered = covered_pixels(cal, covered)
    u, v, rays, fitted = sample_grid(cal, grid, covered=covered)
    target = np.column_stack([a.ravel() for a in np.meshgrid(u, v)])
    known = reachable(rays, 180.0)
    reach = reachable(rays, reach_deg)
    err = np.full(len(target), np.nan)
    with np.errstate(all="ignore"):
        err[reach] = 0.0 if exact else np.linalg.norm(model.project(rays[reach]) - target[reach], axis=1)
    if not np.all(np.isfinite(err[fitted])):
        raise LeanFitError(f"the fitted {name} model projects some rays of the covered region to non-finite pixels")
    image = np.isfinite(err)
    w, h = cal.image_size
    return LeanFit(name, model, (int(w), int(h)), cal.method, FitError.of(err[fitted]), FitError.of(err[image]),
                   int(np.sum(known & ~image)), u, v, err.reshape(len(v), len(u)), fitted.reshape(len(v), len(u)),
                   exact, hull_polygon(covered), reach_deg)


def error_at(fit: LeanFit, cal: Calibration, pixels: np.ndarray) -> np.ndarray:
    """(N,) the export's error (px) at photo ``pixels`` (N, 2); NaN where the
    calibration has no ray or the model cannot represent it."""
    pixels = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    rays = cal.rays(pixels)
    ok = reachable(rays, fit.reach_deg)
    err = np.full(len(pixels), np.nan)
    with np.errstate(all="ignore"):
        err[ok] = 0.0 if fit.exact else np.linalg.norm(fit.model.project(rays[ok]) - pixels[ok], axis=1)
    return err


def fit_lean(cal: Calibration, name: str, grid: tuple[int, int] = GRID, covered: np.ndarray | None = None) -> LeanFit:
    """Fit the lean model ``name`` (a key of ``LEAN_MODELS``) to ``cal``'s projection over
    the convex hull of ``covered`` (M, 2) pixels (e.g. the observed corners: where
    the calibration has data); by default the hull the calibration recorded
    (``diagnostics.coverage_hull``), or the whole image if it has none."""
    if name not in LEAN_MODELS:
        raise SettingsError(f"lean model: expected one of {sorted(LEAN_MODELS)}, got {name!r}")
    kind, n = LEAN_MODELS[name]
    covered = covered_pixels(cal, covered)
    u, v, rays, ok = sample_grid(cal, grid, covered=covered)
    if ok.sum() < 50:
        raise LeanFitError(f"only {int(ok.sum())} rays of the image could be unprojected; too few to fit {name}")
    target = np.column_stack([a.ravel() for a in np.meshgrid(u, v)])
    if exact_name(cal) == name:
        return evaluate(cal.model, cal, name, REACH_DEG[kind], True, grid, covered)
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
    # A rational denominator that vanishes on a ring throws the rays near it to infinity, and a grid
    # of samples steps over a thin ring. A fit with such a ring in the covered region is no
    # candidate; one with it only outside is taken when no fit is free of it, and says so.
    def r2_of(mask: np.ndarray) -> float:
        return float(np.max(np.sum((rays[mask, :2] / rays[mask, 2:]) ** 2, axis=1), initial=0.0))

    image_r2, covered_r2 = r2_of(reachable(rays, REACH_DEG[kind])), r2_of(ok)
    poles = [pole_radius(m, image_r2) if kind == "opencv" else None for m in candidates]
    usable = [k for k, p in enumerate(poles) if p is None] or [
        k for k, p in enumerate(poles) if p is not None and p * p > covered_r2]
    if not usable:
        r = min(p for p in poles if p is not None)
        raise LeanFitError(f"every fit of {name} divides by zero inside the corners' region (its rational denominator "
                           f"1 + k4·r² + k5·r⁴ + k6·r⁶ vanishes at r = {r:.3f}, a ring round the principal point): "
                           "export as opencv5 or kb4")
    with np.errstate(all="ignore"):
        cost = [np.nansum((candidates[k].project(rays[ok]) - target[ok]) ** 2) for k in usable]
    best = usable[int(np.nanargmin(cost))]
    fit = evaluate(candidates[best], cal, name, REACH_DEG[kind], False, grid, covered)
    return dataclasses.replace(fit, pole_radius=poles[best])


def pole_radius(model: OpenCVModel, r2_max: float) -> float | None:
    """The smallest normalised radius r (r² ≤ ``r2_max``) where an OpenCV model's rational
    denominator 1 + k4 r² + k5 r⁴ + k6 r⁶ vanishes; None where it has no such root (or no
    denominator: fewer than 8 coefficients)."""
    if len(model.coefficients) < 8:
        return None
    k4, k5, k6 = (float(c) for c in model.coefficients[5:8])
    roots = np.roots(np.trim_zeros(np.array([k6, k5, k4, 1.0]), "f"))
    real = roots[np.abs(roots.imag) <= 1e-9 * np.maximum(np.abs(roots), 1.0)].real
    inside = real[(real > 0) & (real <= r2_max)]
    return float(np.sqrt(inside.min())) if len(inside) else None


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
    """``.npz`` with ``error_px`` (gh, gw) over the whole image (NaN where the model has
    no ray), ``covered`` (gh, gw) the covered region's samples, ``u`` (gw,), ``v`` (gh,)
    and the summary numbers: ``rms``, ``max``, ``p99`` (covered region), ``image_rms``,
    ``image_max``, ``image_p99`` (whole image)."""
    np.savez_compressed(path, error_px=fit.error_map, covered=fit.covered_mask, u=fit.u, v=fit.v,
                        rms=fit.rms, max=fit.max, p99=fit.p99,
                        image_rms=fit.image.rms, image_max=fit.image.max, image_p99=fit.image.p99)
