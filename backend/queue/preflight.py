"""Checks of a job's corners before the solver runs: data that cannot determine the
camera fails at once with what to do, instead of a confident wrong answer."""
from __future__ import annotations

import numpy as np

from calib_core import Observations
from calib_core.errors import DataError

# max/min depth of the board's corners within a view: 1.02 is a tilt of about 3°
# for a board a third of its distance across; calibration views are tilted 20-45°.
MIN_DEPTH_RATIO = 1.02


def depth_ratios(obs: Observations) -> list[float]:
    """Per planar view: how much the board's depth varies across it (1.0 = face-on), from its homography."""
    import cv2

    out = []
    for v in obs.views:
        if len(v) < 4 or np.any(np.abs(v.object_points[:, 2]) > 1e-9):
            continue
        H, _ = cv2.findHomography(v.object_points[:, :2], v.image_points, 0)
        if H is None or not np.all(np.isfinite(H)):
            continue
        w = np.column_stack([v.object_points[:, :2], np.ones(len(v))]) @ H[2]
        w = np.abs(w) if w.min() * w.max() > 0 else np.array([1.0, np.inf])  # a sign change: the board spans the horizon
        out.append(float(w.max() / w.min()))
    return out


def check_geometry(obs: Observations) -> None:
    ratios = depth_ratios(obs)
    if len(ratios) >= 2 and max(ratios) < MIN_DEPTH_RATIO:
        raise DataError(f"all {len(ratios)} views show the board face-on (fronto-parallel), so the focal length "
                        "cannot be told from the distance: add views with the board tilted by 20-45° in "
                        "different directions")
