"""Where in the image the corners fall: a grid histogram and the empty regions.

Distortion is strongest at the edges and corners of the image; a calibration
with no data there extrapolates, so we say which of those regions are empty.
"""
from __future__ import annotations

from typing import Any

import numpy as np

GRID_X = 8  # histogram cells across; down follows the aspect ratio


def coverage(points: np.ndarray, image_size: tuple[int, int], grid_x: int = GRID_X) -> dict[str, Any]:
    """Histogram of corner pixels (N, 2) over a grid of the image (W, H).

    Returns ``{"grid": [gx, gy], "counts": gy rows of gx ints, "fraction_covered",
    "empty_regions": names}`` (counts[0] is the top row).
    """
    w, h = image_size
    gx = grid_x
    gy = max(2, int(round(grid_x * h / w)))
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    counts, _, _ = np.histogram2d(pts[:, 1], pts[:, 0], bins=[gy, gx], range=[[-0.5, h - 0.5], [-0.5, w - 0.5]])
    counts = counts.astype(np.int64)
    return {
        "grid": [gx, gy],
        "counts": counts.tolist(),
        "fraction_covered": float(np.mean(counts > 0)),
        "empty_regions": empty_regions(counts),
    }


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


def coverage_warning(cov: dict[str, Any]) -> str | None:
    regions = cov.get("empty_regions") or []
    if not regions:
        return None
    return ("no corners in the " + ", ".join(regions) + " of the image: the lens is least known there; "
            "add views with the board in those regions")
