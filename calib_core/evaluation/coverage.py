"""Where in the image the corners fall: a grid histogram and the empty regions.

Distortion is strongest at the edges and corners of the image; a calibration
with no data there extrapolates, so we say which of those regions are empty.
A fisheye whose image circle ends inside the frame has no light in the frame's
corners: there only the cells inside the circle count, and the regions named
are stretches of the circle's edge (``detection.image_circle`` finds it).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..observations import Circle

GRID_X = 8  # histogram cells across; down follows the aspect ratio
INSIDE_SHARE = 0.5  # a cell counts when at least this share of it lies inside the image circle
SAMPLES = 8  # per cell side, to measure that share

# The circle's edge in eight directions from its centre, counter-clockwise from the right (y up).
RIM_DIRECTIONS = ("right", "top-right", "top", "top-left", "left", "bottom-left", "bottom", "bottom-right")
RIM_SUFFIX = " of the image circle"


def coverage(points: np.ndarray, image_size: tuple[int, int], grid_x: int = GRID_X,
             circle: Circle | None = None) -> dict[str, Any]:
    """Histogram of corner pixels (N, 2) over a grid of the image (W, H).

    Returns ``{"grid": [gx, gy], "counts": gy rows of gx ints, "fraction_covered",
    "empty_regions": names}`` (counts[0] is the top row). With the lens's image
    ``circle``, also ``"image_circle": {"cx", "cy", "radius"}`` and ``"inside"`` (gy rows
    of gx bools: the cells that count); the fraction and the regions are of those cells.
    """
    w, h = image_size
    gx = grid_x
    gy = max(2, int(round(grid_x * h / w)))
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    counts, _, _ = np.histogram2d(pts[:, 1], pts[:, 0], bins=[gy, gx], range=[[-0.5, h - 0.5], [-0.5, w - 0.5]])
    counts = counts.astype(np.int64)
    out = {"grid": [gx, gy], "counts": counts.tolist()}
    if circle is None:
        return {**out, "fraction_covered": float(np.mean(counts > 0)), "empty_regions": empty_regions(counts)}
    inside = cells_inside(circle, (gx, gy), image_size)
    return {**out, "fraction_covered": float(np.mean(counts[inside] > 0)) if inside.any() else 0.0,
            "empty_regions": empty_rim(counts, inside, circle, image_size),
            "image_circle": circle_json(circle), "inside": inside.tolist()}


def empty_regions(counts: np.ndarray) -> list[str]:
    """Names of image corners (their cell empty) and edges (half their cells or more empty).

    counts: (gy, gx) histogram, row 0 at the top.
    """
    empty = counts == 0
    out = [name for name, cell in (("top-left corner", empty[0, 0]), ("top-right corner", empty[0, -1]),
                                   ("bottom-left corner", empty[-1, 0]), ("bottom-right corner", empty[-1, -1])) if cell]
    edges = {"top edge": empty[0, 1:-1], "bottom edge": empty[-1, 1:-1],
             "left edge": empty[1:-1, 0], "right edge": empty[1:-1, -1]}
    out += [name for name, cells in edges.items() if cells.size and cells.mean() >= 0.5]
    return out


def cells_inside(circle: Circle, grid: tuple[int, int], image_size: tuple[int, int]) -> np.ndarray:
    """(gy, gx) bool: the cells at least INSIDE_SHARE inside the circle (sampled on a
    SAMPLES² lattice per cell: a sliver of a cell cannot hold a corner's window)."""
    (gx, gy), (w, h) = grid, image_size
    cx, cy, r = circle
    xs = (np.arange(gx * SAMPLES) + 0.5) * w / (gx * SAMPLES) - 0.5
    ys = (np.arange(gy * SAMPLES) + 0.5) * h / (gy * SAMPLES) - 0.5
    lit = (xs[None, :] - cx) ** 2 + (ys[:, None] - cy) ** 2 <= r * r
    return lit.reshape(gy, SAMPLES, gx, SAMPLES).mean(axis=(1, 3)) >= INSIDE_SHARE


def empty_rim(counts: np.ndarray, inside: np.ndarray, circle: Circle, image_size: tuple[int, int]) -> list[str]:
    """Names of the stretches of the image circle's edge (eight directions) where half of
    the rim cells or more are empty. Rim cells: those inside with a neighbour outside the
    circle or the frame; each belongs to the direction of its centre from the circle's."""
    gy, gx = counts.shape
    w, h = image_size
    padded = np.pad(inside, 1, constant_values=False)
    rim = inside & ~(padded[:-2, 1:-1] & padded[2:, 1:-1] & padded[1:-1, :-2] & padded[1:-1, 2:])
    jj, ii = np.nonzero(rim)
    cx, cy, _ = circle
    angle = np.arctan2(cy - (jj + 0.5) * h / gy, (ii + 0.5) * w / gx - cx)  # y up: counter-clockwise
    direction = np.round(angle / (np.pi / 4)).astype(np.int64) % len(RIM_DIRECTIONS)
    empty = counts[jj, ii] == 0
    return [RIM_DIRECTIONS[d] + RIM_SUFFIX for d in (2, 3, 1, 4, 0, 5, 7, 6)   # read top to bottom
            if (direction == d).any() and empty[direction == d].mean() >= 0.5]


def coverage_warning(cov: dict[str, Any]) -> str | None:
    regions = cov.get("empty_regions") or []
    if not regions:
        return None
    if cov.get("image_circle"):
        where = "near the edge of the image circle at the " + ", ".join(r.removesuffix(RIM_SUFFIX) for r in regions)
    else:
        where = "in the " + ", ".join(regions) + " of the image"
    return (f"no corners {where}: the lens is least known there; "
            "add views with the board in those regions")


def circle_json(circle: Circle | None) -> dict[str, float] | None:
    """The circle as stored with the coverage and the observations: ``{"cx", "cy", "radius"}`` px."""
    if circle is None:
        return None
    cx, cy, r = circle
    return {"cx": round(cx, 1), "cy": round(cy, 1), "radius": round(r, 1)}
