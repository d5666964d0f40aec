"""What the initialisation needs from calibration objects that are not one plane
(a cube of boards, several boards at known poses: ``freecal.target/1``).

- Zhang's closed form works on homographies of planes: the object's planar
  faces are found in its own points (``planar_faces``) and every view's
  faces become planar pseudo-views in face coordinates (``face_views``), the
  homographies of which give the focal-length candidate exactly as a set of
  one board per view does.
- A view's pose is then that of the whole object, from its rays by PnP
  (``pose_of_rays``): every corner of every face constrains it, and no face
  needs to hold six corners on its own.
"""
from __future__ import annotations

import cv2
import numpy as np

from .solve import Data

# Object points are printed or machined: a face is flat to well under a
# thousandth of the object's size (0.3 mm on a 30 cm cube).
FACE_TOLERANCE = 1e-3
MIN_FACE_POINTS = 6   # a homography needs 4; six keep it from fitting noise
PLANE_TRIALS = 256    # random triples per face: a cube's largest face is drawn ~10 times
MAX_FACES = 32


def is_board_plane(object_points: np.ndarray) -> bool:
    """Every point on Z = 0 (a planar board in its own frame, formats.md §1)."""
    return bool(np.all(np.abs(object_points[:, 2]) <= 1e-9 * max(1.0, float(np.abs(object_points).max(initial=0)))))


def planar_faces(object_points: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Face label (N,) of each object point (-1: on no face of at least
    MIN_FACE_POINTS points) and, per face, its frame (4, 3): origin, in-plane
    axes e1, e2 and normal. Largest face first.

    The planes are found among the object's distinct points (not per view):
    random triples propose planes, the one holding most points is a face, its
    points are removed, and so on (RANSAC with a fixed seed: the same object
    always gets the same faces)."""
    unique, inverse = np.unique(np.round(object_points, 9), axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    extent = float(np.ptp(unique, axis=0).max(initial=0.0)) if len(unique) else 0.0
    tol = FACE_TOLERANCE * max(extent, 1e-12)
    label = np.full(len(unique), -1)
    frames: list[np.ndarray] = []
    rng = np.random.default_rng(0)
    left = np.arange(len(unique))
    while len(left) >= MIN_FACE_POINTS and len(frames) < MAX_FACES:
        p = unique[left]
        tri = rng.integers(0, len(p), (PLANE_TRIALS, 3))
        normal = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
        size = np.linalg.norm(normal, axis=1)
        good = size > 1e-6 * extent**2       # collinear triples propose no plane
        if not good.any():
            break
        normal, origin = normal[good] / size[good, None], p[tri[good, 0]]
        near = np.abs(np.einsum("tj,tnj->tn", normal, p[None] - origin[:, None])) < tol   # (T, M)
        best = int(np.argmax(near.sum(axis=1)))
        inliers = near[best]
        if inliers.sum() < MIN_FACE_POINTS:
            break
        frame = _plane_frame(p[inliers])
        inliers = np.abs((p - frame[0]) @ frame[3]) < tol     # the refined plane's points
        if inliers.sum() < MIN_FACE_POINTS:
            break
        label[left[inliers]] = len(frames)
        frames.append(frame)
        left = left[~inliers]
    return label[inverse], frames


def _plane_frame(points: np.ndarray) -> np.ndarray:
    """(4, 3): centroid, two in-plane axes and the normal of the best plane through points."""
    centre = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - centre, full_matrices=False)
    e1, e2 = vt[0], vt[1]
    return np.stack([centre, e1, e2, np.cross(e1, e2)])


def face_views(data: Data) -> Data:
    """One planar pseudo-view per (view, face) with at least MIN_FACE_POINTS
    corners, its object points in face coordinates (Z = 0): what homographies
    (Zhang's focal length) are computed on. A board already on Z = 0 is returned
    as it is."""
    if is_board_plane(data.object_points):
        return data
    label, frames = planar_faces(data.object_points)
    on_face = label >= 0
    key = data.view_index[on_face] * (len(frames) + 1) + label[on_face]
    groups, group_of, counts = np.unique(key, return_inverse=True, return_counts=True)
    big = counts >= MIN_FACE_POINTS
    keep_group = np.cumsum(big) - 1                      # new view number of each big group
    idx = np.flatnonzero(on_face)[big[group_of]]
    g = group_of[big[group_of]]
    face = label[idx]
    frame = np.stack(frames)[face] if frames else np.zeros((0, 4, 3))
    rel = data.object_points[idx] - frame[:, 0]
    xy = np.stack([np.einsum("nj,nj->n", rel, frame[:, 1]), np.einsum("nj,nj->n", rel, frame[:, 2])], axis=-1)
    obj = np.column_stack([xy, np.zeros(len(idx))])
    return Data(obj, data.image_points[idx], keep_group[g], int(big.sum()))


def pose_of_rays(object_points: np.ndarray, rays: np.ndarray) -> np.ndarray | None:
    """[rvec | tvec] (6,) of an object seen along unit rays (N, 3), all in
    front (Z > 0): PnP on the rays' pinhole image (SQPnP, then
    Levenberg–Marquardt on the reprojection), any shape of object. None if
    OpenCV finds no pose."""
    if len(object_points) < 4:
        return None
    obj = np.ascontiguousarray(object_points, dtype=np.float64).reshape(-1, 1, 3)
    img = np.ascontiguousarray(rays[:, :2] / rays[:, 2:], dtype=np.float64).reshape(-1, 1, 2)
    eye = np.eye(3)
    try:
        ok, rvec, tvec = cv2.solvePnP(obj, img, eye, None, flags=cv2.SOLVEPNP_SQPNP)
        if not ok:
            return None
        rvec, tvec = cv2.solvePnPRefineLM(obj, img, eye, None, rvec, tvec)
    except cv2.error:
        return None
    pose = np.concatenate([rvec.reshape(3), tvec.reshape(3)])
    return pose if np.all(np.isfinite(pose)) else None
