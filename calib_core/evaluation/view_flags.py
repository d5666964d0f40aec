"""Which views of a calibration look suspicious, and why: the curation flags.

Three questions per view, each answered against the rest of the set or against
noise, so that one threshold serves a pinhole webcam and a fisheye alike:

- ``outliers``: a large share of its corners was thrown out by the robust
  outlier rejection (a misdetected patch, glare, a corner on the wrong square);
- ``rmse``: its rmse is far above the rest, measured robustly (median and MAD
  of the views' rmse, so that the bad view does not hide itself by inflating
  the spread): a modified z-score above ``RMSE_Z`` *and* 1.5 times the median
  (a set of near-identical views has a tiny MAD, where a z-score alone flags
  noise);
- ``structure``: its residuals follow a smooth pattern over the board far
  more than the other views' do (a bent or warped board, a board that moved
  during the exposure). Measured by fitting a quadratic surface over the
  board's own coordinates to dx and dy (6 terms each): its share of the
  residual power (noise alone explains about 6/N of it; an F-test says whether
  it is chance) and its rms in px, the pattern's size. Every real set leaves
  some pattern in every view (on GoPro's 24 photos the quadratic explains 36 to
  91 % of each view's residual power: lens model, board flatness, detector
  bias all leave one), so the pattern's rms is judged against the other views
  (robust z-score, as for rmse), and the pattern must be a fair share of the
  view's own residuals (``STRUCTURE_SHARE``) and significant.

Flags are computed on the fit's own residuals (observed − projected with the
view's fitted pose) of its inlier corners. ``view_flags`` is what the report's
per-view table, the service's page and ``freecal calibrate`` show.
"""
from __future__ import annotations

from typing import Any

import numpy as np
from scipy import stats

from ..calibration import Calibration
from ..observations import Observations

OUTLIER_SHARE = 0.10    # of a view's corners thrown out
RMSE_Z = 3.5            # modified z-score (Iglewicz & Hoaglin's outlier rule)
RMSE_RATIO = 1.5        # and this many times the set's median rmse
MIN_VIEWS_FOR_RMSE = 4  # a median and a MAD need a few views
STRUCTURE_SHARE = 0.25  # of the residual power a smooth pattern over the board explains (noise: ~6/N)
STRUCTURE_P = 1e-6      # and not by chance (F-test; a set has tens of views)
STRUCTURE_TERMS = 6     # 1, x, y, x², xy, y² per component
MIN_POINTS_FOR_STRUCTURE = 3 * STRUCTURE_TERMS


def view_flags(cal: Calibration, obs: Observations) -> list[dict[str, Any]]:
    """One entry per view of ``cal`` found in ``obs``: its figures and its flags.

    Each entry: ``view``, ``n_detected`` (corners given), ``n_kept`` (inliers used),
    ``outlier_share``, ``rmse``, ``max_error`` (inliers, px), ``rmse_z`` (robust
    z-score against the other views, None with fewer than 4 views), ``structure``
    (share of residual power explained by a quadratic over the board, None when
    too few points), ``structure_p``, ``structure_rms`` (that pattern's rms, px),
    ``structure_z`` (its robust z-score against the other views) and ``flags``: a list of ``{"code", "text"}``
    with ``code`` one of ``outliers``, ``rmse``, ``structure``, in plain words.
    """
    known = {v.name for v in obs.views}
    rows = [_view_figures(cal, obs, v) for v in cal.views if v.name in known]
    rmse = np.array([r["rmse"] for r in rows], float)
    med, spread = _median_spread(rmse)
    pattern = np.array([np.nan if r["structure_rms"] is None else r["structure_rms"] for r in rows], float)
    p_med, p_spread = _median_spread(pattern)
    for r in rows:
        flags = []
        if r["n_detected"] and r["outlier_share"] >= OUTLIER_SHARE:
            n_out = r["n_detected"] - r["n_kept"]
            flags.append({"code": "outliers", "text": f"{n_out} of {r['n_detected']} corners "
                          f"({100 * r['outlier_share']:.0f} %) thrown out as outliers"})
        z = None
        if len(rows) >= MIN_VIEWS_FOR_RMSE and np.isfinite(r["rmse"]) and spread > 0:
            z = float((r["rmse"] - med) / spread)
            if z > RMSE_Z and r["rmse"] > RMSE_RATIO * med:
                flags.append({"code": "rmse", "text": f"rmse {r['rmse']:.3f} px, {r['rmse'] / med:.1f} times the "
                              f"median of the views ({med:.3f} px)"})
        r["rmse_z"] = z
        sz = None
        if len(rows) >= MIN_VIEWS_FOR_RMSE and r["structure_rms"] is not None and p_spread > 0:
            sz = float((r["structure_rms"] - p_med) / p_spread)
            if (sz > RMSE_Z and r["structure_rms"] > RMSE_RATIO * p_med and r["structure"] >= STRUCTURE_SHARE
                    and r["structure_p"] < STRUCTURE_P):
                flags.append({"code": "structure", "text": f"its residuals follow a smooth pattern over the board "
                              f"({r['structure_rms']:.3f} px rms, {100 * r['structure']:.0f} % of their power; "
                              f"{r['structure_rms'] / p_med:.1f} times the views' median): a bent board, or one "
                              "that moved during the exposure?"})
        r["structure_z"] = sz
        r["flags"] = flags
    return rows


def _view_figures(cal: Calibration, obs: Observations, result) -> dict[str, Any]:
    v = obs.view(result.name)
    n = len(v)
    keep = np.ones(n, bool)
    keep[np.asarray(result.outliers, int)] = False
    d = v.image_points[keep] - cal.project(v.object_points[keep], result.rvec, result.tvec)
    finite = np.all(np.isfinite(d), axis=1)  # a point the model cannot project (past a fisheye's edge)
    d = d[finite]
    err = np.hypot(d[:, 0], d[:, 1])
    share, p = structure(v.object_points[keep][finite], d)
    return {"view": v.name, "n_detected": n, "n_kept": int(keep.sum()),
            "outlier_share": float(1 - keep.sum() / n) if n else 0.0,
            "rmse": float(np.sqrt(np.mean(err ** 2))) if len(err) else float("nan"),
            "max_error": float(err.max()) if len(err) else None,
            "structure": share, "structure_p": p,
            "structure_rms": None if share is None or not len(err) else float(np.sqrt(share * np.mean(err ** 2)))}


def structure(board_points: np.ndarray, residuals: np.ndarray) -> tuple[float | None, float | None]:
    """(share of the residual power (N, 2) a quadratic in the board coordinates (N, 3) explains,
    its F-test p-value under pure noise); (None, None) with too few points."""
    n = len(residuals)
    if n < MIN_POINTS_FOR_STRUCTURE:
        return None, None
    xy = board_points[:, :2]
    span = np.ptp(xy, axis=0)
    if np.any(span <= 0):
        return None, None  # a single row of corners: no surface to fit
    x, y = ((xy - xy.mean(axis=0)) / (span / 2)).T
    design = np.column_stack([np.ones(n), x, y, x * x, x * y, y * y])
    coef, *_ = np.linalg.lstsq(design, residuals, rcond=None)
    total = float(np.sum(residuals ** 2))
    if total <= 0:
        return 0.0, 1.0
    left = float(np.sum((residuals - design @ coef) ** 2))
    share = 1.0 - left / total
    df1, df2 = 2 * STRUCTURE_TERMS, 2 * (n - STRUCTURE_TERMS)
    f = (share / df1) / max((1.0 - share) / df2, 1e-300)
    return float(share), float(stats.f.sf(f, df1, df2))


def _median_spread(values: np.ndarray) -> tuple[float, float]:
    """Median and robust σ (1.4826·MAD) of the finite values."""
    v = values[np.isfinite(values)]
    if not len(v):
        return float("nan"), 0.0
    med = float(np.median(v))
    return med, float(1.4826 * np.median(np.abs(v - med)))
