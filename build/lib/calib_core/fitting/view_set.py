"""Is a set of views able to determine a camera at all? Degenerate sets fail here,
saying what to shoot, instead of giving a confident, wrong calibration.

Three ways a set cannot determine the focal length, each from the geometry:

- **duplicates**: views whose corners agree to within ``DUPLICATE_PX`` are one
  pose (copies of one photo, or a camera and a board that did not move); 13
  copies of one photo fitted to rmse 0.002 px with fx 276 instead of 533;
- **face-on**: every board fronto-parallel: focal length and distance trade
  off exactly, so only their ratio is seen;
- **no tilt between views**: every board normal within ``MIN_TILT_SPREAD_DEG``
  of the others (the same tilt moved around the frame): planes that are all
  parallel leave the focal length unobservable (Sturm & Maybank 1999).

The first two are read from the corners before the solver runs (no camera
needed: image distances, and depth ratios from each view's homography, whose
third row does not depend on the intrinsics). The third needs the board normals
in the camera, so it is checked on the poses of the first fit.
"""
from __future__ import annotations

import numpy as np

from ..errors import DegenerateViews
from ..observations import Observations, View

MIN_POSES = 3   # Zhang's method needs three planes of different orientation for five intrinsics
# Two shots of one pose differ by the detection noise only: corner noise is 0.1-0.5 px RMS per axis, so
# the RMS distance between the same corner in two shots is under 0.7 px; a new pose moves corners by
# many pixels. Below this, the second view adds no geometry.
DUPLICATE_PX = 1.0
# max/min depth of the board's corners within a view: 1.02 is a tilt of about 3° for a board a third
# of its distance across; calibration views are tilted 20-45°.
MIN_DEPTH_RATIO = 1.02
# Calibration guides ask for 20-45° between views. Sets shot with one tilt (parallel planes) fit
# poses within 0.01-1.7° of each other on the synthetic lenses (the noise of telling normals apart),
# good sets 50° and more: below a few degrees the normals are parallel as far as the data can tell.
MIN_TILT_SPREAD_DEG = 4.0
WHAT_TO_SHOOT = ("shoot 10-20 views with the board in different parts of the frame, tilted by 20-45° in "
                 "different directions (left, right, up, down)")


def check_views(obs: Observations) -> None:
    """DegenerateViews when the corners alone show the set cannot determine the focal length."""
    check_distinct_poses(obs.views)
    check_tilted(obs)


def check_distinct_poses(views: list[View]) -> None:
    poses: list[View] = []   # one view per distinct pose
    same: tuple[str, str] | None = None
    for v in views:
        twin = next((p for p in poses if corner_distance(p, v) < DUPLICATE_PX), None)
        if twin is None:
            poses.append(v)
            if len(poses) >= MIN_POSES:
                return
        elif same is None:
            same = (twin.name, v.name)
    if len(poses) < len(views) and same is not None:
        raise DegenerateViews(
            f"the {len(views)} views show only {len(poses)} distinct pose(s) of the board: views such as "
            f"{same[0]!r} and {same[1]!r} have the same corners to within {DUPLICATE_PX:g} px (copies of one "
            f"photo, or a camera and board that did not move), and a calibration needs at least {MIN_POSES} "
            f"different poses: {WHAT_TO_SHOOT}")


def corner_distance(a: View, b: View) -> float:
    """RMS image distance between the corners two views share (inf when they share fewer than 4)."""
    if a.ids is not None and b.ids is not None:
        _, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
    elif len(a) == len(b):
        ia = ib = np.arange(len(a))
    else:
        return np.inf
    if len(ia) < 4:
        return np.inf
    d = a.image_points[ia] - b.image_points[ib]
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


def check_tilted(obs: Observations) -> None:
    ratios = depth_ratios(obs)
    if len(ratios) >= 2 and max(ratios) < MIN_DEPTH_RATIO:
        raise DegenerateViews(
            f"all {len(ratios)} views show the board face-on (fronto-parallel), so the focal length cannot be "
            f"told from the distance: add views with the board tilted by 20-45° in different directions")


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


def check_fitted_tilts(rvecs: np.ndarray, planar: bool = True) -> None:
    """DegenerateViews when the fitted board normals (rotation vectors, one per view) are all parallel."""
    if not planar or len(rvecs) < 2:
        return
    from scipy.spatial.transform import Rotation

    normals = Rotation.from_rotvec(np.asarray(rvecs, dtype=float)).as_matrix()[:, :, 2]
    spread = tilt_spread(normals)
    if spread < MIN_TILT_SPREAD_DEG:
        raise DegenerateViews(
            f"the board is tilted the same way in all {len(rvecs)} views (its normals are within {spread:.1f}° "
            f"of each other, under {MIN_TILT_SPREAD_DEG:g}°), so the focal length cannot be told from the "
            f"distance and a calibration would be confidently wrong: {WHAT_TO_SHOOT}")


def tilt_spread(normals: np.ndarray) -> float:
    """The largest angle (degrees) between two of the unit normals (V, 3)."""
    cos = np.clip(normals @ normals.T, -1.0, 1.0)
    return float(np.degrees(np.arccos(cos.min())))
