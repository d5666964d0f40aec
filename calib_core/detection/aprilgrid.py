"""Kalibr's AprilGrid: AprilTags 36h11 with black squares at their corners.

Layout, as Kalibr builds it (``GridCalibrationTargetAprilgrid.cpp``,
``kalibr_create_target_pdf``): ``X × Y`` tags of edge ``s`` (the black
border included, two bits wide), ``g = spacing · s`` apart; tag ``t`` sits at
column ``t % X``, row ``t // X``, counted from the **bottom-left** of the
printed page, with its lower-left corner at ``(col, row) · (1 + spacing) · s``.
Its four corners are points of a ``2X × 2Y`` lattice, numbered row-major
from the bottom-left: point ``r · 2X + c`` at
``x = (c // 2)(1 + spacing) s + (c % 2) s``, ``y`` likewise with ``r``
(page frame: x right, y **up**, z out of the page, as Kalibr's).

Kalibr draws each tag turned by 180° from the AprilTag image OpenCV
generates for that id (checked bit by bit), so OpenCV's marker corners
0, 1, 2, 3 (its top-left, top-right, bottom-right, bottom-left) are, on
the page, the tag's bottom-right, bottom-left, top-left and top-right:
``CORNER_OFFSETS`` below.
"""
from __future__ import annotations

import numpy as np

from ..board import BoardSpec
from . import corner_refine
from .markers import Markers, homographies, layout_verdict, why_none, wrong_layout_reason

BORDER_BITS = 2   # Kalibr's tags have a two-bit black border (OpenCV's default is one)


def corner_ids(tag_ids: np.ndarray, tag_cols: int) -> np.ndarray:
    """Kalibr's point indices (T, 4) of OpenCV's four corners of tags ``tag_ids`` (T,),
    counted from the board's first tag."""
    tag_ids = np.asarray(tag_ids, dtype=np.int64).reshape(-1)
    cols = 2 * tag_cols
    base = (tag_ids // tag_cols) * 2 * cols + (tag_ids % tag_cols) * 2     # the tag's lower-left point
    return base[:, None] + np.array([1, 0, cols, cols + 1])[None, :]


REFINE_SHARE = 0.15   # refinement half-window over the tag's shortest edge in px: inside the two-bit border (0.2)
# How far the refinement may move OpenCV's tag corner: the black corner squares touch each tag
# at its corners, so OpenCV's outline of the tag is cut there and its corners land up to a tenth
# of the tag off (rendered: 2.7 px on 40 px tags); within 0.15 of the tag the X-junction is the
# only one (the border is 0.2 of the tag wide, the corner square the spacing ratio of it).
MAX_SHIFT_SHARE = 0.12


def detect(gray: np.ndarray, board: BoardSpec, markers: Markers | None = None):
    """(ids (N,), pixels (N, 2), reason if none) of an AprilGrid in ``gray``.

    OpenCV finds the tags (two-bit border); each tag's corners are polished
    where the tag's black border meets its corner square (an X-junction):
    cornerSubPix, then the saddle fit, with a window inside the border
    (Kalibr itself refines with cornerSubPix, a 5 x 5 window)."""
    found = markers or Markers(gray)
    dictionary = str(board.dictionary)
    corners, tags = found.of(dictionary, board.first_marker, board.n_markers, BORDER_BITS)
    if len(tags) == 0:
        return None, None, "board not found: " + why_none(gray, dictionary, BORDER_BITS, board.first_marker,
                                                          board.n_markers, found)
    once = np.flatnonzero(np.bincount(tags - board.first_marker)[tags - board.first_marker] == 1)
    corners, tags = corners[once], tags[once]     # a tag id seen twice: a stray tag, neither is trusted
    keep, wrong = layout_check(board, corners, tags - board.first_marker)
    if wrong:
        return None, None, (wrong_layout_reason(f"{len(tags)} tags", f"{board.cols} × {board.rows} AprilGrid", "tags")
                            + " and its spacing ratio")
    corners, tags = corners[keep], tags[keep]      # a misread tag goes alone
    ids = corner_ids(tags - board.first_marker, board.cols).reshape(-1)
    raw = corners.reshape(-1, 2).astype(np.float64)
    sides = np.linalg.norm(corners - np.roll(corners, 1, axis=1), axis=2)   # (T, 4) px
    edge = sides.mean(axis=1)
    # The window from the tag's shortest side: seen 60-70° off face-on, one from the mean reached past
    # the border into the bits, and cornerSubPix settled 5 px off (28 of 64 corners kept; 62 so)
    half = np.repeat(np.clip(np.rint(REFINE_SHARE * sides.min(axis=1)), 2, 10).astype(int), 4)
    h, w = gray.shape[:2]
    inside = np.all((raw >= half[:, None] + 1) & (raw <= np.array([w, h]) - 2 - half[:, None]), axis=1)
    ids, raw, half = ids[inside], raw[inside], half[inside]
    pts = corner_refine.refine(gray, raw, half)
    pts, det, sure = corner_refine.saddle_points(gray, pts, half)
    keep = (det < 0) & sure & (np.linalg.norm(pts - raw, axis=1) <= 0.5 + MAX_SHIFT_SHARE * np.repeat(edge, 4)[inside])
    if not keep.any():
        return None, None, f"too few corners (0 of {len(raw)} tag corners confirmed)"
    refined = np.full((len(tags) * 4, 2), np.nan)
    refined[np.flatnonzero(inside)[keep]] = pts[keep]
    whole = np.all(np.isfinite(refined.reshape(-1, 4, 2)), axis=(1, 2))
    gap = spacing_seen(board, tags[whole] - board.first_marker, refined.reshape(-1, 4, 2)[whole])
    if abs(gap - float(board.tag_spacing or 0.0)) > SPACING_TOLERANCE:  # NaN (too few pairs): not judged
        return None, None, (f"board not found: its tags are {gap:.2f} of a tag apart, the board's spec says "
                            f"{board.tag_spacing:g}: check the spacing ratio (the spec's fourth field, Kalibr's "
                            "tagSpacing)")
    return ids[keep], pts[keep], ""


# A tag's homography, from its four corners, puts a board neighbour's two nearest corners (a
# spacing away) within this share of the neighbour's size; measured on 1 428 pairs of rendered
# random grids: 0.25 at most, 0.02 at the median. A grid of another width puts them a tag away.
AGREE = 0.35
MIN_PAIRS = 4  # pairs of neighbouring tags that measure the gap between tags
# The gap between tags the refined corners show, against the spec's, in tag edges: on 94 random
# grids through the six synthetic lenses (benchmarks boards' draws) within 0.010 of the spec, and
# at least 0.040 off for a spec 0.05 wrong. A wrong spacing (0.2 for a 0.3 print) otherwise
# calibrated at 2-5 px.
SPACING_TOLERANCE = 0.025


def layout_check(board: BoardSpec, corners: np.ndarray, tags: np.ndarray) -> tuple[np.ndarray, bool]:
    """(keep (T,), wrong layout) of decoded tags (pixels (T, 4, 2), indices from the board's
    first) (``markers.layout_verdict``), each pair two tags side by side on the board."""
    obj, first, second = _side_by_side(board, tags)
    px = corners.astype(np.float64)
    h = homographies(obj[first], px[first])
    q = np.einsum("pij,pkj->pki", h, np.concatenate([obj[second], np.ones((len(second), 4, 1))], axis=2))
    miss = np.linalg.norm(q[..., :2] / q[..., 2:] - px[second], axis=-1)              # (P, 4)
    nearest = np.argsort(np.linalg.norm(obj[second] - obj[first].mean(axis=1)[:, None], axis=-1), axis=1)[:, :2]
    x, y = px[second][..., 0], px[second][..., 1]
    size = np.sqrt(np.abs(0.5 * np.sum(x * np.roll(y, -1, axis=1) - np.roll(x, -1, axis=1) * y, axis=1)))
    agree = np.take_along_axis(miss, nearest, axis=1).mean(axis=1) < AGREE * size
    return layout_verdict(first, second, agree, len(tags))


def _side_by_side(board: BoardSpec, tags: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Board points (T, 4, 2) of OpenCV's corners of ``tags`` (T,), and the pairs (first, second)
    of tags side by side on the board."""
    obj = board.object_points(corner_ids(tags, board.cols).reshape(-1))[:, :2].reshape(len(tags), 4, 2)
    row, col = tags // board.cols, tags % board.cols
    first, second = np.nonzero(np.abs(row[:, None] - row[None]) + np.abs(col[:, None] - col[None]) == 1)
    return obj, first, second


def spacing_seen(board: BoardSpec, tags: np.ndarray, px: np.ndarray) -> float:
    """The gap between neighbouring tags, in tag edges, that the image shows, from tags whose
    four refined corners ``px`` (T, 4, 2) were all found: each pair of tags side by side, the
    second taken back onto the board through the first's homography, its two corners nearest
    the first moved along the pair from where the spec puts them; the median move over the
    pairs, added to the spec's spacing. NaN with fewer than MIN_PAIRS pairs."""
    obj, first, second = _side_by_side(board, tags)
    if len(first) < MIN_PAIRS:
        return float("nan")
    h = homographies(obj[first], px[first])
    back = np.einsum("pij,pkj->pki", np.linalg.inv(h), np.concatenate([px[second], np.ones((len(second), 4, 1))], axis=2))
    back = back[..., :2] / back[..., 2:]
    along = obj[second].mean(axis=1) - obj[first].mean(axis=1)
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    nearest = np.argsort(np.linalg.norm(obj[second] - obj[first].mean(axis=1)[:, None], axis=-1), axis=1)[:, :2]
    moved = np.einsum("pkj,pj->pk", np.take_along_axis(back - obj[second], nearest[..., None], axis=1), along)
    return float(float(board.tag_spacing or 0.0) + np.median(moved) / board.square_size)
