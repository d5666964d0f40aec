"""How far detected corners are from reference corners (ground truth or another detector).

Corners are matched by position, not by id: a partial plain chessboard's ids are
only defined up to a shift of the board lattice (see ``grid.py``), so ids are
checked separately, as one lattice motion per view (``lattice_agreement``).
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from ..observations import Observations

MATCH_PX = 1.0  # a detected corner further than this from every reference corner is wrong

# The 8 motions of the square lattice (4 rotations, each with and without a mirror).
_ROTS = [np.eye(2), np.array([[0, -1], [1, 0]]), -np.eye(2), np.array([[0, 1], [-1, 0]])]
MOTIONS = _ROTS + [r @ np.diag([1, -1]) for r in _ROTS]


def lattice_agreement(ours: np.ndarray, ref: np.ndarray) -> float:
    """Largest fraction of (col, row) pairs ours (N, 2) → ref (N, 2) that one lattice
    motion (rotation/mirror + integer shift) maps onto each other; 1.0 is a consistent grid."""
    if len(ours) == 0:
        return 1.0
    best = 0
    for rot in MOTIONS:
        _, counts = np.unique(np.rint(ref - ours @ rot.T).astype(np.int64), axis=0, return_counts=True)
        best = max(best, int(counts.max()))
    return best / len(ours)


def corner_errors(detected: Observations, reference: Observations, cols: int | None = None) -> dict[str, Any]:
    """Distances (px) from each detected corner to the nearest reference corner of the same view.

    Views are paired by name; views missing from either side are counted, not compared.
    With ``cols`` (chessboard inner corners per row, both sides' ids), also the worst
    per-view lattice agreement of the ids. Returns ``{"median", "p95", "max", "n",
    "n_wrong" (> MATCH_PX), "views", "min_lattice_agreement", "distances"}``.
    """
    ref = {v.name: v for v in reference.views}
    dists, agree, views = [], [], 0
    for v in detected.views:
        r = ref.get(v.name)
        if r is None or len(r) == 0:
            continue
        views += 1
        d, j = cKDTree(r.image_points).query(v.image_points)
        dists.append(d)
        if cols and v.ids is not None and r.ids is not None:
            m = d < MATCH_PX
            agree.append(lattice_agreement(np.stack([v.ids[m] % cols, v.ids[m] // cols], 1),
                                           np.stack([r.ids[j[m]] % cols, r.ids[j[m]] // cols], 1)))
    d = np.concatenate(dists) if dists else np.zeros(0)
    stats = (float(np.median(d)), float(np.percentile(d, 95)), float(d.max())) if d.size else (np.nan,) * 3
    return {"median": stats[0], "p95": stats[1], "max": stats[2], "n": int(d.size),
            "n_wrong": int(np.sum(d > MATCH_PX)), "views": views,
            "min_lattice_agreement": min(agree) if agree else None, "distances": d}


def best_motion(ours: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The lattice motion (rotation/mirror (2, 2), integer shift (2,)) mapping most of
    ours (N, 2) onto ref (N, 2) (col, row) pairs; None without pairs."""
    best = None
    for rot in MOTIONS:
        t, counts = np.unique(np.rint(ref - ours @ rot.T).astype(np.int64), axis=0, return_counts=True)
        k = int(counts.argmax())
        if best is None or counts[k] > best[0]:
            best = (int(counts[k]), rot, t[k])
    return None if best is None else (best[1], best[2])


def same_id_errors(detected: Observations, reference: Observations, cols: int) -> dict[str, Any]:
    """Distance (px) from each detected corner to the reference corner of the *same* board
    corner, ids mapped through the view's lattice motion (found from corners within
    MATCH_PX). Corners the reference has no counterpart for are counted apart
    (``n_unreferenced``): a reference detector that missed a corner does not make ours wrong.
    Returns ``{"distances", "n", "n_unreferenced", "views"}``."""
    ref = {v.name: v for v in reference.views}
    dists, extra, views = [], 0, 0
    for v in detected.views:
        r = ref.get(v.name)
        if r is None or len(r) == 0 or len(v) == 0 or v.ids is None or r.ids is None:
            continue
        views += 1
        d, j = cKDTree(r.image_points).query(v.image_points)
        m = d < MATCH_PX
        ours = np.stack([v.ids % cols, v.ids // cols], 1)
        theirs = np.stack([r.ids % cols, r.ids // cols], 1)
        motion = best_motion(ours[m], theirs[j[m]]) if m.any() else None
        if motion is None:
            extra += len(v)
            continue
        mapped = ours @ motion[0].T + motion[1]
        lookup = {(int(a), int(b)): k for k, (a, b) in enumerate(theirs)}
        k = np.array([lookup.get((int(a), int(b)), -1) for a, b in mapped])
        has = k >= 0
        dists.append(np.linalg.norm(v.image_points[has] - r.image_points[k[has]], axis=1))
        extra += int((~has).sum())
    d = np.concatenate(dists) if dists else np.zeros(0)
    return {"distances": d, "n": int(d.size), "n_unreferenced": extra, "views": views}
