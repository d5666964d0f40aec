"""The one interface every camera model shares.

A model maps normalised coordinates of its base projection (``camera.py``)
to pixels: ``pixel_of(xn)``. The solver, the metrics, rectification and the
viewer use only this interface, so a new model is one new file.

Parameter Jacobians are reported sparsely, per residual row: ``cols`` (N, 2, c)
are parameter indices and ``vals`` (N, 2, c) the derivatives, row 0 for u and
row 1 for v. Entries may repeat a column with value 0 (padding).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any, ClassVar, Self

import numpy as np
import scipy.sparse as sp
from numba import njit

from . import camera
from .bspline_basis import BSplineField, breaks_of

# Residual rows linear in the parameters and their Jacobian, ``(r, J)``: J (r, n_params).
Prior = tuple[np.ndarray, sp.csr_matrix]


class CameraModel(ABC):
    kind: ClassVar[str]  # the distortion.type it writes
    base: str = "pinhole"
    intrinsics: np.ndarray  # [fx, fy, cx, cy, skew]

    # ---- what each model provides -------------------------------------------
    @property
    @abstractmethod
    def n_params(self) -> int:
        """Number of fitted parameters."""

    @abstractmethod
    def params(self) -> np.ndarray:
        """The fitted parameters (n_params,)."""

    @abstractmethod
    def with_params(self, x: np.ndarray) -> Self:
        """The same model with parameters ``x`` (a new object)."""

    @abstractmethod
    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        """Pixels (N, 2) of normalised coordinates (N, 2); with ``jacobian`` also
        ∂uv/∂xn (N, 2, 2) and the parameter Jacobian ``cols, vals``."""

    def prior(self) -> Prior | None:
        """Extra residual rows linear in the parameters, ``(r, J)``, or None."""
        return None

    def restored(self, settings: dict[str, Any]) -> CameraModel:
        """This model with what its JSON ``distortion`` leaves out but the
        calibration's ``settings`` record (regularisers, gauge, held parts):
        what a covariance needs to be the fit's own. Parametric models need
        nothing."""
        return self

    def free_mask(self) -> np.ndarray | None:
        """(n_params,) bool: the parameters a fit of this model moves (None: all).
        Models whose parameters trade off along a flat valley hold some of
        them (a gauge choice, recorded in their settings)."""
        return None

    @abstractmethod
    def distortion_json(self) -> dict[str, Any]:
        """The ``distortion`` object of formats.md."""

    @classmethod
    @abstractmethod
    def from_json(cls, intrinsics: np.ndarray, distortion: dict[str, Any], base: str) -> Self:
        """The model a calibration's ``intrinsics`` [fx, fy, cx, cy, skew],
        ``distortion`` object and ``base`` describe (formats.md), or a
        FormatError naming the field that is wrong. ``restored`` then adds
        what the calibration's ``settings`` record."""

    def settings_json(self) -> dict[str, Any]:
        """What the fit of this model chose beyond its ``distortion`` object
        (regularisers, gauge, held parts), for the calibration's ``settings``:
        what ``restored`` reads back. Parametric models choose nothing."""
        return {}

    def base_json(self) -> str:
        """The ``base`` the calibration JSON records: the format's base for the
        distortion type, which need not be the one this model computes on
        (Kannala–Brandt is written on the pinhole base, see ``fisheye.py``)."""
        return self.base

    # ---- what a model is made of ------------------------------------------------
    @property
    def bspline_field(self) -> BSplineField | None:
        """The B-spline distortion field this model carries (in ideal pixels
        for ``bspline``, in its core's pixels for ``hybrid``), or None."""
        return None

    def knot_breaks(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The knot grid of the B-spline field: its interval breaks along u and
        along v (domain ends included), or None without a field."""
        field = self.bspline_field
        return None if field is None else (breaks_of(field.knots_u), breaks_of(field.knots_v))

    def exact_parametric(self) -> ParametricModel | None:
        """This model as a parametric one that projects identically, or None:
        what exports to tools that know only OpenCV's and Kannala–Brandt's
        models can write without a fit."""
        return None

    # ---- shared ---------------------------------------------------------------
    def project(self, pc: np.ndarray, jacobian: bool = False):
        """Pixels (N, 2) of camera-frame points (N, 3); with ``jacobian`` also
        ∂uv/∂Pc (N, 2, 3) and the parameter Jacobian ``cols, vals``."""
        if not jacobian:
            return self.pixel_of(camera.normalise(pc, self.base))
        xn, d_xn = camera.normalise(pc, self.base, jacobian=True)
        uv, d_uv, cols, vals = self.pixel_of(xn, jacobian=True)
        return uv, _chained(np.ascontiguousarray(d_uv), d_xn), cols, vals

    def ideal_pixel(self, xn: np.ndarray) -> np.ndarray:
        """``(xn, yn)`` into pixels with the intrinsics alone (no distortion)."""
        fx, fy, cx, cy, s = self.intrinsics
        return np.stack([fx * xn[:, 0] + s * xn[:, 1] + cx, fy * xn[:, 1] + cy], axis=-1)

    def normalised_of_ideal(self, uv: np.ndarray) -> np.ndarray:
        fx, fy, cx, cy, s = self.intrinsics
        y = (uv[:, 1] - cy) / fy
        return np.stack([(uv[:, 0] - cx - s * y) / fx, y], axis=-1)

    def distort(self, ideal_uv: np.ndarray) -> np.ndarray:
        """Ideal pixels (N, 2) (the intrinsics applied to ``xn``) → observed pixels."""
        return self.pixel_of(self.normalised_of_ideal(np.asarray(ideal_uv, dtype=np.float64).reshape(-1, 2)))

    def normalised_of_pixel(self, uv: np.ndarray, tol: float = 1e-9, max_iterations: int = 50) -> np.ndarray:
        """Invert ``pixel_of`` by damped Newton (``refine_preimage``) from
        ``newton_start``, vectorised over points (N, 2) → (N, 2).

        Converges to ``tol`` pixels wherever the model is locally invertible;
        points that do not converge come back as NaN.
        """
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        xn, err = refine_preimage(self, self.newton_start(uv), uv, tol, max_iterations)
        xn[np.linalg.norm(err, axis=-1) > max(tol * 100, 1e-6)] = np.nan
        return xn

    def newton_start(self, uv: np.ndarray) -> np.ndarray:
        """Where Newton starts inverting pixels ``uv`` (N, 2): the undistorted
        guess. Models that add a field to a core start nearer, from the core's
        own inverse."""
        return self.normalised_of_ideal(uv)

    def undistort_points(self, uv: np.ndarray) -> np.ndarray:
        """Observed pixels (N, 2) → ideal pixels (N, 2): the inverse of ``distort``."""
        return self.ideal_pixel(self.normalised_of_pixel(uv))

    def rays(self, uv: np.ndarray) -> np.ndarray:
        """Unit rays (N, 3) in the camera frame of observed pixels (N, 2)."""
        return camera.ray_of(self.normalised_of_pixel(uv), self.base)

    def intrinsics_json(self) -> dict[str, float]:
        fx, fy, cx, cy, s = (float(v) for v in self.intrinsics)
        return {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "skew": s}


def free_parameters(model: CameraModel) -> np.ndarray:
    """(n_params,) bool: the parameters a fit of ``model`` moves (``free_mask``, None: all)."""
    mask = model.free_mask()
    return np.ones(model.n_params, dtype=bool) if mask is None else mask


def fitted_parameter_count(model: CameraModel) -> int:
    """The parameters the fit moved (a hybrid holds its core's coefficients,
    a held field is no parameter): what a table or a choice of models counts."""
    return int(np.sum(free_parameters(model)))


class ParametricModel(CameraModel):
    """A model with parameters ``[fx, fy, cx, cy, coefficients…]`` (OpenCV's and
    Kannala–Brandt's). Its skew is not fitted: 0 in every fit freecal makes, as
    OpenCV has it, and kept where a file read gives another (formats.md puts it
    into every type's pixels: cv2.fisheye's ``alpha`` is skew / fx)."""

    def __init__(self, intrinsics: Any, coefficients: Any):
        self.intrinsics = np.asarray(intrinsics, dtype=np.float64).copy()
        self.coefficients = np.asarray(coefficients, dtype=np.float64).copy()

    @property
    def n_params(self) -> int:
        return 4 + len(self.coefficients)

    def params(self) -> np.ndarray:
        return np.concatenate([self.intrinsics[:4], self.coefficients])

    def with_params(self, x: np.ndarray) -> Self:
        return type(self)(np.append(x[:4], self.intrinsics[4]), x[4:])

    def exact_parametric(self) -> ParametricModel:
        return self

    @abstractmethod
    def distort_normalised(self, xn: np.ndarray, jacobian: bool = False):
        """Distorted normalised coordinates ``xd`` (N, 2); with ``jacobian`` also
        ∂xd/∂xn (N, 2, 2) and ∂xd/∂coefficients (N, 2, ≥ n)."""

    def pixel_of(self, xn: np.ndarray, jacobian: bool = False):
        fx, fy, cx, cy, s = self.intrinsics
        if not jacobian:
            xd = self.distort_normalised(xn)
            u = fx * xd[:, 0] + cx if s == 0 else fx * xd[:, 0] + s * xd[:, 1] + cx
            return np.stack([u, fy * xd[:, 1] + cy], axis=-1)
        xd, d_xd, d_k = self.distort_normalised(xn, jacobian=True)
        return _pixel_rows(np.ascontiguousarray(xd), np.ascontiguousarray(d_xd), np.ascontiguousarray(d_k),
                           len(self.coefficients), fx, fy, cx, cy, s)


@njit(cache=True, nogil=True)
def _chained(d_uv, d_xn):  # pragma: no cover (compiled)
    """∂uv/∂Pc = ∂uv/∂xn (N, 2, 2) · ∂xn/∂Pc (N, 2, 3), point by point (numpy's
    stacked product of small matrices costs more than the arithmetic)."""
    n = len(d_uv)
    out = np.empty((n, 2, 3))
    for i in range(n):
        for r in range(2):
            for c in range(3):
                out[i, r, c] = d_uv[i, r, 0] * d_xn[i, 0, c] + d_uv[i, r, 1] * d_xn[i, 1, c]
    return out


@njit(cache=True, nogil=True)
def _pixel_rows(xd, d_xd, d_k, nk, fx, fy, cx, cy, s):  # pragma: no cover (compiled)
    """``ParametricModel.pixel_of``'s pixels (N, 2), ∂uv/∂xn (N, 2, 2) and
    parameter Jacobian rows: u on fx, cx and the coefficients, v on fy, cy and
    the coefficients (one pass instead of a dozen array copies). The skew s
    (held) adds s·yd to u; the branches keep a skew-free camera's arithmetic as it was."""
    n = len(xd)
    uv = np.empty((n, 2))
    d_uv = np.empty((n, 2, 2))
    cols = np.empty((n, 2, 2 + nk), dtype=np.int64)
    vals = np.empty((n, 2, 2 + nk))
    for i in range(n):
        for r in range(2):
            f = fx if r == 0 else fy
            uv[i, r] = f * xd[i, r] + (cx if r == 0 else cy)
            d_uv[i, r, 0] = f * d_xd[i, r, 0]
            d_uv[i, r, 1] = f * d_xd[i, r, 1]
            cols[i, r, 0], cols[i, r, 1] = r, r + 2  # u: fx, cx; v: fy, cy
            vals[i, r, 0], vals[i, r, 1] = xd[i, r], 1.0
            for k in range(nk):
                cols[i, r, 2 + k] = 4 + k
                vals[i, r, 2 + k] = f * d_k[i, r, k]
        if s != 0.0:
            uv[i, 0] += s * xd[i, 1]
            d_uv[i, 0, 0] += s * d_xd[i, 1, 0]
            d_uv[i, 0, 1] += s * d_xd[i, 1, 1]
            for k in range(nk):
                vals[i, 0, 2 + k] += s * d_k[i, 1, k]
    return uv, d_uv, cols, vals


# Lengths (1, 1/2, 1/4, ...) a Newton step is tried at before its point counts as stuck.
BACKTRACKS = 30
HALF, SHORTER = np.array([0.5]), 0.5 ** np.arange(2.0, BACKTRACKS)


def refine_preimage(model: CameraModel, xn: np.ndarray, uv: np.ndarray, tol: float,
                    max_iterations: int) -> tuple[np.ndarray, np.ndarray]:
    """Damped Newton for ``model.pixel_of(xn) = uv`` from ``xn`` (N, 2),
    vectorised over points: the refined ``xn`` and its pixel error (N, 2).

    Each point backtracks so that its error always shrinks. A point no step
    shrinks is stuck (outside where the model is invertible: a fold, a pole,
    a field far from its data) and stops there: retrying would repeat the
    same step, and such points cost the most evaluations."""
    xn = np.array(xn, dtype=np.float64)
    err = pixel_error(model, xn, uv)
    active = np.flatnonzero(np.linalg.norm(err, axis=-1) > tol)
    # Steps toward pixels the model cannot reach overflow or divide by zero: those points
    # fail by their error (not below the last one), and numpy's warnings would say nothing.
    with np.errstate(all="ignore"):
        for _ in range(max_iterations):
            if not len(active):
                break
            p, d_uv, _, _ = model.pixel_of(xn[active], jacobian=True)
            det = d_uv[:, 0, 0] * d_uv[:, 1, 1] - d_uv[:, 0, 1] * d_uv[:, 1, 0]
            d_uv[~(np.abs(det) > 1e-300)] = np.eye(2)  # a singular point fails by its error, not by an exception
            step = np.linalg.solve(d_uv, -(p - uv[active])[..., None])[..., 0]
            e0 = np.linalg.norm(err[active], axis=-1)
            trial = xn[active] + step
            e1 = pixel_error(model, trial, uv[active])
            worse = ~(np.linalg.norm(e1, axis=-1) < e0)
            # Only the points whose step overshot are evaluated again: at half the step, then,
            # those still worse, at every shorter length at once (a point near a fold needs
            # most of them, and one evaluation of all costs less than as many calls).
            for lengths in (HALF, SHORTER):
                redo = np.flatnonzero(worse)
                if not len(redo):
                    break
                tried = xn[active[redo], None] + lengths[:, None] * step[redo, None]  # (R, L, 2)
                errors = pixel_error(model, tried.reshape(-1, 2), np.repeat(uv[active[redo]], len(lengths), axis=0))
                errors = errors.reshape(len(redo), len(lengths), 2)
                better = np.linalg.norm(errors, axis=-1) < e0[redo, None]
                first = np.argmax(better, axis=1)  # the longest that gains
                ok = better[np.arange(len(redo)), first]
                trial[redo[ok]], e1[redo[ok]] = tried[ok, first[ok]], errors[ok, first[ok]]
                worse[redo[ok]] = False
            moved = active[~worse]
            xn[moved], err[moved] = trial[~worse], e1[~worse]
            active = moved[np.linalg.norm(err[moved], axis=-1) > tol]
    return xn, err


def core_inverse_start(model: CameraModel, core: CameraModel, uv: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """A Newton start for a model that adds a small field f to ``core``'s
    pixel p, uv = p + f(p): the core's inverse of p ≈ uv − f(uv) (``offset``
    = f(uv)), off by about f'·f. Where the core cannot invert that, the
    undistorted guess."""
    with np.errstate(all="ignore"):
        xn = core.normalised_of_pixel(uv - offset, tol=1e-6)
    lost = ~np.all(np.isfinite(xn), axis=1)
    xn[lost] = model.normalised_of_ideal(uv[lost])
    return xn


def pixel_error(model: CameraModel, xn: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """``model.pixel_of(xn) − uv`` (N, 2), infinite where not finite."""
    with np.errstate(all="ignore"):
        e = model.pixel_of(xn) - uv
    return np.where(np.isfinite(e), e, np.inf)


def intrinsics_jacobian(xn: np.ndarray, a: np.ndarray) -> np.ndarray:
    """∂uv/∂[fx, fy, cx, cy, skew] (N, 2, 5) for ``uv = m(K xn)`` with ∂m = ``a`` (N, 2, 2)."""
    n = len(xn)
    # ∂(u, v)_ideal / ∂[fx, fy, cx, cy, s]
    dk = np.zeros((n, 2, 5))
    dk[:, 0, 0] = xn[:, 0]
    dk[:, 0, 2] = 1.0
    dk[:, 0, 4] = xn[:, 1]
    dk[:, 1, 1] = xn[:, 1]
    dk[:, 1, 3] = 1.0
    return a @ dk
