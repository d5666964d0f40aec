"""Choosing the smoothing weight (and knot count) by how well the field
predicts views left out of its fit: grouped cross-validation of the
control-point problem, in closed form.

At fixed intrinsics and poses the field is linear in its control values:
``min ‖W^½ (B P − d)‖² + λ ‖D P‖²`` subject to the gauge ``G P = 0`` (plus a
tiny ridge), solved by ``A P = BᵀW d`` with ``A = S + λ DᵀD``, ``S = BᵀWB``
in the gauge's null space.
With the generalised eigenvectors ``DᵀD v = μ S v`` (``VᵀSV = I``) the
solution for every λ is diagonal: ``P(λ) = V diag(1 / (1 + λ μ)) Vᵀ BᵀW d``.

Leaving out one group g of rows (one view's corners) changes A by
``C_g = B_gᵀ W_g B_g``, and the left-out rows' residuals follow from the full
solution's without a refit: ``e_g = r_g + B_g (A − C_g)⁻¹ B_gᵀ W_g r_g``
(Sherman–Morrison–Woodbury; the same as ``(I − H_gg)⁻¹ r_g`` with H the hat
matrix). In the eigenbasis ``A − C_g`` is ``diag(1 + λμ) − M_g`` with
``M_g = (B_g V)ᵀ W_g (B_g V)`` formed once per group, so every (group, λ)
costs one small Cholesky factorisation.

GCV (Craven & Wahba) scores prediction at the corners already seen; a view's
corners share its board's warp, its pose error and its detector bias, and
they cover only part of the image, so GCV favoured fine grids that predicted
new views 10–40 % worse (freeform lenses, 10 views). Grouping by view asks
the question a user asks: how well does the field predict a view it has not
seen.
"""
from __future__ import annotations

import functools
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from .cholesky import cholesky_solve
from .gram import gram

# Up to 1e6: over a parametric core that already fits the lens the field is
# wanted nearly flat; capped at 1e3 it was held at the edge.
LAMBDA_GRID = np.logspace(-3, 6, 19)
# At most this many groups: views beyond are pooled into interleaved folds.
MAX_GROUPS = 10


@dataclass
class CVCurve:
    """Leave-one-group-out prediction errors of the field for each λ."""

    lambdas: np.ndarray  # (L,)
    group_sse: np.ndarray  # (G, L) sum of squared left-out residuals, both components, px²
    counts: np.ndarray  # (G,) corners per group
    dof: np.ndarray  # (L,) effective number of control parameters (both components)

    @property
    def score(self) -> np.ndarray:
        """(L,) mean squared left-out residual per corner, both axes summed (px²)."""
        return self.group_sse.sum(axis=0) / self.counts.sum()

    @property
    def best(self) -> int:
        return int(np.argmin(self.score))


def groups_of(view_index: np.ndarray, max_groups: int = MAX_GROUPS) -> np.ndarray:
    """(N,) group of each sample: its view, or with more views than
    ``max_groups`` its interleaved fold of views (view k in fold k mod G)."""
    views, dense = np.unique(view_index, return_inverse=True)
    return dense % max_groups if len(views) > max_groups else dense


def cv_curve(b: sp.csr_matrix, weights: np.ndarray, bend: sp.csr_matrix, gauge: sp.csr_matrix,
             response: np.ndarray, ridge: float, groups: np.ndarray, lambdas: np.ndarray = LAMBDA_GRID,
             refine: bool = False, start: float | None = None) -> CVCurve:
    """Grouped cross-validation over ``lambdas`` for the two field components.

    b: (N, n) design; weights: (N, 2) per-component sample weights (mean 1);
    bend: (m, n) smoothness operator; gauge: (6, 2n) gauge rows, x rows first
    then y, interleaved as in ``BSplineModel.gauge_rows``, held exactly;
    response: (N, 2) observed offsets; ridge: λ_reg; groups: (N,) ints 0..G−1,
    the rows left out together. The left-out residuals are scored unweighted:
    the weights shape the fit, a user's error is in pixels.

    ``refine``: walk the grid downhill instead of scoring all of it (the
    score is smooth in log λ, with one minimum): from ``start``'s nearest
    λ and its neighbours (a neighbouring knot grid's choice), else from
    every fourth λ, on to each lower neighbour until both neighbours of the
    lowest are scored. The same choice as the whole grid for a sixth to a
    third of its scores."""
    lambdas = np.asarray(lambdas, dtype=float)
    b = sp.csr_matrix(b)
    r = (bend.T @ bend).toarray()
    order = np.argsort(groups, kind="stable")
    counts = np.bincount(groups)
    n = b.shape[1]
    parts = []
    basis = None
    for c in range(2):
        g = gauge[c::2, c * n : (c + 1) * n].toarray()
        if basis is None or not np.array_equal(g, basis[0]):  # both components' gauge rows are usually the same
            basis = (g, *gauge_null_space(g, r))
        parts.append(_Component(b, weights[:, c], basis[1], basis[2], response[:, c], ridge, order, counts))

    # The two components are independent problems: one per core.
    def evaluate(lams: np.ndarray):
        with ThreadPoolExecutor(max_workers=2) as pool:
            (sx, dx), (sy, dy) = pool.map(lambda part: part.scores(lams), parts)
        return sx + sy, dx + dy

    return walk_lambdas(evaluate, lambdas, counts, refine, start)


def walk_lambdas(evaluate, lambdas: np.ndarray, counts: np.ndarray, refine: bool = False,
                 start: float | None = None) -> CVCurve:
    """The curve of ``evaluate(λs) -> ((G, L) left-out SSE, (L,) dof)`` over
    ``lambdas``: all of them, or with ``refine`` walked downhill (``cv_curve``)."""
    lambdas = np.asarray(lambdas, dtype=float)
    if not refine or len(lambdas) < 5:
        sse, dof = evaluate(lambdas)
        return CVCurve(lambdas, sse, counts.astype(float), dof)
    scored: dict[int, tuple[np.ndarray, float]] = {}  # grid index → (per-group SSE, dof)

    def score(indices) -> None:
        new = sorted({int(k) for k in indices if 0 <= k < len(lambdas)} - scored.keys())
        if new:
            sse, dof = evaluate(lambdas[new])
            scored.update({k: (sse[:, j], float(dof[j])) for j, k in enumerate(new)})

    if start is None:
        score(range(0, len(lambdas), 4))
    else:
        first = int(np.argmin(np.abs(np.log(lambdas) - np.log(start))))
        score((first - 1, first, first + 1))
    while True:
        best = min(scored, key=lambda k: float(scored[k][0].sum()))
        unscored = [k for k in (best - 1, best + 1) if 0 <= k < len(lambdas) and k not in scored]
        if not unscored:
            break
        score(unscored)
    idx = np.array(sorted(scored))
    return CVCurve(lambdas[idx], np.column_stack([scored[k][0] for k in idx]), counts.astype(float),
                   np.array([scored[k][1] for k in idx]))


def gauge_null_space(g: np.ndarray, r: np.ndarray):
    """(Z, ZᵀRZ): an orthonormal basis of the gauge rows' null space and the
    smoothness operator R there. The gauge rows hold exactly: the controls
    live in that null space. As heavily weighted rows instead they made S so
    ill-conditioned that the left-out residuals lost 8 digits."""
    z = np.linalg.qr(g.T, mode="complete")[0][:, np.linalg.matrix_rank(g):]
    return z, z.T @ r @ z


class _Component:
    """One field component's control-point problem, prepared for scoring any λ."""

    def __init__(self, b, w, z, rz, d, ridge, order, counts):
        """z: the gauge's null space (``gauge_null_space``), rz: the smoothness operator in it."""
        # BᵀWB from B's sparse rows, then into the null space: Zᵀ(BᵀWB)Z costs
        # two n³ products where (BZ)ᵀW(BZ) cost N·n².
        btwb = z.T @ gram(b, w) @ z
        s = btwb + max(ridge, 1e-9) * np.eye(z.shape[1])
        try:
            mu, v = scipy.linalg.eigh(rz, s)
        except np.linalg.LinAlgError:
            # Controls no corner touches make S singular: a ridge relative to
            # the data's scale fixes it.
            s += 1e-9 * np.trace(btwb) / len(s) * np.eye(len(s))
            mu, v = scipy.linalg.eigh(rz, s)
        self.mu = np.maximum(mu, 0.0)
        self.q = np.asarray(b[order] @ (z @ v))  # (N, n') rows in the eigenbasis, grouped by view
        self.d, self.w = d[order], w[order]
        self.rhs = self.q.T @ (self.w * self.d)
        self.lever = np.einsum("ij,ij->j", self.q, self.w[:, None] * self.q)  # vᵢᵀ BᵀWB vᵢ
        self.bounds = np.concatenate([[0], np.cumsum(counts)])
        # Per group, the λ-free part of its system (built on the first scoring, kept for the refinement's).
        self.blocks: list[np.ndarray | None] = [None] * len(counts)

    def _block(self, k: int) -> np.ndarray:
        """Group k's λ-free matrix: W_g^½ Q_g (rows, n') when the group has
        fewer rows than unknowns, else Q_gᵀ W_g Q_g (n', n')."""
        block = self.blocks[k]
        if block is None:
            rows = slice(self.bounds[k], self.bounds[k + 1])
            qg, wg = self.q[rows], self.w[rows]
            block = np.sqrt(wg)[:, None] * qg if len(wg) < len(self.mu) else qg.T @ (wg[:, None] * qg)
            self.blocks[k] = block
        return block

    def _system(self, block: np.ndarray, lam: float) -> np.ndarray:
        """diag(1 + λμ) − Q_gᵀ W_g Q_g, a new array."""
        a = -block
        a[np.diag_indices(len(a))] += 1.0 + lam * self.mu
        return a

    def scores(self, lambdas: np.ndarray):
        """((G, L) left-out sum of squares, (L,) effective parameters).
        Each (group, λ) is one symmetric positive definite solve (Cholesky)."""
        shrink = 1.0 / (1.0 + np.outer(lambdas, self.mu))  # (L, n')
        resid = self.d[None, :] - (shrink * self.rhs) @ self.q.T  # (L, N) residuals of the full fit
        n = len(self.mu)
        sse = np.zeros((len(self.bounds) - 1, len(lambdas)))
        for k in range(len(sse)):
            rows = slice(self.bounds[k], self.bounds[k + 1])
            qg, wg, rg = self.q[rows], self.w[rows], resid[:, rows]
            block = self._block(k)
            m = len(wg)
            if m < n:  # (I − H_gg) e = r, H_gg = Q_g diag(shrink) Q_gᵀ W_g; symmetric as W^½ (I − H_gg) W^-½
                root = np.sqrt(wg)
                for j in range(len(lambdas)):
                    # I − (W^½ Q_g diag(shrink)^½)(…)ᵀ: its lower triangle by a rank-k update (BLAS syrk)
                    scaled = block * np.sqrt(shrink[j])
                    h = scipy.linalg.blas.dsyrk(-1.0, scaled, lower=1)
                    h[np.arange(m), np.arange(m)] += 1.0
                    sse[k, j] = np.sum((_spd_solve_lower(h, root * rg[j]) / root) ** 2)
            else:  # e = r + Q_g (diag(1 + λμ) − Q_gᵀ W_g Q_g)⁻¹ Q_gᵀ W_g r
                rhs = (rg * wg) @ qg
                for j in range(len(lambdas)):
                    e = rg[j] + qg @ _spd_solve(functools.partial(self._system, block, lambdas[j]), rhs[j])
                    sse[k, j] = np.sum(e * e)
        return sse, shrink @ self.lever


def _spd_solve(build, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b for the symmetric positive definite ``a = build()``, factorised in
    place by LAPACK's Cholesky solver (its lower triangle: the transposed
    array's memory is in LAPACK's order, so nothing is copied); by LU on a
    fresh copy where rounding leaves it indefinite."""
    x = cholesky_solve(build().T, b, lower=True, overwrite=True)
    return np.linalg.solve(build(), b) if x is None else x


def _spd_solve_lower(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a⁻¹ b for a symmetric positive definite ``a`` of which only the lower
    triangle is filled (Fortran order, as BLAS's syrk returns it)."""
    x = cholesky_solve(a, b, lower=True)
    return np.linalg.solve(np.tril(a) + np.tril(a, -1).T, b) if x is None else x
