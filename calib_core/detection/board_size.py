"""The chessboard's size as the photos show it: to catch a board given with the wrong size.

Two mistakes are common: squares counted instead of inner corners (16 × 10 for a 15 × 9
board), and another board's size (9 × 6, OpenCV's sample, for a 15 × 9 board). Neither can
be seen from the size given alone, but the photos tell: a grid grown without a size limit
(``visible_grid``: a small seed found by OpenCV, grown by ``grow.grow_board`` over
the whole visible lattice, which stops at the board's white border) spans the board's
inner corners wherever the whole board is in view. The board's size is the most common
complete grid over the photos (partial views, cut by the image's edge, vary and do not
outvote it).

``suggest_size`` judges a detection: a size given too large shows in the corners already
found (no view reaches the size given, and most views are complete grids of one smaller
size); a size given too small (or another board) makes most photos fail, and the photos
are then probed with ``visible_grid``; or the detector finds the smaller grid inside the
board, which a probe of a few photos shows (a larger complete grid in most of them). Cheap:
the first costs nothing, a probe about 0.3 s a photo (GoPro, 1000 × 750).
"""
from __future__ import annotations

import concurrent.futures as cf
import os
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..board import MAX_SIDE, BoardSpec
from ..observations import View

SEEDS = (4, 5, 3)        # seed grids tried in turn, as for partial boards (detect_image._grown_grid)
MIN_SHARE = 0.4          # of the views or photos that must show the suggested grid whole
MIN_PHOTOS = 2
COMPLETE = 0.9           # share of a grid's positions found for it to count as the whole board
MAX_PROBES = 40          # photos probed at most (spread over the set): enough to find the mode
SAMPLE = 4               # photos probed when the board was found: is it larger than the size given?


@dataclass(frozen=True)
class SizeSuggestion:
    cols: int            # inner corners across
    rows: int            # inner corners down
    n_photos: int        # photos (or views) in which the whole grid of that size was seen
    n_images: int        # photos looked at

    def board(self, given: BoardSpec) -> BoardSpec:
        """The board given, with this size."""
        return BoardSpec.parse(f"chessboard:{self.cols}x{self.rows}:{given.square_size:g}mm")

    def message(self, given: BoardSpec) -> str:
        """What was found, in words that fit any place (no command-line flag, no form field)."""
        return (f"the photos show a chessboard of {self.cols} × {self.rows} inner corners (the whole grid in "
                f"{self.n_photos} of {self.n_images} photos), not {given.cols} × {given.rows}: its size is "
                "counted in inner corners (where four squares meet), one less than the squares each way")


def visible_grid(gray: np.ndarray) -> tuple[int, int, int] | None:
    """(cols, rows, corners found) of the chessboard lattice seen in a greyscale image, cols ≥ rows,
    whatever its declared size; None when no chessboard is found."""
    import cv2

    from .detect_image import MIN_LATTICE_SCORE, SB_FLAGS
    from .grid import expand, gap_strides, lattice_score, place_grid
    from .grow import grow_board

    for n in SEEDS:
        cv2.setRNGSeed(0x5EED)
        ok, corners, meta = cv2.findChessboardCornersSBWithMeta(gray, (n, n), SB_FLAGS | cv2.CALIB_CB_LARGER)
        if not (ok and meta is not None and meta.size == corners.shape[0]):
            continue
        grid = corners.reshape(*meta.shape, 2).astype(np.float64)
        sr, sc = gap_strides(grid, gray)
        if (sr == 0).any() or (sc == 0).any() or lattice_score(expand(grid, sr, sc)[0], gray) < MIN_LATTICE_SCORE:
            continue
        placed = place_grid(grid, MAX_SIDE, MAX_SIDE, gray)
        if placed is None:
            continue
        grown = grow_board(gray, *placed, MAX_SIDE, MAX_SIDE)
        return _extent(grown.ids, MAX_SIDE)
    return None


def probe_file(path: str | Path) -> tuple[int, int, int] | None:
    """``visible_grid`` of an image file (None if it cannot be read); never raises. A photo of
    more than REDUCE_ABOVE pixels is probed on a reduced copy, as detection works on one: the
    lattice's size does not change with the scale, and the sector-based search on a blank 49 MP
    photo held the worker for minutes."""
    import cv2

    from .detect_image import REDUCE_ABOVE, REDUCED_PIXELS, read_gray

    try:
        gray = read_gray(path)
        if gray is None:
            return None
        h, w = gray.shape[:2]
        if h * w >= REDUCE_ABOVE:
            k = float(np.sqrt(REDUCED_PIXELS / (h * w)))
            gray = cv2.resize(gray, (round(w * k), round(h * k)), interpolation=cv2.INTER_AREA)
        return visible_grid(gray)
    except Exception:  # a photo the probe cannot read tells nothing: the others decide
        return None


def suggest_size(board: BoardSpec, views: Sequence[View], n_images: int, paths: Sequence[Path] = (),
                 workers: int | None = None) -> SizeSuggestion | None:
    """The board's size the photos show, when it is not ``board``'s; None when they agree or cannot tell.

    ``views``: the corners detected with ``board`` (ids on it); ``paths``: the photos, probed when
    the board was found in fewer than half of the ``n_images`` photos."""
    if board.type != "chessboard":
        return None
    if len(views) * 2 >= n_images:
        found = _too_large(board, views)
        if found is not None or not paths:
            return found
        # a size given too small is found too, as a part of the board: a few photos tell
        sample = _probe_all(_spread(paths, SAMPLE), workers)
        larger = [g for g in sample if g is not None and g[0] * g[1] > board.cols * board.rows]
        if len(larger) * 2 <= len(sample):
            return None
    if not paths:
        return None
    grids = _probe_all(_spread(paths, MAX_PROBES), workers)
    return _mode(board, [g for g in grids if g is not None], len(grids))


def _spread(paths: Sequence[Path], n: int) -> list[Path]:
    """At most ``n`` of the photos, spread over the set."""
    step = max(1, -(-len(paths) // n))
    return list(paths)[::step][:n]


def _too_large(board: BoardSpec, views: Sequence[View]) -> SizeSuggestion | None:
    """Corners found on a board given larger than it is: no view reaches its size, most are one smaller grid."""
    grids = [_extent(v.ids, board.cols) for v in views if v.ids is not None and len(v.ids)]
    given = (max(board.cols, board.rows), min(board.cols, board.rows))
    if not grids or any((c, r) == given for c, r, _ in grids):
        return None
    return _mode(board, grids, len(views))


def _mode(board: BoardSpec, grids: list[tuple[int, int, int]], n_images: int) -> SizeSuggestion | None:
    """The most common complete grid, if enough photos show it and it is not the board given."""
    complete = Counter((c, r) for c, r, n in grids if n >= COMPLETE * c * r and r >= 2)
    if not complete:
        return None
    (c, r), count = complete.most_common(1)[0]
    if count < max(MIN_PHOTOS, MIN_SHARE * n_images):
        return None
    if (c, r) == (max(board.cols, board.rows), min(board.cols, board.rows)):
        return None
    if board.cols < board.rows:  # keep the orientation the size was given in
        c, r = r, c
    return SizeSuggestion(c, r, count, n_images)


def _extent(ids: np.ndarray, cols: int) -> tuple[int, int, int]:
    """(columns, rows, corners) spanned by corner ids of a board ``cols`` wide, larger side first."""
    r, c = np.divmod(np.asarray(ids, int), cols)
    a, b = int(np.ptp(c)) + 1, int(np.ptp(r)) + 1
    return max(a, b), min(a, b), len(ids)


def _probe_all(paths: list[Path], workers: int | None) -> list[tuple[int, int, int] | None]:
    from .detect import _context, _init_worker, worker_logging

    n = max(1, min(workers or os.cpu_count() or 1, len(paths)))
    if n > 1:
        try:
            with cf.ProcessPoolExecutor(n, mp_context=_context(), initializer=_init_worker,
                                        initargs=worker_logging()) as pool:
                return list(pool.map(probe_file, [str(p) for p in paths]))
        except (OSError, NotImplementedError, cf.process.BrokenProcessPool, RuntimeError):
            pass  # no pool here: probe in this process
    return [probe_file(p) for p in paths]
