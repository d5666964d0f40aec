"""Cubic B-splines: clamped knot vectors, the basis and its derivative, and the
tensor-product field ``Δ(u, v)`` of ``formats.md`` (``bspline`` distortion).

Everything works on arrays of points: a point touches 4 basis functions per
axis, so a field value is a 16-term sum and the design matrix has 16 non-zeros
per row (the per-point recurrences run compiled, ``bspline_kernel.py``). Outside the knot domain the end polynomial pieces are extended, which
is what ``scipy.interpolate.NdBSpline`` does with ``extrapolate=True``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from ..errors import FormatError
from . import bspline_kernel

DEGREE = 3


def clamped_knots(breaks: np.ndarray) -> np.ndarray:
    """Clamped cubic knot vector from the sorted interval breaks ``[lo, ..., hi]``."""
    breaks = np.asarray(breaks, dtype=np.float64)
    return np.concatenate([np.repeat(breaks[0], DEGREE), breaks, np.repeat(breaks[-1], DEGREE)])


def breaks_of(knots: np.ndarray) -> np.ndarray:
    """Interval breaks (domain ends and interior knots) of a clamped knot vector."""
    return np.asarray(knots)[DEGREE:-DEGREE]


def validate_knots(knots: Any, name: str) -> np.ndarray:
    """A clamped cubic knot vector, or a FormatError naming what is wrong."""
    try:
        t = np.asarray(knots, dtype=np.float64)
    except (TypeError, ValueError):
        raise FormatError(f"{name}: expected a list of numbers") from None
    if t.ndim != 1 or len(t) < 2 * (DEGREE + 1):
        raise FormatError(f"{name}: a clamped cubic knot vector needs at least 8 knots, got {t.size}")
    if not np.all(np.isfinite(t)):
        raise FormatError(f"{name}: knots must be finite numbers")
    if np.any(np.diff(t) < 0):
        raise FormatError(f"{name}: knots must be non-decreasing")
    if not (np.all(t[: DEGREE + 1] == t[0]) and np.all(t[-DEGREE - 1 :] == t[-1])):
        raise FormatError(f"{name}: end knots must be repeated 4 times (clamped cubic)")
    if not t[-1] > t[0]:
        raise FormatError(f"{name}: the domain is empty (first and last knot are equal)")
    if np.any(np.diff(t[DEGREE:-DEGREE]) <= 0):
        raise FormatError(f"{name}: interior knots must be distinct and inside the domain")
    return t


def find_span(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Index ``i`` of the knot interval ``[t[i], t[i+1])`` used for each x.

    Points left or right of the domain use the first or last interval (the
    end polynomial pieces are extended); the right end belongs to the last one.
    """
    n_basis = len(t) - DEGREE - 1
    return np.clip(np.searchsorted(t, x, side="right") - 1, DEGREE, n_basis - 1)


def basis(t: np.ndarray, x: np.ndarray, derivative: bool = False):
    """Cubic basis at ``x`` (N,): ``span`` (N,) and values (N, 4) of
    ``N_{span-3..span}``; with ``derivative`` also their first derivatives (N, 4)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    span = find_span(t, x)
    values, deriv = bspline_kernel.basis_rows(t, x, span)
    return (span, values, deriv) if derivative else (span, values)


@dataclass
class Design:
    """Which 16 control points each point touches and with what weights.

    cols: (N, 16) int flat control indices ``i * n_v + j``.
    w, w_u, w_v: (N, 16) basis products and their u and v derivatives.
    """

    cols: np.ndarray
    w: np.ndarray
    w_u: np.ndarray | None = None
    w_v: np.ndarray | None = None

    def derivative_weights(self) -> tuple[np.ndarray, np.ndarray]:
        """``(w_u, w_v)``, which only a design built with ``derivative`` has."""
        if self.w_u is None or self.w_v is None:
            raise ValueError("this design was built without derivatives (design(..., derivative=True))")
        return self.w_u, self.w_v

    def matrix(self, n_controls: int) -> sp.csr_matrix:
        n = len(self.cols)
        return sp.csr_matrix(
            (self.w.ravel(), self.cols.ravel(), np.arange(0, 16 * n + 1, 16)), shape=(n, n_controls)
        )


class BSplineField:
    """The two-component field ``(Δx, Δy)(u, v)`` of ``formats.md``.

    knots_u, knots_v: clamped cubic knot vectors, in the field's pixel units.
    control: (n_u, n_v, 2) control values in pixels, ``[..., 0]`` for Δx.
    """

    def __init__(self, knots_u, knots_v, control):
        self.knots_u = validate_knots(knots_u, "knots_u")
        self.knots_v = validate_knots(knots_v, "knots_v")
        control = np.asarray(control, dtype=np.float64)
        if control.shape != (self.n_u, self.n_v, 2):
            raise FormatError(
                f"control points: expected shape ({self.n_u}, {self.n_v}) per component for "
                f"{len(self.knots_u)} u-knots and {len(self.knots_v)} v-knots, got {control.shape[:2]}"
            )
        self.control = control

    @classmethod
    def zeros(cls, knots_u, knots_v) -> BSplineField:
        n_u, n_v = len(knots_u) - DEGREE - 1, len(knots_v) - DEGREE - 1
        return cls(knots_u, knots_v, np.zeros((n_u, n_v, 2)))

    @property
    def n_u(self) -> int:
        return len(self.knots_u) - DEGREE - 1

    @property
    def n_v(self) -> int:
        return len(self.knots_v) - DEGREE - 1

    @property
    def n_controls(self) -> int:
        return self.n_u * self.n_v

    @property
    def domain(self) -> tuple[float, float, float, float]:
        """(u_min, u_max, v_min, v_max)."""
        return self.knots_u[DEGREE], self.knots_u[-DEGREE - 1], self.knots_v[DEGREE], self.knots_v[-DEGREE - 1]

    def with_control(self, control: np.ndarray) -> BSplineField:
        """Same knots, new control values (no re-validation: the solver's fast path)."""
        new = object.__new__(BSplineField)
        new.knots_u, new.knots_v = self.knots_u, self.knots_v
        new.control = np.asarray(control, dtype=np.float64).reshape(self.n_u, self.n_v, 2)
        return new

    def design(self, uv: np.ndarray, derivative: bool = False) -> Design:
        """The sparse rows of the field at points ``uv`` (N, 2)."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        u, v = np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1])
        cols, w, w_u, w_v = bspline_kernel.design_rows(self.knots_u, self.knots_v, u, v, find_span(self.knots_u, u),
                                                        find_span(self.knots_v, v), self.n_v, derivative)
        return Design(cols, w, w_u, w_v) if derivative else Design(cols, w)

    def __call__(self, uv: np.ndarray) -> np.ndarray:
        """Offsets ``(Δx, Δy)`` at ``uv`` (..., 2) → (..., 2)."""
        uv = np.asarray(uv, dtype=np.float64)
        d = self.design(uv)
        return self._combine(d.w, d.cols).reshape(uv.shape)

    def evaluate(self, uv: np.ndarray):
        """Offsets (N, 2), their Jacobian (N, 2, 2) ``[[Δx_u, Δx_v], [Δy_u, Δy_v]]``, and the
        design (without derivative weights), in one compiled pass."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        u, v = np.ascontiguousarray(uv[:, 0]), np.ascontiguousarray(uv[:, 1])
        cols, w, offset, jac = bspline_kernel.evaluate_rows(
            self.knots_u, self.knots_v, u, v, find_span(self.knots_u, u), find_span(self.knots_v, v), self.n_v,
            np.ascontiguousarray(self.control.reshape(-1, 2)))
        return offset, jac, Design(cols, w)

    def _combine(self, weights: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Σ_k weights[n, k] · control[cols[n, k]] per component, (N, 2)."""
        return bspline_kernel.combine(weights, cols, np.ascontiguousarray(self.control.reshape(-1, 2)))

    def bending(self) -> sp.csr_matrix:
        """The smoothness operator of this knot grid (``bending_operator``)."""
        return bending_operator(self.knots_u, self.knots_v)

    # ---- JSON --------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        return {
            "type": "bspline",
            "degree": [DEGREE, DEGREE],
            "knots_u": self.knots_u.tolist(),
            "knots_v": self.knots_v.tolist(),
            "control_x": self.control[..., 0].tolist(),
            "control_y": self.control[..., 1].tolist(),
        }

    @classmethod
    def from_json(cls, doc: dict[str, Any], where: str = "distortion") -> BSplineField:
        if doc.get("degree", [DEGREE, DEGREE]) != [DEGREE, DEGREE]:
            raise FormatError(f"{where}.degree: version 1 allows [3, 3] only, got {doc.get('degree')!r}")
        for key in ("knots_u", "knots_v", "control_x", "control_y"):
            if key not in doc:
                raise FormatError(f"{where}.{key}: missing")
        try:
            cx = np.asarray(doc["control_x"], dtype=np.float64)
            cy = np.asarray(doc["control_y"], dtype=np.float64)
        except (TypeError, ValueError):
            raise FormatError(f"{where}.control_x/control_y: expected rectangular lists of numbers") from None
        if cx.shape != cy.shape or cx.ndim != 2:
            raise FormatError(f"{where}.control_x/control_y: expected two 2-D grids of the same shape")
        if not (np.all(np.isfinite(cx)) and np.all(np.isfinite(cy))):
            raise FormatError(f"{where}.control_x/control_y: values must be finite")
        try:
            return cls(doc["knots_u"], doc["knots_v"], np.stack([cx, cy], axis=-1))
        except FormatError as exc:
            raise FormatError(f"{where}.{exc}") from None


def greville(knots: np.ndarray) -> np.ndarray:
    """Greville abscissae: where each control value sits along its axis."""
    return np.convolve(knots[1:-1], np.ones(DEGREE) / DEGREE, mode="valid")


def _divided_second_difference(g: np.ndarray) -> sp.csr_matrix:
    """(n−2, n): second derivative estimates at interior Greville points,
    each row scaled by √(local spacing) so that the sum of squares
    approximates ∫ f''² over the axis."""
    n = len(g)
    if n < 3:
        return sp.csr_matrix((0, n))
    h0, h1 = np.diff(g)[:-1], np.diff(g)[1:]
    rows = np.repeat(np.arange(n - 2), 3)
    cols = (np.arange(n - 2)[:, None] + np.arange(3)).ravel()
    vals = np.column_stack([2 / (h0 * (h0 + h1)), -2 / (h0 * h1), 2 / (h1 * (h0 + h1))])
    vals *= np.sqrt(0.5 * (h0 + h1))[:, None]
    return sp.csr_matrix((vals.ravel(), (rows, cols)), shape=(n - 2, n))


# Bending operators already built, by knot vectors: a knot grid's is asked for by
# every step that touches it (validation, control points, prior rows). Shared,
# so read-only by convention: callers build new matrices from it.
_BENDING: dict[tuple[bytes, bytes], sp.csr_matrix] = {}
_BENDING_KEPT = 64


def bending_operator(knots_u: np.ndarray, knots_v: np.ndarray) -> sp.csr_matrix:
    """[D_r; D_c]: second differences of the control grid along u and along v
    (flattened as ``i * n_v + j``), divided by the Greville spacings and
    weighted by the area each control value stands for, so that ‖[D_r; D_c] P‖²
    approximates the bending energy ∫∫ (Δ_uu² + Δ_vv²) du dv of the field
    whatever the knot spacing. This keeps λ_smooth's meaning fixed when the
    knots change (the paper's plain second differences do not)."""
    key = (np.asarray(knots_u, dtype=np.float64).tobytes(), np.asarray(knots_v, dtype=np.float64).tobytes())
    op = _BENDING.get(key)
    if op is None:
        if len(_BENDING) >= _BENDING_KEPT:
            _BENDING.clear()
        op = _BENDING[key] = _bending_operator(knots_u, knots_v)
    return op


def _bending_operator(knots_u: np.ndarray, knots_v: np.ndarray) -> sp.csr_matrix:
    gu, gv = greville(knots_u), greville(knots_v)
    du, dv = _divided_second_difference(gu), _divided_second_difference(gv)
    # Weight of the other axis: √(half the spacing around each control value).
    def cell(g):
        if len(g) < 2:
            return np.ones(len(g))
        d = np.diff(g)
        return np.sqrt(0.5 * (np.concatenate([[d[0]], d]) + np.concatenate([d, [d[-1]]])))

    along_u = sp.kron(du, sp.diags(cell(gv)))
    along_v = sp.kron(sp.diags(cell(gu)), dv)
    return sp.vstack([along_u, along_v]).tocsr()
