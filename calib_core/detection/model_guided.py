"""Re-detection with a first calibration: every board corner predicted through the lens.

As TartanCalib does: once a model exists, the board's pose in a view follows
from the corners already found (PnP on their rays), and every other corner of
the board is projected through the model. Each prediction is then confirmed
like a grown corner (``grow.confirm``: cornerSubPix with a window of a quarter
of the local square, the X-junction, four-arm and stability tests), so a
model that is off only costs corners, never ids. Growth then continues from
whatever was added. Corners are predicted on the lattice of the view's own ids,
so partial plain chessboards (ids up to a shift of the board) work too.
"""
from __future__ import annotations

import cv2
import numpy as np

from ..models import camera
from ..models.unproject import normalised_of_pixel
from .grow import Lattice, confirm, shift
from .image_circle import UnlitDistance

MIN_RAY_Z = 0.1   # rays within ~84° of the axis go into PnP (its pinhole form needs z > 0)


def view_pose(model, obj: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """Board → camera (rvec, tvec) of a view from its corners through the model, or None."""
    rays = camera.ray_of(normalised_of_pixel(model, pts), model.base)
    ok = np.all(np.isfinite(rays), axis=1) & (rays[:, 2] > MIN_RAY_Z)
    if ok.sum() < 6:
        return None
    xn = rays[ok, :2] / rays[ok, 2:]
    good, rvec, tvec = cv2.solvePnP(obj[ok], xn, np.eye(3), None, flags=cv2.SOLVEPNP_ITERATIVE)
    return (rvec.ravel(), tvec.ravel()) if good else None


def predict_through_model(model, lat: Lattice, square: float) -> np.ndarray | None:
    """(R, C, 2) pixels of every lattice position of the board (within its size around the
    corners found) through the model at the view's pose; NaN behind the camera. None
    if the pose cannot be had."""
    i, j = np.nonzero(lat.known)
    def obj_of(r, c):
        return np.stack([(c - lat.c0) * square, (r - lat.r0) * square, np.zeros(len(r))], 1)
    pose = view_pose(model, obj_of(i, j), lat.p[i, j])
    if pose is None:
        return None
    R, C = lat.known.shape
    ii, jj = (a.ravel() for a in np.indices((R, C)))
    pc = camera.rotate(pose[0], obj_of(ii, jj)) + pose[1]
    uv = np.full((R * C, 2), np.nan)
    front = pc[:, 2] > 1e-6
    with np.errstate(all="ignore"):
        uv[front] = model.project(pc[front])
    return uv.reshape(R, C, 2)


def model_guided(gray: np.ndarray, model, square: float):
    """An ``after_growth`` hook for ``grow.grow_board``: confirm every model-predicted corner
    the growth did not reach; returns how many it added."""
    def hook(lat: Lattice, unlit: np.ndarray | UnlitDistance) -> int:
        guess = predict_through_model(model, lat, square)
        if guess is None:
            return 0
        # Local lattice steps from the prediction itself: it is complete where the lattice is not.
        e_col = shift(guess, 0, -1) - guess
        e_row = shift(guess, -1, 0) - guess
        cand = (~lat.known & np.isfinite(guess[..., 0]) & np.isfinite(e_col[..., 0]) & np.isfinite(e_row[..., 0])
                & lat.box_allows())
        return confirm(gray, lat, cand, guess, e_col, e_row, unlit)
    return hook
