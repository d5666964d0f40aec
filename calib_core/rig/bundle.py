"""The rig's joint fit: every camera's model (its free parameters and its
regularisation, as its own calibration fitted them), the cameras' poses
relative to the reference camera and the board's pose at every frame, by
Levenberg–Marquardt on the sparse normal equations. Poses are perturbed on
the left (``camera.retract_poses``), as the single-camera solver does."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.spatial.transform import Rotation

from ..fitting.solve import drop_held, model_columns
from ..models import camera
from ..models.base import CameraModel

MAX_ITERATIONS = 200
FTOL = 1e-10


@dataclass(frozen=True)
class Corners:
    """Every camera's inlier corners: per corner its camera, frame, the
    camera's view index, board point and observed pixel."""

    camera: np.ndarray  # (N,)
    frame: np.ndarray  # (N,)
    view: np.ndarray  # (N,)
    object_points: np.ndarray  # (N, 3)
    image_points: np.ndarray  # (N, 2)


@dataclass
class Adjusted:
    models: list[CameraModel]
    extrinsics: np.ndarray  # (C, 6), the first (reference) zero
    frames: np.ndarray  # (F, 6) board → reference camera
    residuals: np.ndarray  # (N, 2) projected − observed
    cost: float
    iterations: int
    status: str


@dataclass
class _State:
    models: list[CameraModel]
    extrinsics: np.ndarray
    frames: np.ndarray


def adjust(corners: Corners, models: list[CameraModel], extrinsics: np.ndarray, frames: np.ndarray,
           refine_models: bool = True, refine_extrinsics: bool = True) -> Adjusted:
    """Levenberg–Marquardt from ``models``, ``extrinsics`` (C, 6) and
    ``frames`` (F, 6); ``refine_models`` False holds every model (OpenCV's
    ``stereoCalibrate`` with ``CALIB_FIX_INTRINSIC``); ``refine_extrinsics``
    False holds the cameras' relative poses too (a hold-out: only the frames
    are fitted)."""
    columns = _Columns(models, refine_models, refine_extrinsics, len(models), len(frames))
    state = _State(list(models), extrinsics, frames)
    res, jac = _evaluate(corners, state, columns, jacobian=True)
    cost = float(res @ res)
    mu, status, it = 1e-4, "max_iterations", 0
    for it in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (read after the loop)
        normal = (jac.T @ jac).tocsc()
        gradient = jac.T @ res
        diag = np.maximum(normal.diagonal(), 1e-12 * max(normal.diagonal().max(), 1.0))
        while True:
            step = spla.spsolve(normal + sp.diags(mu * diag).tocsc(), -gradient)
            trial = columns.apply(state, step)
            trial_res = _evaluate(corners, trial, columns)
            trial_cost = _cost(trial_res, trial, columns)
            if np.isfinite(trial_cost) and trial_cost <= cost:
                break
            mu *= 4
            if mu > 1e12:
                status = "stalled"
                break
        if status == "stalled":
            break
        gain = cost - trial_cost
        state, cost = trial, trial_cost
        mu = max(mu / 3, 1e-12)
        if gain <= FTOL * max(cost, 1e-300):
            status = "converged"
            break
        res, jac = _evaluate(corners, state, columns, jacobian=True)
    pixels = _pixel_residuals(corners, state)
    return Adjusted(state.models, state.extrinsics, state.frames, pixels, cost, it, status)


class _Columns:
    """The unknowns' layout: each camera's free model parameters (none when
    held), the non-reference cameras' poses, the frames' poses."""

    def __init__(self, models: list[CameraModel], refine_models: bool, refine_extrinsics: bool, n_cameras: int,
                 n_frames: int):
        self.model_columns = []  # per camera: (n_params,) column of each parameter, −1 if held
        offset = 0
        for m in models:
            col = model_columns(m.n_params, m.free_mask()) if refine_models else np.full(m.n_params, -1)
            self.model_columns.append(np.where(col >= 0, col + offset, -1))
            offset += int((col >= 0).sum())
        self.refine_models = refine_models
        self.refine_extrinsics = refine_extrinsics
        self.extrinsics = offset
        self.frames = offset + (6 * (n_cameras - 1) if refine_extrinsics else 0)
        self.total = self.frames + 6 * n_frames

    def apply(self, state: _State, step: np.ndarray) -> _State:
        models = []
        for m, col in zip(state.models, self.model_columns, strict=True):
            free = col >= 0
            models.append(m.with_params(np.where(free, m.params() + step[np.maximum(col, 0)] * free, m.params()))
                          if free.any() else m)
        ext = state.extrinsics.copy()
        if self.refine_extrinsics:
            ext[1:] = camera.retract_poses(ext[1:], step[self.extrinsics:self.frames].reshape(-1, 6))
        return _State(models, ext, camera.retract_poses(state.frames, step[self.frames:].reshape(-1, 6)))


def _points(corners: Corners, state: _State):
    p_ref = camera.transform(state.frames, corners.frame, corners.object_points)
    return p_ref, camera.transform(state.extrinsics, corners.camera, p_ref)


def _pixel_residuals(corners: Corners, state: _State) -> np.ndarray:
    _, pc = _points(corners, state)
    res = np.empty((len(pc), 2))
    for c, model in enumerate(state.models):
        mine = corners.camera == c
        res[mine] = model.project(pc[mine]) - corners.image_points[mine]
    return res


def _priors(state: _State, columns: _Columns):
    """Each refined model's regularisation rows (``CameraModel.prior``), on the layout's columns."""
    rows: list[np.ndarray] = []
    blocks: list[sp.csr_matrix] = []
    if not columns.refine_models:
        return rows, blocks
    for m, col in zip(state.models, columns.model_columns, strict=True):
        prior = m.prior()
        if prior is None:
            continue
        r, j = prior
        j = sp.csr_matrix(j)[:, np.flatnonzero(col >= 0)]
        placed = sp.csr_matrix((j.data, col[col >= 0][j.indices], j.indptr), shape=(j.shape[0], columns.total))
        rows.append(r)
        blocks.append(placed)
    return rows, blocks


def _cost(pixels: np.ndarray, state: _State, columns: _Columns) -> float:
    rows, _ = _priors(state, columns)
    total = float(np.sum(pixels * pixels)) + sum(float(np.sum(r * r)) for r in rows)
    return total if np.isfinite(total) else np.inf


def _evaluate(corners: Corners, state: _State, columns: _Columns, jacobian: bool = False):
    """The residual vector (corners' pixels, then the models' priors) and,
    with ``jacobian``, its sparse Jacobian on ``columns``."""
    if not jacobian:
        return _pixel_residuals(corners, state)
    p_ref, pc = _points(corners, state)
    n = len(pc)
    res = np.empty((n, 2))
    d_pc = np.empty((n, 2, 3))
    rows_of = np.arange(2 * n).reshape(n, 2)
    entries_r, entries_c, entries_v = [], [], []
    for c, model in enumerate(state.models):
        mine = np.flatnonzero(corners.camera == c)
        uv, d, cols, vals = model.project(pc[mine], jacobian=True)
        res[mine] = uv - corners.image_points[mine]
        d_pc[mine] = d
        col = columns.model_columns[c]
        if (col >= 0).any():
            cols, vals = drop_held(col[cols], vals)
            entries_r.append(np.broadcast_to(rows_of[mine][:, :, None], cols.shape).ravel())
            entries_c.append(cols.ravel())
            entries_v.append(vals.ravel())
    rot = Rotation.from_rotvec(state.extrinsics[:, :3]).as_matrix()[corners.camera]  # (N, 3, 3)
    pose_rows = np.broadcast_to(rows_of[:, :, None], (n, 2, 6))
    entries_r.append(pose_rows.ravel())
    entries_c.append(np.broadcast_to(columns.frames + 6 * corners.frame[:, None, None] + np.arange(6), (n, 2, 6)).ravel())
    entries_v.append((d_pc @ rot @ camera.d_transform(p_ref)).ravel())
    moving = corners.camera > 0 if columns.refine_extrinsics else np.zeros(n, dtype=bool)  # the reference's is fixed
    k = int(moving.sum())
    entries_r.append(pose_rows[moving].ravel())
    entries_c.append(np.broadcast_to(columns.extrinsics + 6 * (corners.camera[moving, None, None] - 1) + np.arange(6),
                                     (k, 2, 6)).ravel())
    entries_v.append((d_pc[moving] @ camera.d_transform(pc[moving])).ravel())
    jac = sp.csr_matrix((np.concatenate(entries_v), (np.concatenate(entries_r), np.concatenate(entries_c))),
                        shape=(2 * n, columns.total))
    prior_rows, prior_blocks = _priors(state, columns)
    r = np.concatenate([res.ravel(), *prior_rows])
    if prior_blocks:
        jac = sp.vstack([jac, *prior_blocks]).tocsr()
    return r, jac
