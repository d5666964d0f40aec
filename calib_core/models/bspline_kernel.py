"""The tensor-product cubic B-spline design rows, by a compiled kernel.

Every solver iteration of a field model evaluates its 16 basis products, and
their u and v derivatives, at every corner. In numpy that is a dozen
temporaries per call (2 ms on 7 000 corners, a third of a hybrid model's
projection); one pass per point here takes a tenth of that. ``bspline.py``
wraps these kernels; its tests check them against scipy's B-splines.
"""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _cubic(t, x, s):  # pragma: no cover (compiled)
    """The cubic basis N_{s-3..s} at ``x`` on knot interval ``s`` (The NURBS Book
    A2.2, unrolled into scalars: array scratch per point costs more than the
    arithmetic) and its first derivative from the quadratic basis,
    N'_{k,3} = 3 (N_{k,2} / (t[k+3] − t[k]) − N_{k+1,2} / (t[k+4] − t[k+1]))."""
    l1, l2, l3 = x - t[s], x - t[s - 1], x - t[s - 2]
    r1, r2, r3 = t[s + 1] - x, t[s + 2] - x, t[s + 3] - x
    # Each denominator r_i + l_j is a knot difference: taken from the knots, it
    # stays exact for points far outside the domain, where the sum cancels.
    # degree 1
    temp = 1.0 / (t[s + 1] - t[s])
    a0, a1 = r1 * temp, l1 * temp
    # degree 2: N_{s-2..s, 2}
    temp = a0 / (t[s + 1] - t[s - 1])
    q0, saved = r1 * temp, l2 * temp
    temp = a1 / (t[s + 2] - t[s])
    q1, q2 = saved + r2 * temp, l1 * temp
    # degree 3
    temp = q0 / (t[s + 1] - t[s - 2])
    n0, saved = r1 * temp, l3 * temp
    temp = q1 / (t[s + 2] - t[s - 1])
    n1, saved = saved + r2 * temp, l2 * temp
    temp = q2 / (t[s + 3] - t[s])
    n2, n3 = saved + r3 * temp, l1 * temp
    # Knot spans of a clamped vector with distinct breaks are never empty.
    d1 = 3.0 * q0 / (t[s + 1] - t[s - 2])
    d2 = 3.0 * q1 / (t[s + 2] - t[s - 1])
    d3 = 3.0 * q2 / (t[s + 3] - t[s])
    return n0, n1, n2, n3, -d1, d1 - d2, d2 - d3, d3


@njit(cache=True, nogil=True, error_model="numpy")  # inf/nan as numpy gives, not an exception
def basis_rows(t, x, span):  # pragma: no cover (compiled)
    """(values, deriv), (N, 4) each: the cubic basis N_{span-3..span} at each x
    and its first derivative."""
    n = len(x)
    values = np.empty((n, 4))
    deriv = np.empty((n, 4))
    for p in range(n):
        b = _cubic(t, x[p], span[p])
        for k in range(4):
            values[p, k] = b[k]
            deriv[p, k] = b[4 + k]
    return values, deriv


@njit(cache=True, nogil=True, error_model="numpy")  # inf/nan as numpy gives, not an exception
def design_rows(tu, tv, u, v, span_u, span_v, n_v, derivative):  # pragma: no cover (compiled)
    """(cols, w, w_u, w_v), each (N, 16): flat control indices ``i * n_v + j``,
    basis products and (with ``derivative``; else empty) their u and v derivatives."""
    n = len(u)
    cols = np.empty((n, 16), dtype=np.int64)
    w = np.empty((n, 16))
    w_u = np.empty((n if derivative else 0, 16))
    w_v = np.empty((n if derivative else 0, 16))
    for p in range(n):
        bu = _cubic(tu, u[p], span_u[p])
        bv = _cubic(tv, v[p], span_v[p])
        iu0, iv0 = span_u[p] - 3, span_v[p] - 3
        for a in range(4):
            for b in range(4):
                k = 4 * a + b
                cols[p, k] = (iu0 + a) * n_v + iv0 + b
                w[p, k] = bu[a] * bv[b]
                if derivative:
                    w_u[p, k] = bu[4 + a] * bv[b]
                    w_v[p, k] = bu[a] * bv[4 + b]
    return cols, w, w_u, w_v


@njit(cache=True, nogil=True, error_model="numpy")  # inf/nan as numpy gives, not an exception
def combine(weights, cols, control):  # pragma: no cover (compiled)
    """Σ_k weights[n, k] · control[cols[n, k]] per component: (N, 2) from control (n_controls, 2)."""
    n = len(cols)
    out = np.zeros((n, 2))
    for p in range(n):
        x = 0.0
        y = 0.0
        for k in range(16):
            c = cols[p, k]
            x += weights[p, k] * control[c, 0]
            y += weights[p, k] * control[c, 1]
        out[p, 0] = x
        out[p, 1] = y
    return out


@njit(cache=True, nogil=True, error_model="numpy")  # inf/nan as numpy gives, not an exception
def evaluate_rows(tu, tv, u, v, span_u, span_v, n_v, control):  # pragma: no cover (compiled)
    """(cols, w, offset, jac): ``design_rows`` (no derivative weights kept) and,
    in the same pass, what ``combine`` gives of the values and of the u and v
    derivative weights, summed in the same order: offsets (N, 2) and their
    Jacobian (N, 2, 2) ``[[Δx_u, Δx_v], [Δy_u, Δy_v]]``."""
    n = len(u)
    cols = np.empty((n, 16), dtype=np.int64)
    w = np.empty((n, 16))
    offset = np.empty((n, 2))
    jac = np.empty((n, 2, 2))
    for p in range(n):
        bu = _cubic(tu, u[p], span_u[p])
        bv = _cubic(tv, v[p], span_v[p])
        iu0, iv0 = span_u[p] - 3, span_v[p] - 3
        x = y = xu = yu = xv = yv = 0.0
        for a in range(4):
            for b in range(4):
                k = 4 * a + b
                c = (iu0 + a) * n_v + iv0 + b
                cols[p, k] = c
                wk = bu[a] * bv[b]
                wu = bu[4 + a] * bv[b]
                wv = bu[a] * bv[4 + b]
                w[p, k] = wk
                x += wk * control[c, 0]
                y += wk * control[c, 1]
                xu += wu * control[c, 0]
                yu += wu * control[c, 1]
                xv += wv * control[c, 0]
                yv += wv * control[c, 1]
        offset[p, 0] = x
        offset[p, 1] = y
        jac[p, 0, 0] = xu
        jac[p, 1, 0] = yu
        jac[p, 0, 1] = xv
        jac[p, 1, 1] = yv
    return cols, w, offset, jac


@njit(cache=True, nogil=True)
def hybrid_rows(cols, vals, a, design_cols, design_w, first, n_controls):  # pragma: no cover (compiled)
    """A field over a core: the parameter Jacobian's columns and values (N, 2,
    2c + 16) from the core's (``cols``, ``vals``: (N, 2, c)) and the field's
    design. Each row mixes both of the core's rows through ∂uv/∂p = ``a``
    (N, 2, 2): the core's row-0 entries times a[:, :, 0], then its row-1
    entries times a[:, :, 1], then the 16 controls of the row's component
    (columns from ``first``)."""
    n, _, c = cols.shape
    out_cols = np.empty((n, 2, 2 * c + 16), dtype=np.int64)
    out_vals = np.empty((n, 2, 2 * c + 16))
    for p in range(n):
        for r in range(2):
            for j in range(c):
                out_cols[p, r, j] = cols[p, 0, j]
                out_cols[p, r, c + j] = cols[p, 1, j]
                out_vals[p, r, j] = a[p, r, 0] * vals[p, 0, j]
                out_vals[p, r, c + j] = a[p, r, 1] * vals[p, 1, j]
            offset = first + r * n_controls
            for k in range(16):
                out_cols[p, r, 2 * c + k] = offset + design_cols[p, k]
                out_vals[p, r, 2 * c + k] = design_w[p, k]
    return out_cols, out_vals
