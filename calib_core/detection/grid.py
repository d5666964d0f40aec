"""Place a detected chessboard grid on the board: from grid cells to corner ids.

A detector returns an (h, w) lattice of corners whose orientation and extent
are its own: OpenCV may return the grid rotated by 180°, and a partial
detection (``CALIB_CB_LARGER``) has no origin at all. We fix what the image
itself can tell:

- handedness: the board seen from the front is never mirrored, so the grid is
  flipped if its column and row directions turn the wrong way;
- square colour: the cell whose top-left corner is corner ``(r, c)`` is bright
  iff ``r + c`` is even (OpenCV's convention, ``meta == 2`` at its origin), which
  picks between 180° rotations of a full board and fixes the parity of a
  partial grid's offset.

- lattice stride: on steep views ``CALIB_CB_LARGER`` can grow a grid that steps
  over every other line of the board (seen on 2 of the 25 BabelCalib fisheye
  views, all rows; on rendered fisheye views, some rows). Its corners are real
  but those cells hold two squares, so their quarter-cell samples fall on
  opposite colours; a cell of three squares (one BabelCalib view, OpenCV 5.1)
  changes colour between its fifth and its middle. Such a grid is expanded to the board's own lattice (the
  skipped corners are interpolated only to place it, and are not returned);
  gaps that read as none of these (a grid grown into a grazing
  horizon), or whose cells change colour three times or more along their middle
  (four squares or more, which quarter points can read as one), cut the grid,
  and its largest clean block is kept.

What stays unknown for a partial plain chessboard is *where* on the board the
patch lies: it is placed at the board's top-left (offset 0 or 1 for parity).
Its ids and object points are then consistent within the view (the pose
absorbs the shift), which is all a per-view calibration needs.
"""
from __future__ import annotations

import cv2
import numpy as np

from .quantiles import percentiles

_DECILES = np.array([10, 90]) / 100   # the 10th and 90th percentiles, as np.percentile divides them


def right_handed(grid: np.ndarray) -> np.ndarray:
    """Grid (h, w, 2) with columns reversed if it is mirrored in the image."""
    h, w = grid.shape[:2]
    if h < 2 or w < 2:
        return grid
    dc = grid[:, -1] - grid[:, 0]          # along a row (board x), (h, 2)
    dr = grid[-1, :] - grid[0, :]          # along a column (board y), (w, 2)
    cross = np.mean(dc[:, 0]) * np.mean(dr[:, 1]) - np.mean(dc[:, 1]) * np.mean(dr[:, 0])
    # Image y points down, like board y: a front view has a positive cross product.
    return grid if cross > 0 else grid[:, ::-1]


def cell_brightness_sign(grid: np.ndarray, gray: np.ndarray) -> int:
    """+1 if cell (0, 0) of the grid (h, w, 2) is bright, -1 if dark, 0 if unknown.

    Uses the median over all cells of each parity, so squares with tags or
    markers inside (a minority) do not flip the answer.
    """
    h, w = grid.shape[:2]
    if h < 2 or w < 2:
        return 0
    centres = 0.25 * (grid[:-1, :-1] + grid[1:, :-1] + grid[:-1, 1:] + grid[1:, 1:])  # (h-1, w-1, 2)
    m = centres.reshape(-1, 1, 2).astype(np.float32)
    vals = cv2.remap(gray, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(h - 1, w - 1)
    i, j = np.indices(vals.shape)
    even, odd = vals[(i + j) % 2 == 0], vals[(i + j) % 2 == 1]
    if even.size == 0 or odd.size == 0:
        return 0
    d = float(_median(even.astype(np.float64), 0)) - float(_median(odd.astype(np.float64), 0))  # uint8 levels
    return 0 if abs(d) < 8 else (1 if d > 0 else -1)


def _samples(gray: np.ndarray, grid: np.ndarray, st: list[tuple[float, float]]) -> np.ndarray:
    """Grey levels (len(st), h-1, w-1) at cell coordinates st [(s along a row, t down a column), ...]
    of every cell of grid (h, w, 2), bilinear between the cell's four corners; in one remap
    (one per (s, t) cost more than the sampling)."""
    s, t = (np.array([v[k] for v in st])[:, None, None, None] for k in (0, 1))
    p = ((1 - s) * (1 - t) * grid[:-1, :-1] + s * (1 - t) * grid[:-1, 1:]
         + (1 - s) * t * grid[1:, :-1] + s * t * grid[1:, 1:]).astype(np.float32)
    n, h, w = p.shape[:3]
    m = p.reshape(n * h, w, 2)
    vals = cv2.remap(gray, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    return vals.reshape(n, h, w).astype(np.float64)


def gap_strides(grid: np.ndarray, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Board squares spanned by each row gap (h-1,) and column gap (w-1,) of grid (h, w, 2):
    1, 2, 3, or 0 where the cells are unreadable (a grid grown into a grazing horizon).

    A true cell is one square: its quarter points share a colour. A cell two squares
    long in a direction has its quarter points along it on opposite colours.
    """
    h, w = grid.shape[:2]
    ones = np.ones(max(h - 1, 0), int), np.ones(max(w - 1, 0), int)
    if h < 2 or w < 2:
        return ones
    fractions = (0.2, 0.25, 0.5, 0.75, 0.8)
    st = [(s, t) for s in fractions for t in fractions]
    samples = _samples(gray, grid, st)
    q = dict(zip(st, samples, strict=True))
    lo, hi = percentiles(samples.ravel(), _DECILES)
    contrast = hi - lo
    if contrast < 16:
        return ones

    # Medians along each gap: the tags and markers of tagged boards fill a minority of cells.
    def change(a: tuple[float, float], b: tuple[float, float], axis: int) -> np.ndarray:
        return _median(np.abs(q[a] - q[b]), axis) / contrast

    def classes(two: np.ndarray, three: np.ndarray) -> np.ndarray:
        # Quarter points read one colour over one square and over three (at 0.75 and 2.25
        # squares): a cell of three squares changes colour between its fifth and its middle.
        return np.where(two < 0.25, np.where(three > 0.5, 3, 1), np.where(two > 0.5, 2, 0))

    down = classes(change((0.5, 0.25), (0.5, 0.75), 1),
                   np.minimum(change((0.5, 0.2), (0.5, 0.5), 1), change((0.5, 0.8), (0.5, 0.5), 1)))
    along = classes(change((0.25, 0.5), (0.75, 0.5), 0),
                    np.minimum(change((0.2, 0.5), (0.5, 0.5), 0), change((0.8, 0.5), (0.5, 0.5), 0)))
    # A cell of more squares can read as one of these (six squares: its quarter points on
    # squares 1 and 4, one colour): counted densely along its middle, it changes colour
    # three times or more, and is cut like an unreadable one.
    down[_colour_changes(gray, grid, 1, 0.5 * (lo + hi)) >= 3] = 0
    along[_colour_changes(gray, grid, 0, 0.5 * (lo + hi)) >= 3] = 0
    return down, along


def _colour_changes(gray: np.ndarray, grid: np.ndarray, axis: int, middle: float) -> np.ndarray:
    """The median over each row gap (axis 1) or column gap (axis 0) of grid (h, w, 2) of the
    times its cells' grey level crosses ``middle`` at eight points along their middle."""
    dense = [(k + 0.5) / 8 for k in range(8)]
    st = [(0.5, f) for f in dense] if axis == 1 else [(f, 0.5) for f in dense]
    bright = _samples(gray, grid, st) > middle                       # (8, h-1, w-1)
    return _median(np.sum(bright[1:] != bright[:-1], axis=0).astype(np.float64), axis)


def _median(a: np.ndarray, axis: int) -> np.ndarray:
    """``np.median(a, axis)`` of finite values, the same numbers for a fraction of its overhead
    (six small medians a grid, each costing more in np.median's checks than in the sort)."""
    s = np.sort(a, axis=axis)
    m = s.shape[axis]
    return (np.take(s, (m - 1) // 2, axis) + np.take(s, m // 2, axis)) / 2


def lattice_score(grid: np.ndarray, gray: np.ndarray) -> float:
    """Share of the cells of grid (h, w, 2) that look like one chessboard square each:
    one colour at all four quarter points, bright and dark alternating like a checker.

    A sheared grid (an axis that runs diagonally over the board, which LARGER can grow)
    or a wrongly expanded one scores near 0.5 or below; tagged boards lose only their
    tag squares.
    """
    h, w = grid.shape[:2]
    if h < 2 or w < 2:
        return 0.0
    q = _samples(gray, grid, [(s, t) for s in (0.25, 0.75) for t in (0.25, 0.75)])  # (4, h-1, w-1)
    lo, hi = percentiles(q.ravel(), _DECILES)
    if hi - lo < 16:
        return 0.0
    uniform = q.max(0) - q.min(0) < 0.5 * (hi - lo)
    bright = q.mean(0) > 0.5 * (lo + hi)
    parity = np.indices(bright.shape).sum(0) % 2 == 0
    checker = max(np.mean(bright == parity), np.mean(bright != parity))
    return float(min(np.mean(uniform), checker))


def _longest_run(ok: np.ndarray) -> tuple[int, int]:
    """[start, end) of the longest run of True in ok (n,)."""
    best, start = (0, 0), None
    for k, v in enumerate(np.append(ok, False)):
        if v and start is None:
            start = k
        elif not v and start is not None:
            best = max(best, (start, k), key=lambda r: r[1] - r[0])
            start = None
    return best


def expand(grid: np.ndarray, sr: np.ndarray, sc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Grid (h, w, 2) on the board's own lattice: gap k of rows (columns) spans sr[k] (sc[k])
    squares, the corners in between are interpolated. Returns (H, W, 2) and the (H, W) mask
    of detected (not inserted) corners."""
    def positions(strides, n):
        at = np.concatenate([[0], np.cumsum(strides)])                # lattice index of each grid line
        lat = np.arange(at[-1] + 1)
        k = np.minimum(np.searchsorted(at, lat, side="right") - 1, n - 2)
        return k, (lat - at[k]) / np.asarray(strides)[k], at

    h, w = grid.shape[:2]
    r0, fr, at_r = positions(sr, h)
    c0, fc, at_c = positions(sc, w)
    fr, fc = fr[:, None, None], fc[None, :, None]
    full = ((1 - fr) * (1 - fc) * grid[r0][:, c0] + (1 - fr) * fc * grid[r0][:, c0 + 1]
            + fr * (1 - fc) * grid[r0 + 1][:, c0] + fr * fc * grid[r0 + 1][:, c0 + 1])
    real = np.zeros(full.shape[:2], bool)
    real[np.ix_(at_r, at_c)] = True
    return full, real


def place_grid(grid: np.ndarray, cols: int, rows: int, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Ids (N,) and pixels (N, 2) of a detected grid (h, w, 2) on a cols × rows board.

    None when the grid fits the board in no orientation (a detector that ran
    past the board's edge).
    """
    sr, sc = gap_strides(grid, gray)
    if (sr == 0).any() or (sc == 0).any():
        # Unreadable gaps: keep the largest block of the grid between them.
        a, b = _longest_run(sr > 0)
        c, d = _longest_run(sc > 0)
        if b - a < 1 or d - c < 1:
            return None
        grid, sr, sc = grid[a:b + 1, c:d + 1], sr[a:b], sc[c:d]
    if (sr == 1).all() and (sc == 1).all():
        return _place(grid, cols, rows, gray)
    full, real = expand(grid, sr, sc)
    placed = _place(np.concatenate([full, real[..., None]], -1), cols, rows, gray)
    if placed is None:
        return None
    ids, pts = placed
    keep = pts[:, 2] > 0.5
    return ids[keep], pts[keep, :2]


def _place(grid: np.ndarray, cols: int, rows: int, gray: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """place_grid on a one-square lattice (h, w, C): channels beyond x, y ride along."""
    grid = right_handed(grid)
    sign = cell_brightness_sign(grid[..., :2], gray)
    H, W = grid.shape[:2]
    cell_parity = np.indices((max(H - 1, 1), max(W - 1, 1))).sum(0) % 2  # (H-1, W-1)
    for k in (0, 2, 1, 3):  # prefer the detector's own orientation, then its 180° turn
        g = np.rot90(grid, k, axes=(0, 1))
        h, w = g.shape[:2]
        if h > rows or w > cols:
            continue
        # The new cell (0, 0) was one of the old corner cells: its parity decides its colour.
        corner_parity = np.rot90(cell_parity, k)[0, 0]
        bright = sign if corner_parity == 0 else -sign
        r0 = c0 = 0
        if bright < 0:  # cell (0,0) dark: it must sit at an odd (r0 + c0)
            if w + 1 <= cols:
                c0 = 1
            elif h + 1 <= rows:
                r0 = 1
            else:
                continue  # a full-size grid with the wrong colour: try the other turn
        r, c = np.indices((h, w))
        ids = ((r + r0) * cols + (c + c0)).ravel()
        return ids, g.reshape(h * w, -1).astype(np.float64)
    if sign != 0:  # colours ambiguous or misread: place it anyway rather than lose the view
        for k in (0, 1):
            g = np.rot90(grid, k, axes=(0, 1))
            h, w = g.shape[:2]
            if h <= rows and w <= cols:
                r, c = np.indices((h, w))
                return (r * cols + c).ravel(), g.reshape(h * w, -1).astype(np.float64)
    return None
