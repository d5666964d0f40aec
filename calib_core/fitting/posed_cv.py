"""Grouped cross-validation of a field over a fitted core, each view's pose refit.

``smoothing.cv_curve`` scores a field at the core's camera and poses, each view's
pose held. Where the core's error is not a function of the pixel alone, that
misjudges it: a lens whose distortion no parametric model represents (an
elliptic one, say) makes the core's fit tilt each view's pose to absorb part of
the error, a different part in each view, and what is left, view by view, is not
one field. Held there, no field predicts the views left out better; fitted with
the poses, the paper's field predicted them 4x better (docs/model-choice.md,
"Poses that hide a field").

Here each view's six pose parameters are eliminated from its rows, linearised at
the core's fit: the field is fitted with the other views' poses free, and the
view left out is predicted with its own pose refit, as the joint fit and
``freecal evaluate`` treat them. A pose moves a corner's x and y together, so the
two components are one problem (where ``cv_curve`` solves them apart).
"""
from __future__ import annotations

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from .cholesky import cholesky_solve
from .crossval import pose_basis
from .gram import gram
from .smoothing import CVCurve, gauge_null_space, walk_lambdas


def posed_cv_curve(b: sp.csr_matrix, weights: np.ndarray, bend: sp.csr_matrix, gauge: sp.csr_matrix,
                   response: np.ndarray, pose_jacobian: sp.csr_matrix, view_index: np.ndarray, ridge: float,
                   groups: np.ndarray, lambdas: np.ndarray) -> tuple[CVCurve, np.ndarray]:
    """(curve, (G,) no field's left-out SSE per group): ``cv_curve``'s question
    (same arguments) with each view's pose refit; the curve's ``dof`` is not
    computed (NaN). λ is walked downhill from every fourth value: started from
    the held question's λ, the walk stopped in the wrong one of two minima
    (an elliptic lens: a field at λ = 3 000 scored worse than none, at λ = 30 6 % better).

    pose_jacobian: (2N, 6V) the corners' pixels' derivatives along each view's
    pose, rows interleaved x, y as in the solver's Jacobian. Each view's rows are
    projected off its pose's columns (W-orthogonally), which turns the joint
    problem into a field-only one; leaving a group out removes its projected
    rows (one Cholesky solve a group and λ). No field's error is the response
    projected the same way: each view's pose refit to the core's corners."""
    b = sp.csr_matrix(b)
    n = b.shape[1]
    r = (bend.T @ bend).toarray()
    z = [gauge_null_space(gauge[c::2, c * n : (c + 1) * n].toarray(), r)[0] for c in range(2)]
    split = z[0].shape[1]
    smooth = scipy.linalg.block_diag(z[0].T @ r @ z[0], z[1].T @ r @ z[1])
    counts = np.bincount(groups)
    # Each row's six pose derivatives (its view's columns), rows interleaved x, y.
    coo = sp.coo_matrix(pose_jacobian)
    pose = np.zeros((coo.shape[0], 6))
    pose[coo.row, coo.col - 6 * np.repeat(view_index, 2)[coo.row]] = coo.data
    # Per group: the normal equations' share and rhs, and its rows' design and
    # response projected off their views' poses (the left-out prediction's).
    # The points sorted by group, so that each group's rows are one slice.
    order = np.argsort(groups, kind="stable")
    bounds = np.concatenate([[0], np.cumsum(counts)])
    b = b[order]
    design = [np.asarray(b @ z[c]) for c in range(2)]  # (N, k_c) each component's rows in the gauge's null space
    normal = np.zeros((len(counts), len(smooth), len(smooth)))
    rhs = np.zeros((len(counts), len(smooth)))
    designs, responses = [], []
    for g in range(len(counts)):
        span = slice(bounds[g], bounds[g + 1])
        points = order[span]
        normal[g] = scipy.linalg.block_diag(*(z[c].T @ gram(b[span], weights[points, c]) @ z[c] for c in range(2)))
        x = np.zeros((2 * len(points), len(smooth)))  # the group's rows, interleaved x, y
        x[0::2, :split], x[1::2, split:] = design[0][span], design[1][span]
        d, w = response[points].ravel(), weights[points].ravel()
        rhs[g] = x.T @ (w * d)
        local = np.repeat(view_index[points], 2)
        interleaved = (2 * points[:, None] + [0, 1]).ravel()  # the group's rows of the Jacobian
        for v in np.unique(local):
            rows = np.flatnonzero(local == v)
            m = pose_basis(pose[interleaved[rows]], w[rows])
            xt_w_m = x[rows].T @ (w[rows, None] * m)
            normal[g] -= xt_w_m @ xt_w_m.T
            rhs[g] -= xt_w_m @ (m.T @ (w[rows] * d[rows]))
            x[rows] -= m @ xt_w_m.T
            d[rows] -= m @ (m.T @ (w[rows] * d[rows]))
        designs.append(x)
        responses.append(d)
    total, total_rhs = normal.sum(axis=0), rhs.sum(axis=0)
    total[np.diag_indices(len(total))] += max(ridge, 1e-9)
    no_field = np.array([float(d @ d) for d in responses])

    def evaluate(lams: np.ndarray):
        sse = np.zeros((len(counts), len(lams)))
        for g in range(len(counts)):
            controls = np.column_stack([_spd_solve(total + lam * smooth - normal[g], total_rhs - rhs[g]) for lam in lams])
            sse[g] = np.sum((responses[g][:, None] - designs[g] @ controls) ** 2, axis=0)
        return sse, np.full(len(lams), np.nan)

    return walk_lambdas(evaluate, lambdas, counts, refine=True), no_field


def _spd_solve(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b by Cholesky; by least squares where rounding leaves ``a`` indefinite."""
    x = cholesky_solve(a, b)
    return np.linalg.lstsq(a, b, rcond=None)[0] if x is None else x
