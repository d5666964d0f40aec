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


FIELD_ADVICE = "try a model with a field"  # where no choice among models was made


def verdict(rmse: float, uncertainty: dict[str, Any] | None, no_ray: dict[str, float] | None = None,
            lit: float | None = None, other_model: str | None = FIELD_ADVICE) -> dict[str, Any]:
    """``{"grade", "text", "advice"}`` from the rms (px per point), the
    projection-uncertainty summary (``parameters.describe_camera``'s) and
    where the model has no ray (``no_ray``: line → px from the principal
    point, ``parameters.no_ray_beyond``) against how far out the lens is
    known to light the image (``lit``, px: the farthest corner used).
    ``other_model``: what to say of another model when the corners are far
    from this one (``parameters.other_model``; None: nothing, e.g. the model
    already has a field)."""
    fit = _grade(rmse, RMSE_LIMITS)
    no_ray = no_ray or {}
    advice: list[str] = []
    if fit == "poor":
        advice.append("the corners are far from the model: check the board size and the photos' corners"
                      + (f", or {other_model}" if other_model else ""))
    elif fit == "fair":
        advice.append("the rms is above what a sharp board gives: look for views with large errors")
    reach = _reach(no_ray, lit)
    if reach:
        advice.append(reach)
    if uncertainty is None:
        grade = GRADES[max(GRADES.index(fit), GRADES.index(_reach_grade(no_ray, lit)))]
        return {"grade": grade, "text": f"{rmse:.2f} px rms: {grade}" + "".join(f"; {a}" for a in advice),
                "advice": advice}
    unc = float(uncertainty["median_px"])
    known = _grade(unc, UNCERTAINTY_LIMITS)
    spread = _grade(float(uncertainty["covered_share"]), COVERED_LIMITS, higher_is_better=True)
    grade = GRADES[max(GRADES.index(fit), GRADES.index(known), GRADES.index(spread),
                       GRADES.index(_reach_grade(no_ray, lit)))]
    if known != "good":
        advice.append("the model is loosely determined by these views: add views, with the board tilted more")
    regions = uncertainty.get("uncovered_regions") or []
    if regions:
        advice.append(f"add views at the {_and(regions)} to cover the rest")
    text = f"{rmse:.2f} px rms, {unc:.2f} px projection uncertainty over the covered image: {grade}"
    return {"grade": grade, "text": text + "".join(f"; {a}" for a in advice), "advice": advice}


def _reach(no_ray: dict[str, float], lit: float | None) -> str:
    """The advice for pixels the model gives no ray to, or ""."""
    if not no_ray:
        return ""
    name = min(no_ray, key=lambda k: no_ray[k])
    where = f"farther than {no_ray[name]:.0f} px from the principal point (along the image's {name})"
    if lit is not None and lit > no_ray[name]:
        return (f"the model gives no ray to pixels {where}, where corners show the lens lights the image "
                f"(up to {lit:.0f} px): its distortion turns back there, so undistorting the whole image with it "
                "is wrong; a Kannala-Brandt model or a field over it reaches further")
    return (f"the model gives no ray to pixels {where}: right if the lens leaves them dark, otherwise do not "
            "undistort the whole image with it")


def _reach_grade(no_ray: dict[str, float], lit: float | None) -> str:
    """"fair" at best where the model gives no ray to pixels the lens is known to light."""
    return "fair" if no_ray and lit is not None and lit > min(no_ray.values()) else "good"


def _and(names: list[str]) -> str:
    return names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
