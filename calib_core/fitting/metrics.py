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


CHUNK_ROWS = 256  # rows reduced together: the stacked factors stay a few per column, the padding small


def singular_values(design: sp.csr_matrix) -> np.ndarray:
    """The singular values of a sparse design whose rows each touch a few
    columns (a B-spline field's: the 16 controls of one knot cell), as a
    dense SVD gives them, for a fraction of its N·n² cost.

    Rows that start at the same column touch the same few. Each such group,
    in chunks of at most CHUNK_ROWS rows, is reduced to its triangular QR
    factor (all chunks at once, zero-padded to one shape), and the stacked
    factors have the design's singular values (B = Q R with Q orthogonal).
    The squared route, BᵀB's eigenvalues, loses the small ones the rank and
    the condition number are about."""
    design = sp.csr_matrix(design)
    design.sum_duplicates()
    n = design.shape[1]
    rows = np.flatnonzero(np.diff(design.indptr))
    if not len(rows):
        return np.zeros(min(design.shape))
    first = np.minimum.reduceat(design.indices, design.indptr[rows])
    order = np.argsort(first, kind="stable")
    group = np.cumsum(np.r_[0, np.diff(first[order]) != 0])  # of each row, in ``order``
    # each row's chunk: its group split every CHUNK_ROWS rows
    starts = np.r_[0, np.flatnonzero(np.diff(group)) + 1]
    rank = np.arange(len(order)) - np.repeat(starts, np.diff(np.r_[starts, len(order)]))
    chunk_key = group * (len(order) // CHUNK_ROWS + 1) + rank // CHUNK_ROWS
    chunk = np.unique(chunk_key, return_inverse=True)[1]
    slot = rank % CHUNK_ROWS
    # every nonzero: its chunk, its row's slot in the chunk, its column's place among the chunk's columns
    sub = design[rows[order]]
    nz_chunk = np.repeat(chunk, np.diff(sub.indptr))
    nz_slot = np.repeat(slot, np.diff(sub.indptr))
    keys, inverse = np.unique(nz_chunk.astype(np.int64) * n + sub.indices, return_inverse=True)
    key_chunk = keys // n
    key_place = np.arange(len(keys)) - np.searchsorted(key_chunk, key_chunk)  # its rank among its chunk's columns
    width = int(np.max(key_place)) + 1
    blocks = np.zeros((chunk.max() + 1, int(slot.max()) + 1, width))
    blocks[nz_chunk, nz_slot, key_place[inverse]] = sub.data
    # (chunks, k, width): mode "r" returns R alone, which numpy's stubs do not say
    factors: np.ndarray = np.linalg.qr(blocks, mode="r")  # type: ignore[assignment]
    columns = np.full((len(factors), width), n)  # a padding column lands in an extra last column, dropped
    columns[key_chunk, key_place] = keys % n
    stacked = np.zeros((*factors.shape[:2], n + 1))
    np.put_along_axis(stacked, np.broadcast_to(columns[:, None, :], factors.shape), factors, axis=2)
    return np.linalg.svd(stacked[:, :, :n].reshape(-1, n), compute_uv=False)
