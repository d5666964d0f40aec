"""A calibration judged in one line: how well the model fits the corners, how
well the projection is known where there were corners, and where to add views.

"0.26 px rms, 0.03 px projection uncertainty over the covered image: good;
add views at the top-left to cover the rest".

Thresholds: corner detectors measure a chessboard corner to 0.1-0.3 px, so
an rms (per point, OpenCV's figure) up to 0.5 px is what a good calibration
leaves, past 1 px something is wrong (corners, board size, model). The
projection uncertainty is the error a direction's pixel would carry from the
fit alone: a tenth of a pixel is below any detector's noise; past 0.3 px it
is as large as the noise itself.
"""
from __future__ import annotations

from typing import Any

import numpy as np

GRADES = ("good", "fair", "poor")
RMSE_LIMITS = (0.5, 1.0)          # px rms per point: good up to the first, fair up to the second
UNCERTAINTY_LIMITS = (0.1, 0.3)   # px, median over the covered image
COVERED_LIMITS = (0.7, 0.4)       # share of the image with corners nearby: good from the first, fair from the second
UNCOVERED_SHARE = 0.5             # a region with fewer of its cells covered counts as empty

# The image in thirds, named as a photographer would say where to hold the board.
REGIONS = (("top-left", "top", "top-right"), ("left", "centre", "right"), ("bottom-left", "bottom", "bottom-right"))


def uncovered_regions(covered: np.ndarray, inside: np.ndarray) -> list[str]:
    """Names of the image's ninths where fewer than half of the cells ``inside``
    the lens's image (nv, nu bool) have a corner nearby (``covered``)."""
    nv, nu = covered.shape
    rows = np.array_split(np.arange(nv), 3)
    cols = np.array_split(np.arange(nu), 3)
    out = []
    for i, r in enumerate(rows):
        for j, c in enumerate(cols):
            cells = inside[np.ix_(r, c)]
            if cells.sum() and covered[np.ix_(r, c)][cells].mean() < UNCOVERED_SHARE:
                out.append(REGIONS[i][j])
    return out


def _grade(value: float, limits: tuple[float, float], higher_is_better: bool = False) -> str:
    if not np.isfinite(value):
        return "poor"
    good, fair = limits
    if higher_is_better:
        return GRADES[0] if value >= good else GRADES[1] if value >= fair else GRADES[2]
    return GRADES[0] if value <= good else GRADES[1] if value <= fair else GRADES[2]


def verdict(rmse: float, uncertainty: dict[str, Any] | None) -> dict[str, Any]:
    """``{"grade", "text", "advice"}`` from the rms (px per point) and the
    projection-uncertainty summary (``parameters.describe_camera``'s)."""
    fit = _grade(rmse, RMSE_LIMITS)
    advice: list[str] = []
    if fit == "poor":
        advice.append("the corners are far from the model: check the board size and the photos' corners, "
                      "or try a model with a field")
    elif fit == "fair":
        advice.append("the rms is above what a sharp board gives: look for views with large errors")
    if uncertainty is None:
        return {"grade": fit, "text": f"{rmse:.2f} px rms: {fit}" + "".join(f"; {a}" for a in advice),
                "advice": advice}
    unc = float(uncertainty["median_px"])
    known = _grade(unc, UNCERTAINTY_LIMITS)
    spread = _grade(float(uncertainty["covered_share"]), COVERED_LIMITS, higher_is_better=True)
    grade = GRADES[max(GRADES.index(fit), GRADES.index(known), GRADES.index(spread))]
    if known != "good":
        advice.append("the model is loosely determined by these views: add views, with the board tilted more")
    regions = uncertainty.get("uncovered_regions") or []
    if regions:
        advice.append(f"add views at the {_and(regions)} to cover the rest")
    text = f"{rmse:.2f} px rms, {unc:.2f} px projection uncertainty over the covered image: {grade}"
    return {"grade": grade, "text": text + "".join(f"; {a}" for a in advice), "advice": advice}


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
