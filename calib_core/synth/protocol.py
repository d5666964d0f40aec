"""The protocol's views: noisy training views filling the frame, noise-free
hold-out views over the whole image, and the ground truth."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..observations import Observations, View
from .lenses import (
    ALL_KINDS,
    HOLDOUT_BOARD,
    IMAGE_SIZE,
    INTRINSICS,
    LENSES,
    SQUARE,
    TRAIN_BOARD,
    TRUTH_FORMAT,
    WIDE_KINDS,
    in_view,
    true_project,
)

MAX_INCIDENCE_DEG = 80.0   # a board corner seen more obliquely than this is too foreshortened to detect


def board_points(cols: int, rows: int, square: float = SQUARE) -> np.ndarray:
    """Inner corners (rows·cols, 3), id = row·cols + col, origin at corner 0."""
    j, i = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    return np.stack([i.ravel() * square, j.ravel() * square, np.zeros(rows * cols)], axis=-1)


def look_at_pose(eye: np.ndarray, target: np.ndarray, roll: float) -> np.ndarray:
    """[rvec | tvec] of a camera at ``eye`` (board frame) looking at ``target``."""
    z = target - eye
    z /= np.linalg.norm(z)
    up = np.array([0.0, 1.0, 0.0]) if abs(z[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    x = np.cross(up, z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    r_cam_board = np.stack([x, y, z])  # rows: camera axes in board frame
    r = Rotation.from_rotvec([0, 0, roll]).as_matrix() @ r_cam_board
    return np.concatenate([Rotation.from_matrix(r).as_rotvec(), -r @ eye])


def _visible(kind: str, pose: np.ndarray, pts: np.ndarray, margin: float = 0.0):
    rot = Rotation.from_rotvec(pose[:3])
    pc = rot.apply(pts) + pose[3:]
    ok = in_view(kind, pc)
    uv = np.full((len(pts), 2), np.nan)
    uv[ok] = true_project(kind, pc[ok])
    w, h = IMAGE_SIZE
    if kind in WIDE_KINDS:
        # Past 90° off the axis a board faces the camera sideways: keep the corners it shows
        # at most MAX_INCIDENCE_DEG from its normal.
        normal = rot.apply([0.0, 0.0, 1.0])
        cos_angle = np.abs(pc @ normal) / np.linalg.norm(pc, axis=1)
    else:
        # Keep corners seen at most ~80° off axis: a real board corner further out
        # is too foreshortened to detect.
        cos_angle = pc[:, 2] / np.linalg.norm(pc, axis=1)
    ok &= (cos_angle > np.cos(np.radians(MAX_INCIDENCE_DEG))) & np.all(np.isfinite(uv), axis=1)
    ok &= (uv[:, 0] >= margin) & (uv[:, 0] <= w - 1 - margin) & (uv[:, 1] >= margin) & (uv[:, 1] <= h - 1 - margin)
    return ok, uv


def pose_looking_at(target: np.ndarray, dist: float, tilt: np.ndarray, roll: float) -> np.ndarray:
    """Pose whose optical axis meets the board at ``target`` from ``dist`` mm,
    the board tilted by ``tilt`` (about the camera's x and y axes, radians)."""
    r = Rotation.from_rotvec([0.0, 0.0, roll]) * Rotation.from_rotvec([tilt[0], 0.0, 0.0]) * Rotation.from_rotvec([0.0, tilt[1], 0.0])
    return np.concatenate([r.as_rotvec(), np.array([0.0, 0.0, dist]) - r.apply(target)])


def _train_poses(rng: np.random.Generator, n_views: int) -> np.ndarray:
    """Close views of a large board that fill the frame, tilted every way."""
    cols, rows = TRAIN_BOARD
    centre = np.array([(cols - 1) * SQUARE / 2, (rows - 1) * SQUARE / 2, 0.0])
    poses = []
    for k in range(n_views):
        phi = 2 * np.pi * k / n_views + rng.uniform(-0.3, 0.3)
        tilt = np.radians(rng.uniform(15, 35)) * np.array([np.cos(phi), np.sin(phi)]) if k else np.zeros(2)
        target = centre + np.array([*rng.uniform(-100, 100, size=2), 0.0])
        poses.append(pose_looking_at(target, rng.uniform(160, 220), tilt, rng.uniform(-0.5, 0.5)))
    return np.array(poses)


def facing(centre: np.ndarray, towards: np.ndarray, distance: float, tilt: np.ndarray, roll: float) -> np.ndarray:
    """Pose (board → camera) of a board whose point ``centre`` lies ``distance`` mm along the unit
    direction ``towards`` from the camera, the board facing the camera, then tilted (radians about its
    x and y axes) and turned by ``roll`` about its normal: what a lens past 180° sees all round."""
    x = np.cross([0.0, 1.0, 0.0] if abs(towards[1]) < 0.9 else [1.0, 0.0, 0.0], towards)
    x /= np.linalg.norm(x)
    face = np.column_stack([x, np.cross(towards, x), towards])          # board z away from the camera
    r = face @ Rotation.from_rotvec([tilt[0], tilt[1], roll]).as_matrix()
    return np.concatenate([Rotation.from_matrix(r).as_rotvec(), towards * distance - r @ centre])


def _direction(off_axis: float, azimuth: float) -> np.ndarray:
    return np.array([np.sin(off_axis) * np.cos(azimuth), np.sin(off_axis) * np.sin(azimuth), np.cos(off_axis)])


def _wide_train_poses(rng: np.random.Generator, n_views: int) -> np.ndarray:
    """The large board facing the camera from all round, its centre up to 95° off the axis."""
    cols, rows = TRAIN_BOARD
    centre = np.array([(cols - 1) * SQUARE / 2, (rows - 1) * SQUARE / 2, 0.0])
    poses = []
    for k in range(n_views):
        off_axis = np.radians(95.0) * np.sqrt((k + rng.uniform(0.2, 0.8)) / n_views)   # spread over the sphere's cap
        azimuth = 2.39996 * k + rng.uniform(-0.3, 0.3)                                # golden angle
        target = centre + np.array([*rng.uniform(-100, 100, 2), 0.0])
        poses.append(facing(target, _direction(off_axis, azimuth), rng.uniform(220, 320),
                            np.radians(rng.uniform(-30, 30, 2)), rng.uniform(-0.5, 0.5)))
    return np.array(poses)


def _wide_holdout_poses() -> np.ndarray:
    """The huge board straight ahead, and facing the camera from 55° and 95° off its axis all round."""
    cols, rows = HOLDOUT_BOARD
    centre = np.array([(cols - 1) * SQUARE / 2, (rows - 1) * SQUARE / 2, 0.0])
    poses = [facing(centre, np.array([0.0, 0.0, 1.0]), 400.0, np.zeros(2), 0.0)]
    for off_axis in np.radians([55.0, 95.0]):
        for a in np.radians(np.arange(0, 360, 45)):
            poses.append(facing(centre, _direction(off_axis, a), 400.0, np.zeros(2), 0.15))
    return np.array(poses)


def _holdout_poses() -> np.ndarray:
    """Fronto-parallel and tilted views of a huge board: the whole image covered."""
    cols, rows = HOLDOUT_BOARD
    centre = np.array([(cols - 1) * SQUARE / 2, (rows - 1) * SQUARE / 2, 0.0])
    poses = [look_at_pose(centre + [0, 0, -400.0], centre, 0.0)]
    for a in np.radians(np.arange(0, 360, 45)):
        d = np.array([np.cos(a), np.sin(a)])
        poses.append(look_at_pose(centre + [*(d * 250), -350.0], centre + [*(-d * 600), 0.0], 0.15))
    return np.array(poses)


def shoot(kind, poses, pts, sigma, rng, prefix):
    """The views of board points ``pts`` a camera at ``poses`` sees through the true lens, with noise ``sigma``
    (views with fewer than 20 corners left out), and the poses kept."""
    views, kept_poses = [], []
    ids = np.arange(len(pts))
    for k, pose in enumerate(poses):
        ok, uv = _visible(kind, pose, pts)
        if ok.sum() < 20:
            continue
        noisy = uv[ok] + (rng.normal(0.0, sigma, size=(ok.sum(), 2)) if sigma > 0 else 0.0)
        views.append(View(f"{prefix}{k:02d}", pts[ok], noisy, ids[ok]))
        kept_poses.append(pose)
    return views, np.array(kept_poses)


@dataclass
class SynthSet:
    train: Observations
    holdout: Observations
    truth: dict[str, Any]


def generate(kind: str = "radial", sigma: float = 0.3, seed: int = 0, n_views: int = 10) -> SynthSet:
    """Training (noisy), hold-out (noise-free, whole image) and the truth."""
    if kind not in ALL_KINDS:
        raise ValueError(f"unknown synthetic kind {kind!r}; expected one of {ALL_KINDS}")
    rng = np.random.default_rng(seed)
    wide = kind in WIDE_KINDS
    cols, rows = TRAIN_BOARD
    board = {"type": "chessboard", "cols": cols, "rows": rows, "square_size": SQUARE, "units": "mm"}
    train = _wide_train_poses(rng, n_views) if wide else _train_poses(rng, n_views)
    train_views, train_poses = shoot(kind, train, board_points(cols, rows), sigma, rng, "train_")
    hc, hr = HOLDOUT_BOARD
    hboard = {"type": "chessboard", "cols": hc, "rows": hr, "square_size": SQUARE, "units": "mm"}
    hold = _wide_holdout_poses() if wide else _holdout_poses()
    hold_views, hold_poses = shoot(kind, hold, board_points(hc, hr), 0.0, rng, "holdout_")
    fx, fy, cx, cy = INTRINSICS
    truth = {
        "format": TRUTH_FORMAT,
        "kind": kind,
        "sigma": sigma,
        "seed": seed,
        "image_size": list(IMAGE_SIZE),
        "intrinsics": {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "skew": 0.0},
        "lens": LENSES[kind],
        "train_views": [{"name": v.name, "rvec": p[:3].tolist(), "tvec": p[3:].tolist()} for v, p in zip(train_views, train_poses, strict=True)],
        "holdout_views": [{"name": v.name, "rvec": p[:3].tolist(), "tvec": p[3:].tolist()} for v, p in zip(hold_views, hold_poses, strict=True)],
    }
    return SynthSet(Observations(IMAGE_SIZE, train_views, board), Observations(IMAGE_SIZE, hold_views, hboard), truth)
