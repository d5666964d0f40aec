"""Error figures (formats.md §3) and design-matrix diagnostics (Tables 10–11)."""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .gram import gram


def rmse(res: np.ndarray) -> float:
    """Per-point (Euclidean) RMS, what ``cv2.calibrateCamera`` returns: sqrt(mean(dx² + dy²))."""
    return float(np.sqrt(np.mean(np.sum(res * res, axis=-1)))) if len(res) else float("nan")


def rmse_axis(res: np.ndarray) -> float:
    """Per-component RMS (mrcal's figure): sqrt(mean(r²)) over x and y separately."""
    return float(np.sqrt(np.mean(res * res))) if len(res) else float("nan")


def centre_mask(image_points: np.ndarray, image_size) -> np.ndarray:
    """Observed pixel / (W−1, H−1) inside [0.25, 0.75]²."""
    w, h = image_size
    q = image_points / np.array([w - 1.0, h - 1.0])
    return np.all((q >= 0.25) & (q <= 0.75), axis=1)


def noise_floor(sigma: float, n_params: int, n_points: int) -> float:
    """Expected training rmse_axis of a perfect model: σ·sqrt(1 − P/(2N))."""
    return float(sigma * np.sqrt(max(0.0, 1.0 - n_params / (2.0 * n_points))))


def summary(res: np.ndarray, image_points: np.ndarray, image_size) -> dict[str, float]:
    c = centre_mask(image_points, image_size)
    return {
        "rmse": rmse(res),
        "rmse_axis": rmse_axis(res),
        "rmse_center": rmse(res[c]),
        "rmse_edge": rmse(res[~c]),
        "n_points": int(len(res)),
    }


def design_diagnostics(design: sp.csr_matrix, weights: np.ndarray, regulariser: sp.csr_matrix,
                       breaks_u: np.ndarray, breaks_v: np.ndarray, samples: np.ndarray) -> dict:
    """Rank, condition numbers of the (weighted, regularised) normal matrices for
    x and y, zero columns and empty intervals of the control-point design."""
    design = sp.csr_matrix(design)
    sv = singular_values(design)
    tol = sv.max() * max(design.shape) * np.finfo(float).eps if sv.size else 0.0
    reg = (regulariser.T @ regulariser).toarray()
    conds = []
    for k in range(weights.shape[1]):
        normal = gram(design, weights[:, k]) + reg  # BᵀWB from B's sparse rows
        conds.append(float(np.linalg.cond(normal)))
    column_mass = np.bincount(design.indices, weights=np.abs(design.data), minlength=design.shape[1])
    return {
        "rank": int(np.sum(sv > tol)),
        "n_controls": int(design.shape[1]),
        "condition_x": conds[0],
        "condition_y": conds[1],
        "condition_unregularised": float(sv.max() / sv.min()) if sv.size and sv.min() > 0 else float("inf"),
        "zero_columns": int(np.sum(column_mass == 0)),
        "empty_intervals_u": int(np.sum(np.histogram(samples[:, 0], bins=breaks_u)[0] == 0)),
        "empty_intervals_v": int(np.sum(np.histogram(samples[:, 1], bins=breaks_v)[0] == 0)),
        "intervals": [len(breaks_u) - 1, len(breaks_v) - 1],
    }


def singular_values(design: sp.csr_matrix) -> np.ndarray:
    """The singular values of a sparse design whose rows each touch a few
    columns (a B-spline field's: the 16 controls of one knot cell), as a
    dense SVD gives them, for a fraction of its N·n² cost.

    Rows that start at the same column touch the same few: each such group is
    reduced to its triangular QR factor, and the stacked factors have the
    design's singular values (B = Q R with Q orthogonal), at most a few rows
    per column. The squared route, BᵀB's eigenvalues, loses the small ones
    the rank and the condition number are about."""
    design = sp.csr_matrix(design)
    lengths = np.diff(design.indptr)
    rows = np.flatnonzero(lengths > 0)
    if not len(rows):
        return np.zeros(min(design.shape))
    first = np.minimum.reduceat(design.indices, design.indptr[rows])
    order = rows[np.argsort(first, kind="stable")]
    bounds = np.flatnonzero(np.diff(np.sort(first))) + 1
    factors = []
    for group in np.split(order, bounds):
        block = design[group]
        cols = np.unique(block.indices)
        r = np.linalg.qr(block[:, cols].toarray(), mode="r")
        stacked = np.zeros((len(r), design.shape[1]))
        stacked[:, cols] = r
        factors.append(stacked)
    return np.linalg.svd(np.vstack(factors), compute_uv=False)
