"""Board corners in one image: decode, find, refine, judge. Never raises.

Runs on worker threads or in worker processes, so it takes a path and returns plain data.
Chessboards: OpenCV's classic detector on the full pattern first (fast), then
``findChessboardCornersSBWithMeta`` with ``CALIB_CB_LARGER`` from a small seed,
which grows over whatever part of the board is visible (partial boards), then
the sector-based one on the full pattern. ChArUco: ``cv2.aruco.CharucoDetector``,
whose ids are absolute, so partial boards come naturally; AprilGrid: its tags'
corners (``aprilgrid.py``). Markers are found once per image and dictionary
(``markers.py``), so several boards of one image share them (``targets.py``).
"""
from __future__ import annotations

import logging
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np

from ..board import BoardSpec
from ..evaluation.coverage import Circle
from . import aprilgrid, charuco
from .grid import expand, gap_strides, lattice_score, place_grid
from .grow import grow_board
from .image_circle import find_image_circle
from .markers import Markers
from .model_guided import model_guided

if TYPE_CHECKING:
    from .targets import BoardHit

log = logging.getLogger("freecal.detect")

MIN_CORNERS = 6            # fewer cannot constrain a view's pose and the lens together
MIN_SIDE = 32              # px: a narrower image cannot show the smallest board's squares a few pixels wide
MAX_EDGE_WIDTH = 8.0       # px, black-to-white transition; OpenCV calls < 3 sharp
REDUCE_ABOVE = 12e6        # pixels: detect on a reduced copy above this ...
REDUCED_PIXELS = 3e6       # ... of about this many pixels, refine at full resolution
MAX_REFINE_SHIFT = 1.0    # px a final cornerSubPix may move a detector's corner
SB_FLAGS = cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY
# No CALIB_CB_NORMALIZE_IMAGE (OpenCV's default adds it): its histogram equalisation turns a
# flat, grainy background into thousands of small quads, and the classic detector then spends
# 7-10 s a photo failing on a board it cannot see whole (1280 x 960, partial or white-on-black
# boards); without it 0.4-0.6 s. On the real sets it finds as many boards or more (GoPro: the
# two it missed) in half the time (docs/detection.md, "The classic detector's flags").
CLASSIC_FLAGS = cv2.CALIB_CB_ADAPTIVE_THRESH
MIN_LATTICE_SCORE = 0.8   # share of grid cells that must read as one checker square
SEEDS = (4, 5, 3, 6)       # seed grid sizes for partial boards, tried in turn (see _grown_grid; 6: rendered fisheye view 2)
SUBPIX = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 40, 1e-3)


@dataclass
class ImageResult:
    """One image's outcome. ids (N,) int64 and points (N, 2) float64 when used."""

    name: str
    status: str
    n_corners: int
    reason: str
    sharpness: float | None = None
    width: int | None = None
    height: int | None = None
    ids: np.ndarray | None = None
    points: np.ndarray | None = None
    model_added: int | None = None   # corners the re-detection through a calibration added
    boards: list[BoardHit] | None = None   # a target's boards, found or not (targets.py); ids/points: the object's
    image_circle: Circle | None = None   # a fisheye's lit disc (cx, cy, r), None: lit to the border


def read_gray(path: str | Path) -> np.ndarray | None:
    """8-bit greyscale image (H, W), or None if it cannot be decoded.

    EXIF orientation is ignored on purpose: calibration is of the sensor's
    pixel grid, and every image of a set must share it.
    """
    try:
        data = np.fromfile(str(path), dtype=np.uint8)  # unlike imread, copes with any path encoding
    except OSError:
        return None
    if data.size == 0:
        return None
    try:
        return cv2.imdecode(data, cv2.IMREAD_GRAYSCALE | cv2.IMREAD_IGNORE_ORIENTATION)
    except cv2.error as exc:
        if "MAX_IMAGE" not in str(exc):
            raise
        # OpenCV's decoding limit (OPENCV_IO_MAX_IMAGE_PIXELS: freecal sets it from FREECAL_MAX_IMAGE_PIXELS)
        limit = os.environ.get("OPENCV_IO_MAX_IMAGE_PIXELS", "OpenCV's default")
        raise TooManyPixels(f"more pixels than the limit of {limit} (FREECAL_MAX_IMAGE_PIXELS): downscale it, "
                            "or raise the limit") from None


class TooManyPixels(ValueError):
    """The image declares more pixels than OpenCV may decode here."""


def detect_file(path: str | Path, board: BoardSpec, name: str | None = None, model=None) -> ImageResult:
    """Detect the board in one image file; every failure becomes a rejected result.
    With a camera ``model`` (a first calibration's), every board corner is also predicted
    through it and confirmed (``model_guided``)."""
    # A fisheye whose image circle ends inside the frame bends a board's lines more than
    # OpenCV's classic detector follows, which then takes its longest to find nothing
    # (docs/detection.md, "Photos inside an image circle"): the sector-based seeds that
    # follow it find those boards, and growth covers them.
    return on_file(path, name, lambda gray, circle: detect_gray(gray, board, model, classic_first=circle is None))


def on_file(path: str | Path, name: str | None,
            detect: Callable[[np.ndarray, Circle | None], ImageResult]) -> ImageResult:
    """``detect(gray, image circle)`` on the greyscale image of one file; every failure
    becomes a rejected result."""
    name = name or Path(path).name
    try:
        try:
            gray = read_gray(path)
        except TooManyPixels as exc:
            return ImageResult(name, "rejected", 0, str(exc))
        if gray is None:
            return ImageResult(name, "rejected", 0, "could not decode the file as an image")
        h, w = gray.shape
        if min(h, w) < MIN_SIDE:
            return ImageResult(name, "rejected", 0, f"too small to show a board: {w} x {h} px (each side needs at "
                               f"least {MIN_SIDE} px)")
        circle = find_image_circle(gray)  # here, where every detector's image is decoded once
        res = detect(gray, circle)
        res.name = name
        res.image_circle = circle
        return res
    except Exception as exc:  # a detector crash on one image must not cost the others
        log.warning("detection failed on %s: %s: %s", name, type(exc).__name__, exc)  # the raw text: for the log
        return ImageResult(name, "rejected", 0, failure_reason(exc))


def failure_reason(exc: Exception) -> str:
    """Why one image failed, in words: OpenCV's own text ('OpenCV(5.0.0) /io/opencv/modules/...:
    error: (-215:Assertion failed) ...') names its build folder and an assertion, nothing a user can act on."""
    if isinstance(exc, MemoryError):
        return "not enough memory to process this image: upload a smaller one (fewer pixels)"
    what = "OpenCV could not process it" if isinstance(exc, cv2.error) else f"the detector failed ({type(exc).__name__})"
    return (f"detection failed: {what}; the file may be corrupt or an unusual variant of its format: "
            "re-save it as PNG or JPEG and upload it again")


def detect_gray(gray: np.ndarray, board: BoardSpec, model=None, markers: Markers | None = None,
                classic_first: bool = True) -> ImageResult:
    """Detect in a greyscale image (H, W) uint8; ``model``: as in ``detect_file``;
    ``markers``: the image's markers, shared with other boards of the same image
    (they must have been found on this image, reduced as here); ``classic_first``
    false: chessboards skip OpenCV's classic detector (several boards in one image
    hold it for seconds on the other boards' squares; a fisheye's image circle, see
    ``detect_file``)."""
    # The sector-based detector draws from OpenCV's global RNG: reseed so a
    # result depends on the image alone, not on which images a worker saw before.
    cv2.setRNGSeed(0x5EED)
    h, w = gray.shape[:2]
    scale = 1.0
    work = gray
    if h * w >= REDUCE_ABOVE:
        scale = float(np.sqrt(REDUCED_PIXELS / (h * w)))
        work = cv2.resize(gray, (round(w * scale), round(h * scale)), interpolation=cv2.INTER_AREA)
    markers = markers if markers is not None and markers.gray.shape == work.shape else Markers(work)
    if board.type == "chessboard":
        ids, pts, sharp, why = _chessboard(work, board, classic_first)
    elif board.type == "aprilgrid":
        ids, pts, why = aprilgrid.detect(work, board, markers)
        sharp = None
    else:
        ids, pts, why = charuco.detect(work, board, markers)
        sharp = None
    base = ImageResult("", "rejected", 0, why, None, w, h)
    if ids is None:
        return base
    if scale != 1.0:
        # Pixel centres: full = (reduced + 0.5) / scale - 0.5; refined below where the detail is.
        pts = (pts + 0.5) / scale - 0.5
        sharp = None if sharp is None else sharp / scale
    if board.type == "chessboard" or scale != 1.0:
        half = _refine_half_window(_spacing(pts, ids, board))
        # A grown (LARGER) grid extrapolates corners up to and past the image edge, where the
        # refinement window is cut and snaps onto whatever edge ends there: such corners are
        # not seen, so they are dropped.
        inside = np.all((pts >= half + 1) & (pts <= np.array([w, h]) - 2 - half), axis=1)
        ids, pts = ids[inside], pts[inside]
        # A final cornerSubPix at full resolution: on the BabelCalib fisheye set it takes
        # the corners within 0.5 px of the authors' reference from 81 % (SB alone) to 96 %.
        refined = _refine(gray, pts, half)
        # Where the two estimates disagree by more than a pixel one of them is wrong
        # (a tag or glare next to the corner): such a corner is dropped, not guessed.
        keep = np.linalg.norm(refined - pts, axis=1) <= MAX_REFINE_SHIFT / scale
        ids, pts = ids[keep], refined[keep]
    if board.type == "chessboard" and len(ids) >= MIN_CORNERS:
        # OpenCV's grids stop short of the visible board where distortion bends its lines:
        # grow them over all of it, and check every corner is an X-junction of the right colours.
        hook = None if model is None else model_guided(gray, model, board.square_size)
        grown = grow_board(gray, ids, pts, board.cols, board.rows, after_growth=hook)
        ids, pts = grown.astuple()
        if model is not None:
            base.model_added = grown.after_growth_added
    base.sharpness = sharp
    base.n_corners = len(ids)
    if len(ids) < MIN_CORNERS:
        base.reason = f"too few corners ({len(ids)} found, need at least {MIN_CORNERS})"
        return base
    if sharp is not None and sharp > MAX_EDGE_WIDTH:
        base.reason = (f"too blurry: edges are {sharp:.1f} px wide (sharpness score; at most "
                       f"{MAX_EDGE_WIDTH:g} px accepted, under 3 px is sharp)")
        return base
    order = np.argsort(ids, kind="stable")
    base.status, base.reason = "used", ""
    base.ids, base.points = ids[order].astype(np.int64), pts[order].astype(np.float64)
    return base


def _chessboard(gray: np.ndarray, board: BoardSpec, classic_first: bool = True):
    """(ids, points, edge width px, reason if none)."""
    cols, rows = board.cols, board.rows
    # The classic detector first: on whole boards it is ~100x faster than the sector-based
    # one, and after the final cornerSubPix (detect_gray) as accurate (rendered 9x6 views,
    # exact corners: median 0.037 px either way). The sector-based one then takes the
    # boards it misses (blur, strong distortion), grown from a small seed (partial boards,
    # and whole ones: a seed grows over all of a board the whole pattern misses). The whole
    # pattern comes last: on the 97 photos of the real and rendered sets it found no board
    # where the classic one failed, at 0.4-2 s a photo, and the seeds found one in each.
    grid = None
    ok, corners = cv2.findChessboardCorners(gray, (cols, rows), flags=CLASSIC_FLAGS) if classic_first else (False, None)
    if ok and corners is not None:
        corners = corners.reshape(-1, 2)
        half = _half_window(corners.reshape(rows, cols, 2))
        corners = cv2.cornerSubPix(gray, corners.astype(np.float32), (half, half), (-1, -1), SUBPIX)
        grid = corners.reshape(rows, cols, 2)
    if grid is None:
        grid = _grown_grid(gray, cols, rows)
    placed = None if grid is None else place_grid(grid.astype(np.float64), cols, rows, gray)
    if placed is None:
        # No grid, or a grown one the board cannot hold: a seed can grow over the board's
        # edge, where the outer squares meet the background in corners of their own (a
        # white-on-black board, a dark margin); the whole pattern's search stops at the board.
        ok, corners, meta = cv2.findChessboardCornersSBWithMeta(gray, (cols, rows), SB_FLAGS)
        if ok and meta is not None and meta.size == corners.shape[0]:
            whole = corners.reshape(*meta.shape, 2)
            placed = place_grid(whole.astype(np.float64), cols, rows, gray)
            grid = whole if placed is not None or grid is None else grid
    if grid is None:
        return None, None, None, "board not found"
    if placed is None:
        h, w = grid.shape[:2]
        sr, sc = gap_strides(grid.astype(np.float64), gray)
        if (sr > 0).all() and (sc > 0).all():  # on the board's lattice: a grid that skips lines, filled in
            h, w = int(sr.sum()) + 1, int(sc.sum()) + 1
        seen = f"board not found: the corner grid seen ({w} × {h})"
        if not _fits((h, w), cols, rows):
            return None, None, None, f"{seen} does not fit a {cols} × {rows} board; is the board's size right (inner corners)?"
        # It fits the board: what failed is reading its squares as black and white
        return None, None, None, (f"{seen} fits the board, but its squares do not read as a chessboard's black and "
                                  "white ones (markers inside them?): is it a ChArUco board or an AprilGrid?")
    sharp = _edge_width(gray, grid)
    return placed[0], placed[1], sharp, ""


def _grown_grid(gray: np.ndarray, cols: int, rows: int) -> np.ndarray | None:
    """Partial board: a grid (h, w, 2) grown from a small seed over whatever is visible.

    The grown grid depends on the seed size, and some seeds grow a grid that is not the
    board's lattice (rows skipping a varying number of board lines, or an axis running
    diagonally; seen on rendered views with exact corners). The next seed is tried until
    the grid, expanded to one square per cell, reads as a chessboard (``lattice_score``)
    and the board can hold it (a grid that skips every other line can expand past the
    board: 9 rows of an 8-row board); if none does, the board is not found rather than
    given wrong ids.
    """
    for n in SEEDS:
        seed = (min(n, cols), min(n, rows))
        cv2.setRNGSeed(0x5EED)
        ok, corners, meta = cv2.findChessboardCornersSBWithMeta(gray, seed, SB_FLAGS | cv2.CALIB_CB_LARGER)
        if not (ok and meta is not None and meta.size == corners.shape[0]):
            continue
        grid = corners.reshape(*meta.shape, 2).astype(np.float64)
        sr, sc = gap_strides(grid, gray)
        if (sr == 0).any() or (sc == 0).any():
            continue
        full = expand(grid, sr, sc)[0]
        if _fits(full.shape[:2], cols, rows) and lattice_score(full, gray) >= MIN_LATTICE_SCORE:
            return grid
    return None


def _fits(shape: tuple[int, ...], cols: int, rows: int) -> bool:
    """Does a lattice of shape (h, w) corners fit a cols × rows board, in some quarter turn?"""
    h, w = shape
    return (h <= rows and w <= cols) or (h <= cols and w <= rows)


def _edge_width(gray: np.ndarray, grid: np.ndarray) -> float | None:
    """Median black-to-white transition width (px) over the grid's edges.

    The median, not OpenCV's mean: OpenCV measures across the straight line between
    two corners, and under strong distortion a few curved edges read 15 px wide in a
    sharp image (rendered radial lens, close view).
    """
    h, w = grid.shape[:2]
    if h < 2 or w < 2:
        return None
    try:
        _, edges = cv2.estimateChessboardSharpness(gray, (w, h), grid.reshape(-1, 2).astype(np.float32), 0.8,
                                                   False, None)
    except cv2.error:
        return None
    if edges is None or len(edges) == 0:
        return None
    val = float(np.median(np.asarray(edges).reshape(len(edges), -1)[:, 2]))  # rows: x, y, width, min, max
    return val if np.isfinite(val) and val > 0 else None


def _half_window(grid: np.ndarray) -> int:
    """cornerSubPix half-window: a third of the smallest square, 2..11 px."""
    d = min(np.linalg.norm(np.diff(grid, axis=0), axis=-1).min(initial=np.inf) if grid.shape[0] > 1 else np.inf,
            np.linalg.norm(np.diff(grid, axis=1), axis=-1).min(initial=np.inf) if grid.shape[1] > 1 else np.inf)
    return int(np.clip(d / 3 if np.isfinite(d) else 5, 2, 11))


def _spacing(pts: np.ndarray, ids: np.ndarray, board: BoardSpec) -> float:
    """Smallest distance (px) between corners that are neighbours on the board."""
    c, _ = board.corner_grid
    order = np.argsort(ids)
    s, p = ids[order], pts[order]
    j = np.minimum(np.searchsorted(s, s + 1), len(s) - 1)
    ok = (s[j] == s + 1) & ((s + 1) % c != 0)  # right-hand neighbour exists on the same row
    if not ok.any():
        return 15.0
    return float(np.linalg.norm(p[j[ok]] - p[ok], axis=1).min())


def _refine_half_window(spacing: float) -> int:
    # A small window (a quarter square, >= 4 px) measured best: larger ones reach across
    # curved edges of strongly distorted squares and into the tags of tagged boards.
    return int(np.clip(spacing / 4, 4, 10))


def _refine(gray: np.ndarray, pts: np.ndarray, half: int) -> np.ndarray:
    """cornerSubPix of pts (N, 2) with a (2*half+1)² window; (N, 2) float64."""
    out = cv2.cornerSubPix(gray, pts.astype(np.float32).reshape(-1, 1, 2), (half, half), (-1, -1), SUBPIX)
    return out.reshape(-1, 2).astype(np.float64)
