"""Initialisation with no focal-length guess, from ordinary lenses to fisheyes.

1. Zhang's closed form on board homographies, principal point at the image
   centre and no distortion, gives one focal-length candidate (good for
   moderate lenses).
2. Equidistant cameras whose half-diagonal spans 30°…120° give more (good for
   wide and fisheye lenses, where homographies of distorted corners mislead).
3. For each candidate, every pose comes from a homography between the board
   and the candidate's rays, and a short Kannala–Brandt refinement on a
   subsample scores it. The best one is refined on all points.

A calibration object that is not one plane (several boards at known poses,
a cube) is initialised the same way (``init_3d``): Zhang's candidate from the
homographies of each face it shows in each view, every pose by PnP of the
whole object on the candidate's rays.

The result is a Kannala–Brandt camera (``FisheyeModel``) and poses: the
starting point of every method.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import DataError
from ..models import camera
from ..models.base import CameraModel
from ..models.fisheye import FisheyeModel
from .init_3d import face_views, is_board_plane, pose_of_rays
from .solve import Data, SolveSettings, levenberg_marquardt, spread_views

MIN_POINTS_PER_VIEW = 6


@dataclass
class Initial:
    model: FisheyeModel
    poses: np.ndarray  # (V, 6)
    rmse: float  # per-point RMS of the refined initial model, pixels
    focal_source: str


def zhang_focal(data: Data, image_size: tuple[int, int]) -> tuple[float, float] | None:
    """(fx, fy) from board homographies with the principal point at the image
    centre and no distortion (Zhang's constraints), or None when degenerate
    (e.g. every view fronto-parallel). A calibration object of several planes
    gives one homography per face seen in a view (``init_3d.face_views``)."""
    data = face_views(data)
    w, h = image_size
    shift = np.array([[1.0, 0, -(w - 1) / 2], [0, 1.0, -(h - 1) / 2], [0, 0, 1.0]])
    rows, rhs = [], []
    for k in range(data.n_views):
        m = data.view_index == k
        if m.sum() < MIN_POINTS_PER_VIEW:
            continue
        hmat, _ = cv2.findHomography(data.object_points[m, :2], data.image_points[m], 0)
        if hmat is None:
            continue
        hmat = shift @ hmat
        hmat /= np.linalg.norm(hmat)
        h1, h2 = hmat[:, 0], hmat[:, 1]
        for a, b in ((h1 * h2, None), (h1 * h1, h2 * h2)):
            row = a if b is None else a - b
            norm = np.linalg.norm(row[:2])
            if norm > 0:
                rows.append(row[:2] / norm)
                rhs.append(-row[2] / norm)
    if len(rows) < 2:
        return None
    sol, *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    if np.all(sol > 0):
        return float(1 / np.sqrt(sol[0])), float(1 / np.sqrt(sol[1]))
    # Fall back to a square-pixel camera: one unknown 1/f².
    a = np.array(rows).sum(axis=1)
    s = float(a @ np.array(rhs) / (a @ a)) if a @ a > 0 else -1.0
    if s > 0:
        f = float(1 / np.sqrt(s))
        return f, f
    return None


def _onto_axis(directions: np.ndarray) -> np.ndarray:
    """(V, 3, 3) rotations taking each unit direction (V, 3) onto +Z."""
    axis = np.cross(directions, [0.0, 0.0, 1.0])
    sine = np.linalg.norm(axis, axis=1, keepdims=True)
    angle = np.arctan2(sine, directions[:, 2:])
    return Rotation.from_rotvec(axis / np.maximum(sine, 1e-12) * angle).as_matrix()


def poses_from_rays(model: CameraModel, data: Data) -> np.ndarray | None:
    """A pose per view from the homography between the board plane and the
    model's rays of the observed corners (a view whose object points are not
    all on Z = 0, of a 3-D calibration object: by PnP of the whole object on
    the rays); None if some view cannot be posed.

    Each view's rays are first turned about the camera centre so that their
    mean is the optical axis: a board seen far off axis (a fisheye's edge,
    up to and past 90°) then projects onto the plane Z = 1 like one seen
    straight ahead, and the pose is turned back."""
    xn = model.normalised_of_pixel(data.image_points, tol=1e-6)
    rays = camera.ray_of(xn, model.base)
    finite = np.all(np.isfinite(rays), axis=1)
    mean = np.zeros((data.n_views, 3))
    np.add.at(mean, data.view_index[finite], rays[finite])
    norm = np.linalg.norm(mean, axis=1, keepdims=True)
    turn = _onto_axis(np.where(norm > 0, mean / np.maximum(norm, 1e-300), [0.0, 0.0, 1.0]))
    rays = np.einsum("nij,nj->ni", turn[data.view_index], np.where(finite[:, None], rays, 0.0))
    usable = finite & (rays[:, 2] > 0.2)
    order = np.argsort(data.view_index, kind="stable")
    starts = np.searchsorted(data.view_index[order], np.arange(data.n_views + 1))
    homographies, centroids = np.tile(np.eye(3), (data.n_views, 1, 1)), np.zeros((data.n_views, 3))
    solid: dict[int, np.ndarray] = {}  # views of a 3-D object: their pose by PnP, in the turned frame
    for k in range(data.n_views):  # one homography per view (OpenCV's, not vectorisable)
        m = order[starts[k] : starts[k + 1]]
        m = m[usable[m]]
        if len(m) < 4:
            return None
        if not is_board_plane(data.object_points[m]):
            pose = pose_of_rays(data.object_points[m], rays[m])
            if pose is None:
                return None
            solid[k] = pose
            continue
        # Board coordinates about the observed centroid: better conditioned,
        # and the centroid must land in front of the camera.
        centroids[k] = data.object_points[m].mean(axis=0)
        hmat, _ = cv2.findHomography(data.object_points[m, :2] - centroids[k, :2], rays[m, :2] / rays[m, 2:], 0)
        if hmat is None:
            return None
        homographies[k] = hmat
    # H ~ [r1 r2 t]: scale, orient in front of the camera, nearest rotation.
    lam = 2.0 / (np.linalg.norm(homographies[:, :, 0], axis=1) + np.linalg.norm(homographies[:, :, 1], axis=1))
    lam *= np.where(homographies[:, 2, 2] * lam < 0, -1.0, 1.0)
    h = homographies * lam[:, None, None]
    r1, r2, t = h[:, :, 0], h[:, :, 1], h[:, :, 2]
    u, _, vt = np.linalg.svd(np.stack([r1, r2, np.cross(r1, r2)], axis=-1))
    flip = np.where(np.linalg.det(u @ vt) < 0, -1.0, 1.0)
    u[:, :, 2] *= flip[:, None]
    rot = u @ vt
    back = np.transpose(turn, (0, 2, 1))
    poses = np.zeros((data.n_views, 6))
    poses[:, :3] = Rotation.from_matrix(back @ rot).as_rotvec()
    poses[:, 3:] = np.einsum("kij,kj->ki", back, t - np.einsum("kij,kj->ki", rot, centroids))
    for k, pose in solid.items():
        poses[k, :3] = Rotation.from_matrix(back[k] @ Rotation.from_rotvec(pose[:3]).as_matrix()).as_rotvec()
        poses[k, 3:] = back[k] @ pose[3:]
    return poses


def _subsample(data: Data, max_views: int, per_view: int, rng: np.random.Generator) -> Data:
    """At most ``per_view`` corners of each of at most ``max_views`` views
    (spread over the set): enough to score and shape a camera, and the cost
    no longer grows with the number of views."""
    data = spread_views(data, max_views)
    per_view_picks = []
    for k in range(data.n_views):
        idx = np.flatnonzero(data.view_index == k)
        per_view_picks.append(idx if len(idx) <= per_view else np.sort(rng.choice(idx, per_view, replace=False)))
    keep = np.concatenate(per_view_picks)
    return data.points(keep)


# Kannala–Brandt coefficients of the pinhole projection: tan θ = θ (1 + θ²/3 + 2θ⁴/15 + 17θ⁶/315 + …).
PINHOLE_AS_KB = np.array([1 / 3, 2 / 15, 17 / 315, 62 / 2835])


def _candidates(data: Data, image_size) -> list[tuple[str, float, float, np.ndarray]]:
    """(label, fx, fy, KB coefficients) starting points: pinhole and equidistant
    cameras over a range of fields of view, and Zhang's estimate."""
    w, h = image_size
    half_diag = 0.5 * np.hypot(w, h)
    out = []
    zf = zhang_focal(data, image_size)
    if zf is not None and all(np.isfinite(zf)):
        out.append(("zhang homographies, pinhole", *zf, PINHOLE_AS_KB))
    for deg in (30, 50, 70):
        f = half_diag / np.tan(np.radians(deg))
        out.append((f"pinhole, half-diagonal {deg} deg", f, f, PINHOLE_AS_KB))
    for deg in (60, 90, 120):
        f = half_diag / np.radians(deg)
        out.append((f"equidistant, half-diagonal {deg} deg", f, f, np.zeros(4)))
    return out


# One calibration may try several models from the same start (bspline's core
# choice fits two): the initialisation of a given Data is computed once.
_CACHE: weakref.WeakKeyDictionary[Data, dict] = weakref.WeakKeyDictionary()


def initialise(data: Data, image_size: tuple[int, int], n_coefficients: int = 4) -> Initial:
    """A Kannala–Brandt camera and a pose per view, with no focal guess (cached
    per ``data`` object: the result is never modified by its users)."""
    key = (tuple(image_size), n_coefficients)
    cached = _CACHE.setdefault(data, {})
    if key not in cached:
        cached[key] = _initialise(data, image_size, n_coefficients)
    return cached[key]


def _initialise(data: Data, image_size: tuple[int, int], n_coefficients: int) -> Initial:
    """A Kannala–Brandt camera and a pose per view, with no focal guess.

    Each candidate is scored after fitting only its focal lengths and the poses
    (its shape held): a small, well-posed problem. The best is then refined with
    every parameter free, first on a subsample and then on all points."""
    counts = np.bincount(data.view_index, minlength=data.n_views)
    if np.any(counts < MIN_POINTS_PER_VIEW):
        bad = int(np.argmin(counts))
        raise DataError(f"view {bad} has {counts[bad]} corners; each view needs at least {MIN_POINTS_PER_VIEW}")
    w, h = image_size
    centre = ((w - 1) / 2, (h - 1) / 2)
    sample = _subsample(data, 20, 40, np.random.default_rng(0))
    focal_only = np.zeros(4 + n_coefficients, dtype=bool)
    focal_only[:2] = True
    quick = SolveSettings(max_iterations=30, ftol=1e-4, free_params=focal_only)
    best = None
    for source, fx, fy, coeffs in _candidates(data, image_size):
        k = np.zeros(n_coefficients)
        k[: min(4, n_coefficients)] = coeffs[: min(4, n_coefficients)]
        model = FisheyeModel([fx, fy, *centre, 0.0], k)
        poses = poses_from_rays(model, sample)
        if poses is None:
            continue
        try:
            res = levenberg_marquardt(model, poses, sample, quick)
        except FloatingPointError:
            continue
        rmse = float(np.sqrt(np.mean(np.sum(res.residuals**2, axis=1))))
        if np.isfinite(rmse) and np.all(res.model.intrinsics[:2] > 0) and (best is None or rmse < best[0]):
            best = (rmse, source, res.model, res.poses)
    if best is None:
        raise DataError(
            "could not initialise the camera: no focal length explains the board views. "
            "Check the board size (inner corners) and that the views are not all fronto-parallel."
        )
    _, source, model, poses = best
    res = levenberg_marquardt(model, poses, sample, SolveSettings(max_iterations=100, ftol=1e-6))
    model = res.model
    poses = poses_from_rays(model, data)
    if poses is None:
        raise DataError("could not initialise a pose for every view; remove views with very few corners")
    res = levenberg_marquardt(model, poses, data, SolveSettings(max_iterations=100))
    # Corners near the axis barely constrain the higher coefficients: on a narrow
    # set they can bend the lens back on itself inside the image, and every
    # use of the camera beyond the corners (the B-spline's prior field, the
    # image border's rays) then sees a fold. Fewer coefficients, the rest zero.
    for n in range(n_coefficients - 1, -1, -1):
        if not folds_inside_image(res.model, res.poses, data, image_size):
            break
        k = res.model.coefficients.copy()
        k[n:] = 0.0
        free = np.ones(res.model.n_params, dtype=bool)
        free[4 + n :] = False
        res = levenberg_marquardt(FisheyeModel(res.model.intrinsics, k), res.poses, data,
                                  SolveSettings(max_iterations=100, free_params=free))
    rmse = float(np.sqrt(np.mean(np.sum(res.residuals**2, axis=1))))
    return Initial(res.model, res.poses, rmse, source)


def folds_inside_image(model: FisheyeModel, poses: np.ndarray, data: Data, image_size) -> bool:
    """Does the Kannala–Brandt radius θ_d(θ) turn back before the image ends?

    Looked for up to the farthest image corner: as far as the corners' angles
    reach, and at least to that corner's pinhole angle (a circular fisheye's
    black corners, which no ray reaches, are not asked for beyond its data)."""
    fx, fy, cx, cy, _ = model.intrinsics
    w, h = image_size
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]])
    reach = np.max(np.hypot((corners[:, 0] - cx) / fx, (corners[:, 1] - cy) / fy))
    pc = camera.transform(poses, data.view_index, data.object_points)
    seen = np.max(np.arccos(np.clip(pc[:, 2] / np.linalg.norm(pc, axis=1), -1.0, 1.0)))
    theta = np.linspace(1e-3, min(np.pi, max(seen, np.arctan(reach))), 2000)
    radius, slope = model.radial_profile(theta)
    inside = np.cumsum(radius >= reach) == 0  # before θ_d first reaches the farthest corner
    return bool(np.any(slope[inside] <= 0.0))
