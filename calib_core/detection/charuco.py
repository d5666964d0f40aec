"""ChArUco boards: OpenCV finds the board's markers and names its corners; each
corner is then placed afresh from the markers beside it.

OpenCV interpolates a ChArUco corner through a homography of the markers and
refines it with a window that, on steep and strongly distorted views, reaches
across the thin white margin round the markers onto their edges (rendered
fisheye views: corners 3-5 px off). Here each corner is predicted through the
homography of each marker diagonal to it (a marker is small: its homography
holds under any lens), the predictions averaged, then polished with a window
inside that margin (cornerSubPix and the saddle fit); a corner the polish moves
more than ``MAX_SHIFT`` is dropped.
"""
from __future__ import annotations

import functools

import cv2
import numpy as np

from ..board import BoardSpec
from . import corner_refine
from .markers import Markers, homographies, layout_verdict, why_none, wrong_layout_reason

MAX_SHIFT = 1.0   # px from the markers' prediction

# How OpenCV names corners. It names a corner only where both markers diagonal to it were
# decoded (``minMarkers`` 2), and drops the whole board where one corner of its own
# interpolation lies nearer another marker than its own (``checkMarkers``): every corner
# beside a marker too small or steep to decode was lost, and steep views lost every corner.
# Here each corner is placed and checked afresh from any one of its markers, and the markers'
# layout is checked pair by pair (``layout_check``) (docs/detection.md, "ChArUco corners
# beside one marker, and boards checked against their layout").
_NAMING = cv2.aruco.CharucoParameters()
_NAMING.minMarkers = 1
_NAMING.checkMarkers = False
AGREE = 0.5   # squares: two markers diagonal to a corner place it this close, or one of them is not the board's


def detect(gray: np.ndarray, board: BoardSpec, markers: Markers):
    """(ids (N,), pixels (N, 2), reason if none) of a ChArUco board, from the image's markers of its ids."""
    dictionary = str(board.dictionary)
    mine, mine_ids = markers.of(dictionary, board.first_marker, board.n_markers)
    if len(mine_ids) == 0:
        return None, None, "board not found: " + why_none(gray, dictionary, 1, board.first_marker, board.n_markers,
                                                          markers)
    through = _per_marker(board, mine, mine_ids - board.first_marker)
    keep, wrong = layout_check(board, through, len(mine_ids))
    if wrong:
        legacy = " in OpenCV's legacy layout" if board.legacy else ""
        layout = ("whether it is printed in OpenCV's current layout (the spec says legacy)" if board.legacy else
                  "whether it is printed in OpenCV's legacy layout (add :legacy to the spec)")
        return None, None, (wrong_layout_reason(f"{len(mine_ids)} markers", f"{board.cols} × {board.rows} ChArUco board{legacy}",
                                                "squares") + " and " + layout)
    mine, mine_ids = mine[keep], mine_ids[keep]   # a misread marker goes alone
    detector = cv2.aruco.CharucoDetector(board.cv_charuco(), _NAMING)
    cv_pts, ids, _, _ = detector.detectBoard(gray, markerCorners=list(mine.reshape(-1, 1, 4, 2)),
                                        markerIds=mine_ids.reshape(-1, 1).astype(np.int32))
    if ids is None or len(ids) == 0:
        return None, None, f"too few corners (0 found from {len(mine_ids)} markers)"
    ids = ids.reshape(-1).astype(np.int64)
    predicted, jac, known = predict(board, [a[keep[through[1]]] for a in through], ids)
    ids, jac = ids[known], jac[known]
    half = half_window(board, jac)
    pts = np.full((len(ids), 2), np.nan)
    keep = np.zeros(len(ids), bool)
    # OpenCV's corner first; where that fails, the markers' prediction (OpenCV's own window
    # can land far off on steep views, the prediction a few px off on strongly bent ones).
    for start in (cv_pts.reshape(-1, 2).astype(np.float64)[known], predicted[known]):
        todo = ~keep
        if not todo.any():
            break
        p, ok = corner_refine.polish(gray, start[todo], half[todo], MAX_SHIFT)
        ok &= reads_as_corner(gray, board, ids[todo], p, jac[todo])
        pts[np.flatnonzero(todo)[ok]] = p[ok]
        keep[np.flatnonzero(todo)[ok]] = True
    return ids[keep], pts[keep], ""


@functools.lru_cache(maxsize=32)
def _marker_squares(board: BoardSpec) -> np.ndarray:
    """(rows, cols) bool: the squares that hold a marker (white paper round it)."""
    centres = np.asarray(board.cv_charuco().getObjPoints(), np.float64)[:, :, :2].mean(axis=1)
    cells = np.floor(centres / board.square_size).astype(int)
    out = np.zeros((board.rows, board.cols), bool)
    out[cells[:, 1], cells[:, 0]] = True
    return out


def reads_as_corner(gray: np.ndarray, board: BoardSpec, ids: np.ndarray, pts: np.ndarray,
                    jac: np.ndarray) -> np.ndarray:
    """(N,) bool: the image round each corner shows the four squares its id says, dark where
    a black square touches it, bright in the white margin of each marker square.

    Sampled half the margin out along the board's diagonals, through the markers' local
    map (``jac``: px per board unit): a point the refinement took onto a marker's edge
    (where a white margin meets a black square, a saddle too) reads the wrong way round."""
    if len(ids) == 0:
        return np.zeros(0, bool)
    c = board.cols - 1
    col, row = ids % c + 1, ids // c + 1                     # the corner's lattice point, in squares
    d = min(board.square_size - float(board.marker_size or 0.0), board.square_size / 2) / 4
    signs = np.array([[-1, -1], [1, -1], [-1, 1], [1, 1]])  # TL, TR, BL, BR in board units
    at = pts[:, None, :] + np.einsum("nij,kj->nki", jac, d * signs)
    m = at.astype(np.float32).reshape(-1, 1, 2)
    level = cv2.remap(gray, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    level = level.reshape(len(ids), 4).astype(np.float64)
    squares = _marker_squares(board)
    bright = np.stack([squares[row + (sy - 1) // 2, col + (sx - 1) // 2] for sx, sy in signs], axis=1)
    lo = np.where(bright, -np.inf, level).max(axis=1)
    hi = np.where(bright, level, np.inf).min(axis=1)
    return hi - lo > 0.35 * (level.max(axis=1) - level.min(axis=1)) + 12


@functools.lru_cache(maxsize=32)
def _diagonal_markers(board: BoardSpec) -> tuple[np.ndarray, np.ndarray]:
    """(corner id, marker index) pairs (K,) each: the markers whose nearest corner sits
    diagonally next to a chessboard corner (one or two per corner)."""
    cv_board = board.cv_charuco()
    marker_pts = np.asarray(cv_board.getObjPoints(), np.float64)[:, :, :2]      # (M, 4, 2)
    corners = np.asarray(cv_board.getChessboardCorners(), np.float64)[:, :2]     # (C, 2)
    gap = np.sqrt(2) * (board.square_size - float(board.marker_size or 0.0)) / 2
    d = np.linalg.norm(corners[:, None, None] - marker_pts[None], axis=-1).min(axis=2)   # (C, M)
    corner, marker = np.nonzero(np.abs(d - gap) < 1e-6 * board.square_size)
    return corner, marker


def predict(board: BoardSpec, through: list[np.ndarray], ids: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pixels (N, 2) of corners ``ids``, the mean of their places through the homographies of
    the detected markers diagonal to them (``through``: ``_per_marker``'s rows), the map's
    Jacobian there (N, 2, 2: px per board unit), and which (N,) had a marker."""
    corner, _, p, jac = through
    total, count, jsum = np.zeros((board.n_corners, 2)), np.zeros(board.n_corners), np.zeros((board.n_corners, 2, 2))
    np.add.at(total, corner, p)
    np.add.at(count, corner, 1.0)
    np.add.at(jsum, corner, jac)
    known = count[ids] > 0
    n = np.maximum(count[ids], 1.0)
    return total[ids] / n[:, None], jsum[ids] / n[:, None, None], known


def layout_check(board: BoardSpec, through: list[np.ndarray], k: int) -> tuple[np.ndarray, bool]:
    """(keep (K,), wrong layout) of ``k`` decoded markers (``markers.layout_verdict``; ``through``:
    ``_per_marker``'s rows), each pair the two markers diagonal to one corner: they agree where
    they place it within ``AGREE`` of a square of each other.

    A marker's homography holds at its own corners under any lens, so two markers of the
    board place their shared corner alike; a misread marker, or a board of another size or
    layout, puts the two a square or more apart."""
    order = np.argsort(through[0], kind="stable")
    corner, slot, p, jac = (a[order] for a in through)
    first = np.flatnonzero(corner[1:] == corner[:-1])          # two markers name this corner
    square = board.square_size * np.linalg.svd(0.5 * (jac[first] + jac[first + 1]), compute_uv=False)[:, -1]
    agree = np.linalg.norm(p[first] - p[first + 1], axis=1) < AGREE * square
    return layout_verdict(slot[first], slot[first + 1], agree, k)


def _per_marker(board: BoardSpec, marker_corners: np.ndarray, marker_ids: np.ndarray) -> list[np.ndarray]:
    """[corner id (P,), marker slot in ``marker_ids`` (P,), pixel (P, 2), Jacobian (P, 2, 2)] of
    each corner through the homography of each detected marker diagonal to it."""
    cv_board = board.cv_charuco()
    obj = np.asarray(cv_board.getObjPoints(), np.float64)[:, :, :2]
    corner, marker = _diagonal_markers(board)
    slot = np.full(board.n_markers, -1)
    slot[marker_ids] = np.arange(len(marker_ids))
    use = slot[marker] >= 0
    corner, marker = corner[use], marker[use]
    h = homographies(obj[marker], marker_corners[slot[marker]].astype(np.float64))
    target = np.asarray(cv_board.getChessboardCorners(), np.float64)[corner, :2]
    q = np.einsum("kij,kj->ki", h, np.column_stack([target, np.ones(len(target))]))
    p = q[:, :2] / q[:, 2:]
    jac = (h[:, :2, :2] - p[:, :, None] * h[:, 2:, :2]) / q[:, 2:, None]   # the homography's Jacobian there
    return [corner, slot[marker], p, jac]


def half_window(board: BoardSpec, jac: np.ndarray) -> np.ndarray:
    """Per corner (N,): a window no wider than the white margin round the markers next to it
    where the board is drawn thinnest (``jac`` (N, 2, 2): px per board unit), nor than a quarter square."""
    margin = min((board.square_size - float(board.marker_size or 0.0)) / 2, board.square_size / 4)
    thinnest = np.linalg.svd(jac, compute_uv=False)[:, -1] if len(jac) else np.zeros(0)
    return np.clip(np.floor(thinnest * margin), 2, 10).astype(int)
