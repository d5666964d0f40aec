"""Geometric quality of a rectification (the paper's Table 7), measured on the
detected boards after undistortion.

The board corners of every view are undistorted with the calibration
(``Calibration.undistort_points``, Newton to 1e-9 px) into an ideal pinhole
image of focal ``f`` (the calibration's mean of fx, fy, so figures are in
rectified pixels); the raw image uses the observed pixels as they are. Then:

- **straightness** [px]: each board row and column (≥ 3 corners) gets a
  total-least-squares line; RMS orthogonal distance of its corners, over all
  lines. A pinhole maps board lines to straight lines whatever the pose, so no
  perspective needs removing; with noise σ per axis it tends to σ.
- **spacing CV**: a least-squares board homography H per view (board plane →
  rectified image); the corners are taken back through H⁻¹ to the board plane,
  which removes perspective; neighbouring-corner distances along rows and
  columns there, pooled over views: std / mean (0 for a perfect grid).
- **orthogonality** [deg]: in the same board-plane frame, lines fitted to each
  row and column; mean |90° − angle| over every (row, column) pair of a view.
  A leftover distortion bends lines differently across the board, which a
  single homography cannot absorb.
- **smoothness** [1/px]: the distortion field ``D(p) = p − ideal(p)`` (px) on
  a regular grid of photo pixels; mean Frobenius norm of the Hessians of its
  two components (both second derivatives and the mixed one, in px/px²).
  Lower is smoother. Undefined for the raw image (there is no field).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..calibration import Calibration
from ..errors import DataError
from ..observations import Observations

MIN_LINE_POINTS = 3
SMOOTHNESS_GRID = (48, 60)  # photo pixels sampled (across, down) for the smoothness


def _flat(obs: Observations) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """object_points (N, 3), image_points (N, 2), view_index (N,) over all views."""
    if not obs.views:
        raise DataError("quality: the observations hold no views")
    obj = np.concatenate([np.asarray(v.object_points, dtype=np.float64) for v in obs.views])
    img = np.concatenate([np.asarray(v.image_points, dtype=np.float64) for v in obs.views])
    vid = np.concatenate([np.full(len(v.object_points), k) for k, v in enumerate(obs.views)])
    if np.ptp(obj[:, 2]) > 1e-9 * max(1.0, np.abs(obj).max()):
        raise DataError("quality: the board must be planar (object_points with Z = 0)")
    return obj, img, vid


def grid_indices(object_points: np.ndarray) -> np.ndarray:
    """Integer board coordinates (N, 2) of board points (N, 3) on a square grid."""
    xy = object_points[:, :2] - object_points[:, :2].min(axis=0)
    d = np.abs(np.diff(np.unique(np.round(xy.ravel(), 9))))
    step = d[d > 1e-9].min() if np.any(d > 1e-9) else 1.0
    return np.round(xy / step).astype(np.int64)


def _line_groups(ij: np.ndarray, view_index: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Line id (N,) of each point as a row member and as a column member (ids
    shared across both: rows first), and the number of lines."""
    key_row = view_index * 1_000_003 + ij[:, 1]
    key_col = view_index * 1_000_003 + ij[:, 0]
    _, row_id = np.unique(key_row, return_inverse=True)
    _, col_id = np.unique(key_col, return_inverse=True)
    n_rows = row_id.max() + 1
    return row_id, col_id + n_rows, int(n_rows + col_id.max() + 1)


def _line_moments(p: np.ndarray, ids: np.ndarray, n: int):
    """Per line: count, mean (n, 2) and covariance entries, by bincount (no loop)."""
    cnt = np.bincount(ids, minlength=n).astype(np.float64)
    safe = np.maximum(cnt, 1)
    mx = np.bincount(ids, p[:, 0], n) / safe
    my = np.bincount(ids, p[:, 1], n) / safe
    dx, dy = p[:, 0] - mx[ids], p[:, 1] - my[ids]
    sxx = np.bincount(ids, dx * dx, n) / safe
    syy = np.bincount(ids, dy * dy, n) / safe
    sxy = np.bincount(ids, dx * dy, n) / safe
    return cnt, sxx, syy, sxy


def straightness(points: np.ndarray, ij: np.ndarray, view_index: np.ndarray) -> float:
    """RMS orthogonal distance (px) of points (N, 2) to their rows' and columns' fitted lines."""
    row_id, col_id, n = _line_groups(ij, view_index)
    ids = np.concatenate([row_id, col_id])
    cnt, sxx, syy, sxy = _line_moments(np.concatenate([points, points]), ids, n)
    # The smallest eigenvalue of a line's 2×2 covariance is its mean squared orthogonal distance.
    lam = 0.5 * (sxx + syy) - np.sqrt(0.25 * (sxx - syy) ** 2 + sxy ** 2)
    use = cnt >= MIN_LINE_POINTS
    if not use.any():
        raise DataError(f"quality: no board row or column has {MIN_LINE_POINTS} corners")
    return float(np.sqrt(np.sum(np.maximum(lam[use], 0) * cnt[use]) / np.sum(cnt[use])))


def _board_frame(points: np.ndarray, object_points: np.ndarray, view_index: np.ndarray) -> np.ndarray:
    """Points (N, 2) taken back to the board plane by each view's least-squares homography."""
    import cv2

    out = np.full_like(points, np.nan)
    for k in np.unique(view_index):  # one homography per view: a loop over views, not points
        m = view_index == k
        if m.sum() < 4:
            continue
        h, _ = cv2.findHomography(object_points[m, :2], points[m], 0)
        if h is None:
            continue
        q = np.column_stack([points[m], np.ones(m.sum())]) @ np.linalg.inv(h).T
        out[m] = q[:, :2] / q[:, 2:]
    return out


def spacing_cv(board: np.ndarray, ij: np.ndarray, view_index: np.ndarray) -> float:
    """std/mean of neighbouring-corner distances (board frame, (N, 2)) along rows and columns."""
    key = (view_index * 1_000_003 + ij[:, 1]) * 1_000_003 + ij[:, 0]
    order = np.argsort(key)
    sorted_keys = key[order]
    dists = []
    for di, dj in ((1, 0), (0, 1)):  # right and lower neighbour of every corner, by a sorted lookup
        nb = key + dj * 1_000_003 + di
        pos = np.minimum(np.searchsorted(sorted_keys, nb), len(key) - 1)
        ok = sorted_keys[pos] == nb
        dists.append(np.linalg.norm(board[ok] - board[order[pos[ok]]], axis=1))
    d = np.concatenate(dists)
    d = d[np.isfinite(d)]
    if len(d) < 2:
        raise DataError("quality: no neighbouring corners to measure the spacing")
    return float(np.std(d) / np.mean(d))


def orthogonality(board: np.ndarray, ij: np.ndarray, view_index: np.ndarray) -> float:
    """Mean |90° − angle| (degrees) between fitted row and column lines, board frame (N, 2)."""
    row_id, col_id, n = _line_groups(ij, view_index)
    ok = np.all(np.isfinite(board), axis=1)
    ids = np.concatenate([row_id[ok], col_id[ok]])
    cnt, sxx, syy, sxy = _line_moments(np.concatenate([board[ok], board[ok]]), ids, n)
    direction = 0.5 * np.arctan2(2 * sxy, sxx - syy)  # principal axis angle of each line
    line_view = np.zeros(n, dtype=np.int64)
    line_view[row_id] = view_index
    line_view[col_id] = view_index
    is_row = np.zeros(n, dtype=bool)
    is_row[row_id] = True
    use = cnt >= MIN_LINE_POINTS
    errs = []
    for k in np.unique(view_index):
        r = direction[use & is_row & (line_view == k)]
        c = direction[use & ~is_row & (line_view == k)]
        if len(r) and len(c):
            a = np.abs(np.degrees(r[:, None] - c[None, :])) % 180.0
            errs.append(np.abs(90.0 - a).ravel())
    if not errs:
        raise DataError("quality: no view has both a row and a column of corners")
    return float(np.mean(np.concatenate(errs)))


def smoothness(cal: Calibration, grid: tuple[int, int] = SMOOTHNESS_GRID) -> float:
    """Mean Frobenius norm (1/px) of the Hessian of the distortion field over the photo."""
    w, h = cal.image_size
    u = np.linspace(0, w - 1, grid[0])
    v = np.linspace(0, h - 1, grid[1])
    uu, vv = np.meshgrid(u, v)
    p = np.column_stack([uu.ravel(), vv.ravel()])
    d = (p - cal.undistort_points(p)).reshape(grid[1], grid[0], 2)
    total = np.zeros(d.shape[:2])
    for c in range(2):
        gv, gu = np.gradient(d[..., c], v, u)
        guv, guu = np.gradient(gu, v, u)
        gvv, _ = np.gradient(gv, v, u)
        total += guu ** 2 + gvv ** 2 + 2 * guv ** 2
    return float(np.nanmean(np.sqrt(total)))


def board_quality(points: np.ndarray, object_points: np.ndarray, view_index: np.ndarray) -> dict[str, float]:
    """straightness, spacing_cv, orthogonality of board corners (N, 2) in a (rectified) image."""
    ok = np.all(np.isfinite(points), axis=1)
    points, object_points, view_index = points[ok], object_points[ok], view_index[ok]
    ij = grid_indices(object_points)
    board = _board_frame(points, object_points, view_index)
    return {"straightness": straightness(points, ij, view_index), "spacing_cv": spacing_cv(board, ij, view_index),
            "orthogonality": orthogonality(board, ij, view_index), "n_points": int(ok.sum())}


def geometric_quality(cal: Calibration, obs: Observations, with_smoothness: bool = True) -> dict[str, Any]:
    """Table 7 for ``cal``: its rectification of the boards in ``obs``, plus
    its distortion field's smoothness. Keys: straightness (px), spacing_cv,
    orthogonality (deg), smoothness (1/px), focal (px of the rectified image)."""
    obj, img, vid = _flat(obs)
    fx, fy = cal.model.intrinsics[:2]
    focal = 0.5 * (abs(fx) + abs(fy))
    rays = cal.rays(img)
    with np.errstate(divide="ignore", invalid="ignore"):
        xn = np.where(rays[:, 2:] > 1e-9, rays[:, :2] / rays[:, 2:], np.nan)
    out: dict[str, Any] = board_quality(focal * xn, obj, vid)
    out["smoothness"] = smoothness(cal) if with_smoothness else float("nan")
    out["focal"] = float(focal)
    return out


def raw_quality(obs: Observations) -> dict[str, Any]:
    """Table 7's "raw image" row: the observed corners as they are (no smoothness)."""
    obj, img, vid = _flat(obs)
    out: dict[str, Any] = board_quality(img, obj, vid)
    out["smoothness"] = None  # no field: JSON null
    return out


METRICS = (("straightness", "straightness RMSE [px]"), ("spacing_cv", "spacing CV"),
           ("orthogonality", "orthogonality error [deg]"), ("smoothness", "smoothness [1/px]"))
