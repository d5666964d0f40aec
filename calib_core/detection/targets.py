"""Every board of a calibration object in one image (``freecal.target/1``).

Boards with markers (ChArUco, AprilGrid) are found by their own marker ids,
from one marker detection per dictionary, so each is labelled by what it
shows. Their regions are then masked, and plain chessboards are looked for
in what is left, size by size, as many times as the target has boards of
that size (each found one masked before the next search).

A plain chessboard is *decided* (placed on its face of the object) only
when the image alone can tell which board and which way round it is: the
target has one board of that size, the whole board is found, it is not
square and its corner count across plus down is odd (so its two 180° turns
have differently coloured corner squares). Otherwise it is kept as a planar
view of its own (``placed`` false), as is every board the target gives no
pose (a loose board).

``ImageResult.ids``/``points`` are then the object's view: target corner ids
(``Target``: board k's corner i is ``offset_k + i``) of every placed board.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..target import Target, TargetBoard
from .detect_image import MIN_CORNERS, ImageResult, detect_gray, on_file
from .markers import Markers, family, seen_instead

MASK_MARGIN = 1.0   # a found board's region, grown by this many of its squares, is hidden from later searches


@dataclass
class BoardHit:
    """One board of the target in one image: found (``ids``, ``points``: the
    board's own corner ids and pixels) or not (``reason``)."""

    board: int | None      # index into target.boards; None: one of several chessboards of a size
    label: str
    ids: np.ndarray | None = None
    points: np.ndarray | None = None
    placed: bool = False   # in the object's view (a fixed board, identified)
    reason: str = ""

    @property
    def n_corners(self) -> int:
        return 0 if self.ids is None else len(self.ids)

    def to_json(self) -> dict:
        return {"name": self.label, "n_corners": self.n_corners, "placed": self.placed, "reason": self.reason}


def detect_target_file(path: str | Path, target: Target, name: str | None = None) -> ImageResult:
    return on_file(path, name, lambda gray, _circle: detect_target(gray, target))


def _others_seen(gray: np.ndarray, board: TargetBoard, target: Target, markers: Markers) -> bool:
    """Board ``board`` found no marker of its dictionary, and the markers the image shows
    instead are of a dictionary another board of the target uses: that board is in view, this
    one is not (the reason would have been "check the board's dictionary")."""
    dictionary = str(board.spec.dictionary)
    if markers.all(dictionary, 2 if board.spec.type == "aprilgrid" else 1)[1].size:
        return False
    seen = seen_instead(gray, dictionary, markers)
    return seen is not None and any(
        o is not board and o.spec.n_markers and family(str(o.spec.dictionary)) == family(seen[0]) for o in target.boards)


def detect_target(gray: np.ndarray, target: Target) -> ImageResult:
    """Every board of ``target`` in a greyscale image (H, W) uint8. Never raises on an image."""
    h, w = gray.shape[:2]
    markers = Markers(gray)
    hits: list[BoardHit] = []
    hidden = gray.copy()
    for k, b in enumerate(target.boards):
        if b.spec.type == "chessboard":
            continue
        res = detect_gray(gray, b.spec, markers=markers)
        if res.status == "used" and res.ids is not None and res.points is not None:
            hits.append(BoardHit(k, b.name, res.ids, res.points, placed=b.fixed))
            _hide(hidden, res.points)
        elif res.reason.startswith("board not found: no markers of this board") or _others_seen(gray, b, target, markers):
            first = b.spec.first_marker  # the markers the image shows are other boards' of the target
            hits.append(BoardHit(k, b.name, reason=f"not in view (none of its markers, ids {first}-"
                                                    f"{first + b.spec.n_markers - 1} of {b.spec.dictionary}, decoded)"))
        else:
            hits.append(BoardHit(k, b.name, reason=res.reason))
    hits += _chessboards(hidden, target)
    return _result(target, hits, w, h)


def _chessboards(gray: np.ndarray, target: Target) -> list[BoardHit]:
    """The target's plain chessboards, size by size; ``gray`` is masked as they are found."""
    sizes: dict[tuple[int, int], list[int]] = {}
    for k, b in enumerate(target.boards):
        if b.spec.type == "chessboard":
            sizes.setdefault((b.spec.cols, b.spec.rows), []).append(k)
    hits = []
    for (cols, rows), members in sizes.items():
        spec = target.boards[members[0]].spec
        for n in range(len(members)):
            res = detect_gray(gray, spec, classic_first=False)
            if res.status != "used" or res.ids is None or res.points is None:
                missing = members if len(members) == 1 else members[n:]
                hits += [BoardHit(k, target.boards[k].name, reason=res.reason) for k in missing]
                break
            decided = (len(members) == 1 and len(res.ids) == spec.n_corners and cols != rows
                       and (cols + rows) % 2 == 1)
            if decided:
                k = members[0]
                hits.append(BoardHit(k, target.boards[k].name, res.ids, res.points, placed=target.boards[k].fixed))
            else:  # the one board of its size is still known by name; which of several is not
                which: int | None = members[0] if len(members) == 1 else None
                label = target.boards[members[0]].name if which is not None else f"chessboard {cols}x{rows} #{n + 1}"
                hits.append(BoardHit(which, label, res.ids, res.points,
                                     reason=_undecided(len(members), len(res.ids), spec.n_corners, cols, rows)))
            _hide(gray, res.points)
    return hits


def _undecided(same_size: int, found: int, total: int, cols: int, rows: int) -> str:
    if same_size > 1:
        why = f"the target has {same_size} chessboards of this size, and a chessboard does not say which it is"
    elif found < total:
        why = f"only {found} of its {total} corners are seen, and a partial chessboard does not say which they are"
    else:
        why = f"a {cols}x{rows} chessboard looks the same turned round, so its place on the object cannot be told"
    return f"kept as a view of its own: {why}"


def _hide(gray: np.ndarray, points: np.ndarray) -> None:
    """Paint a found board's region (its corners' hull, grown by MASK_MARGIN squares) a flat grey."""
    if len(points) < 3:
        return
    hull = cv2.convexHull(points.astype(np.float32)).reshape(-1, 2)
    d = np.linalg.norm(points[:, None] - points[None], axis=2)
    np.fill_diagonal(d, np.inf)
    square = float(np.median(d.min(axis=1)))
    centre = hull.mean(axis=0)
    out = hull - centre
    grown = centre + out * (1 + MASK_MARGIN * square / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-9))
    cv2.fillConvexPoly(gray, np.rint(grown).astype(np.int32), int(np.median(gray)))


def _result(target: Target, hits: list[BoardHit], w: int, h: int) -> ImageResult:
    ids_of, pts_of = [], []
    for x in hits:
        if x.placed and x.board is not None and x.ids is not None and x.points is not None:
            ids_of.append(x.ids + target.boards[x.board].offset)
            pts_of.append(x.points)
    own = sum(x.n_corners for x in hits if not x.placed and x.n_corners >= MIN_CORNERS)
    res = ImageResult("", "rejected", sum(x.n_corners for x in hits), "", None, w, h, boards=hits)
    if ids_of:
        ids, pts = np.concatenate(ids_of), np.concatenate(pts_of)
        order = np.argsort(ids, kind="stable")
        res.ids, res.points = ids[order].astype(np.int64), pts[order].astype(np.float64)
    n_object = 0 if res.ids is None else len(res.ids)
    if n_object >= MIN_CORNERS or own:
        res.status = "used"
        if n_object < MIN_CORNERS:
            res.ids = res.points = None
        return res
    found = [x for x in hits if x.n_corners]
    res.reason = ("no board of the target found: " + "; ".join(f"{x.label}: {x.reason}" for x in hits)
                  if not found else
                  f"too few corners ({res.n_corners} found on {', '.join(x.label for x in found)}, need at least "
                  f"{MIN_CORNERS})")
    return res
