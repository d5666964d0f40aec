"""Synthetic calibration objects of several boards, seen through the
protocol's lenses, with ground truth; every board has its own range of
marker ids of one dictionary (``freecal.target/1``).

- ``cube``: ChArUco boards on five faces of a cube (the bottom one stands on
  the table), seen from all round (``camera_poses``). Object frame: the
  cube's centre at the origin, faces with outward normals +x, −x, +y, −y, −z.
- ``corner``: three ChArUco boards on the floor and two walls of a room's
  corner, the planes x = 0, y = 0, z = 0, printed sides into the positive
  octant, seen from inside it (``corner_poses``): a wide lens sees all three
  and fills its whole image with them.

A board's printed side faces −z of its own frame (OpenCV's convention: seen
from the front, x runs right and y down), so the board's third axis is the
face's inward normal.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from ..observations import Observations, View
from ..target import Target
from .lenses import IMAGE_SIZE, in_view, true_project

SIDE = 320.0                       # mm, the cube's edge
SQUARES, SQUARE, MARKER = 7, 40.0, 30.0
DICTIONARY = "DICT_5X5_250"
FACES = {"+x": (1, 0, 0), "-x": (-1, 0, 0), "+y": (0, 1, 0), "-y": (0, -1, 0), "-z": (0, 0, -1)}
MAX_VIEW_ANGLE_DEG = 75.0          # a board seen more obliquely is too foreshortened to detect


def face_pose(normal: np.ndarray, centre: np.ndarray, board_side: float) -> np.ndarray:
    """[rvec | tvec] (board → object) of a square board centred on ``centre``, its printed side towards ``normal``."""
    n = np.asarray(normal, dtype=float)
    e3 = -n
    helper = np.array([0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    e1 = np.cross(helper, e3)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    rot = np.column_stack([e1, e2, e3])
    t = np.asarray(centre, dtype=float) - rot @ np.array([board_side / 2, board_side / 2, 0.0])
    return np.concatenate([Rotation.from_matrix(rot).as_rotvec(), t])


def cube(side: float = SIDE, squares: int = SQUARES, square: float = SQUARE, marker: float = MARKER,
         dictionary: str = DICTIONARY) -> Target:
    """Five ChArUco boards, ``squares`` × ``squares`` of ``square`` mm, one per face."""
    n_markers = squares * squares // 2
    boards = []
    for k, (name, normal) in enumerate(FACES.items()):
        pose = face_pose(np.array(normal, dtype=float), np.array(normal, dtype=float) * side / 2, squares * square)
        boards.append({"name": name, "board": {
            "type": "charuco", "squares_x": squares, "squares_y": squares, "square_size": square,
            "marker_size": marker, "dictionary": dictionary, "legacy": False, "first_marker": k * n_markers},
            "rvec": pose[:3].tolist(), "tvec": pose[3:].tolist()})
    return Target.from_json({"format": "freecal.target/1", "units": "mm", "boards": boards})


CORNER_SQUARES = 9          # the room corner's boards: 9 x 9 squares of SQUARE mm, with PAPER-free edges meeting


def corner(squares: int = CORNER_SQUARES, square: float = SQUARE, marker: float = MARKER,
           dictionary: str = DICTIONARY) -> Target:
    """Three ChArUco boards of ``squares`` × ``squares`` on the planes x = 0, y = 0 and z = 0,
    their edges along the axes a square's margin from the corner, printed sides inwards."""
    side = squares * square
    n_markers = squares * squares // 2
    boards = []
    for k, (name, axis) in enumerate((("floor", 2), ("wall x", 0), ("wall y", 1))):
        normal = np.zeros(3)
        normal[axis] = 1.0
        centre = np.full(3, side / 2 + square / 2)
        centre[axis] = 0.0
        pose = face_pose(normal, centre, side)
        boards.append({"name": name, "board": {
            "type": "charuco", "squares_x": squares, "squares_y": squares, "square_size": square,
            "marker_size": marker, "dictionary": dictionary, "legacy": False, "first_marker": k * n_markers},
            "rvec": pose[:3].tolist(), "tvec": pose[3:].tolist()})
    return Target.from_json({"format": "freecal.target/1", "units": "mm", "boards": boards})


def corner_poses(n: int, rng: np.random.Generator, distance: tuple[float, float] = (330.0, 520.0),
                 off_axis_deg: float = 60.0) -> np.ndarray:
    """``n`` poses (object → camera) inside the corner's octant, ``distance`` mm from the
    origin, looking back towards it, the corner's centre seen up to ``off_axis_deg`` off
    the axis so that the boards cover every part of the image, rolled at random."""
    middle = np.full(3, (CORNER_SQUARES + 1) * SQUARE / 2)
    poses = []
    for _ in range(n):
        direction = np.array([1.0, 1.0, 1.0]) + rng.uniform(-0.45, 0.45, 3)
        eye = direction / np.linalg.norm(direction) * rng.uniform(*distance)
        poses.append(_looking(eye, 0.35 * middle - eye, rng, off_axis_deg, up=np.array([0.0, 0.0, 1.0])))
    return np.array(poses)


def _looking(eye: np.ndarray, towards: np.ndarray, rng: np.random.Generator, off_axis_deg: float,
             up: np.ndarray) -> np.ndarray:
    """[rvec | tvec] (object → camera) of a camera at ``eye`` whose axis is ``towards`` turned by up to
    ``off_axis_deg`` in a random direction, rolled at random."""
    towards = towards / np.linalg.norm(towards)
    side = np.cross(towards, rng.normal(size=3))
    turn = Rotation.from_rotvec(side / np.linalg.norm(side) * np.radians(off_axis_deg) * np.sqrt(rng.uniform()))
    z = turn.apply(towards)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    r = Rotation.from_rotvec(z * rng.uniform(-np.pi, np.pi)).as_matrix() @ np.column_stack([x, np.cross(z, x), z])
    return np.concatenate([Rotation.from_matrix(r.T).as_rotvec(), -r.T @ eye])


def camera_poses(n: int, rng: np.random.Generator, distance: tuple[float, float] = (260.0, 360.0),
                 off_axis_deg: float = 50.0) -> np.ndarray:
    """``n`` poses (object → camera, (n, 6)) from all round the cube and above
    it, ``distance`` mm from its centre, the centre seen up to
    ``off_axis_deg`` off the optical axis so that the cube lands in every part
    of the image, rolled at random."""
    poses = []
    for k in range(n):
        azimuth = 2 * np.pi * (k + rng.uniform(-0.3, 0.3)) / n
        elevation = np.radians(rng.uniform(15, 70))          # above the table (−z is up)
        eye = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth),
                        -np.sin(elevation)]) * rng.uniform(*distance)
        poses.append(_looking(eye, -eye, rng, off_axis_deg, up=np.array([0.0, 0.0, -1.0])))
    return np.array(poses)


def seen(kind: str, target: Target, pose: np.ndarray, margin: float = 0.0,
         max_angle_deg: float = MAX_VIEW_ANGLE_DEG) -> tuple[np.ndarray, np.ndarray]:
    """Target ids (M,) of the corners a camera at ``pose`` sees through lens
    ``kind`` (printed side towards it, at most MAX_VIEW_ANGLE_DEG off the
    board's normal, inside the image by ``margin``) and their exact pixels (M, 2)."""
    ids = np.arange(target.n_corners)
    obj = target.object_points(ids)
    rot = Rotation.from_rotvec(pose[:3])
    pc = rot.apply(obj) + pose[3:]
    board = target.board_index(ids)
    normals = np.stack([-Rotation.from_rotvec(b.pose[:3]).as_matrix()[:, 2] for b in target.boards if b.pose])
    out_cam = rot.apply(normals[board])                    # outward normals in the camera frame
    cos_view = np.einsum("nj,nj->n", -pc, out_cam) / np.linalg.norm(pc, axis=1)
    ok = (cos_view > np.cos(np.radians(max_angle_deg))) & in_view(kind, pc)
    uv = np.full((len(ids), 2), np.nan)
    uv[ok] = true_project(kind, pc[ok])
    w, h = IMAGE_SIZE
    ok &= np.all(np.isfinite(uv), axis=1)
    ok &= (uv[:, 0] >= margin) & (uv[:, 0] <= w - 1 - margin) & (uv[:, 1] >= margin) & (uv[:, 1] <= h - 1 - margin)
    return ids[ok], uv[ok]


def shoot(kind: str, target: Target, poses: np.ndarray, sigma: float, rng: np.random.Generator,
          prefix: str = "cube_") -> Observations:
    """One view per pose with the target's 3-D object points and target ids, noise ``sigma`` px per axis."""
    views = []
    for k, pose in enumerate(poses):
        ids, uv = seen(kind, target, pose)
        if len(ids) < 20:
            continue
        noisy = uv + (rng.normal(0.0, sigma, uv.shape) if sigma > 0 else 0.0)
        views.append(View(f"{prefix}{k:02d}", target.object_points(ids), noisy, ids))
    return Observations(IMAGE_SIZE, views, None, {"target": target.to_json()})
