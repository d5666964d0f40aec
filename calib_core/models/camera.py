"""Rigid poses and the base projections of ``formats.md`` §2, with Jacobians.

Conventions (OpenCV's): ``Pc = R(rvec) · P + tvec`` maps board points to the
camera frame, x right, y down, z forward. Poses are stored as (V, 6) arrays
``[rvec | tvec]``. The solver perturbs a pose on the left,
``T ← exp(δ) · T`` with ``δ = (ω, ν)``, so that ``∂Pc/∂δ = [−[Pc]×  I₃]``.
"""
from __future__ import annotations

import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation

BASES = ("pinhole", "equidistant", "stereographic")
# A pinhole maps a ray θ off axis to tan θ: past this angle the ideal image runs
# off towards infinity, and pinhole-based models exclude such corners.
PINHOLE_MAX_ANGLE_DEG = 85.0


def rotate(rvecs: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Rotate points (N, 3) by rotation vectors (N, 3) or (3,)."""
    return Rotation.from_rotvec(rvecs).apply(points)


def transform(poses: np.ndarray, view_index: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Camera-frame points (N, 3) for board points (N, 3) seen in views ``view_index`` (N,):
    each view's rotation matrix built once, applied by a compiled loop (the
    same products and sums as rotating each point by its own rotation)."""
    poses = np.asarray(poses, dtype=np.float64)
    view_index = np.asarray(view_index)
    if poses.ndim != 2 or view_index.ndim != 1 or len(view_index) and not 0 <= view_index.min() <= view_index.max() < len(poses):
        p = poses[view_index]  # numpy's indexing: its wrap-around and its errors
        return rotate(p[:, :3], points) + p[:, 3:]
    matrices = Rotation.from_rotvec(poses[:, :3]).as_matrix().reshape(-1, 3, 3)
    return _rigid(matrices, np.ascontiguousarray(poses[:, 3:]), np.asarray(view_index, dtype=np.int64),
                  np.ascontiguousarray(points, dtype=np.float64))


@njit(cache=True, nogil=True)
def _rigid(matrices, translations, view, points):  # pragma: no cover (compiled)
    out = np.empty((len(view), 3))
    for i in range(len(view)):
        v = view[i]
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        for r in range(3):
            out[i, r] = matrices[v, r, 0] * x + matrices[v, r, 1] * y + matrices[v, r, 2] * z + translations[v, r]
    return out


def d_transform(pc: np.ndarray) -> np.ndarray:
    """∂Pc/∂δ for the left perturbation δ = (ω, ν): (N, 3, 6)."""
    n = len(pc)
    out = np.zeros((n, 3, 6))
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    # −[Pc]× = [[0, z, −y], [−z, 0, x], [y, −x, 0]]
    out[:, 0, 1], out[:, 0, 2] = z, -y
    out[:, 1, 0], out[:, 1, 2] = -z, x
    out[:, 2, 0], out[:, 2, 1] = y, -x
    out[:, 0, 3] = out[:, 1, 4] = out[:, 2, 5] = 1.0
    return out


def retract_poses(poses: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """Apply left perturbations ``delta`` (V, 6): R ← exp(ω) R, t ← exp(ω) t + ν."""
    step = Rotation.from_rotvec(delta[:, :3])
    rot = step * Rotation.from_rotvec(poses[:, :3])
    return np.hstack([rot.as_rotvec(), step.apply(poses[:, 3:]) + delta[:, 3:]])


def normalise(pc: np.ndarray, base: str = "pinhole", jacobian: bool = False):
    """Normalised coordinates (N, 2) of camera-frame points by the base projection;
    with ``jacobian`` also ∂(xn, yn)/∂Pc (N, 2, 3)."""
    x, y, z = pc[:, 0], pc[:, 1], pc[:, 2]
    if base == "pinhole":
        iz = 1.0 / z
        xn = np.stack([x * iz, y * iz], axis=-1)
        if not jacobian:
            return xn
        jac = np.zeros((len(pc), 2, 3))
        jac[:, 0, 0] = iz
        jac[:, 1, 1] = iz
        jac[:, 0, 2] = -x * iz * iz
        jac[:, 1, 2] = -y * iz * iz
        return xn, jac
    if base not in BASES:
        raise ValueError(f"unknown base projection {base!r}; expected one of {BASES}")
    xn, jac = _angular(np.ascontiguousarray(pc, dtype=np.float64), base == "stereographic", jacobian)
    return (xn, jac) if jacobian else xn


@njit(cache=True, nogil=True, error_model="numpy")  # inf/nan as numpy gives, not an exception
def _angular(pc, stereographic, jacobian):  # pragma: no cover (compiled)
    """``normalise`` on an angular base, point by point: xn = g(θ) (X, Y) / ρ
    with θ = atan2(ρ, Z), g(θ) = θ (equidistant) or 2 tan(θ/2) (stereographic);
    with ``jacobian`` also ∂xn/∂Pc (N, 2, 3)."""
    n = len(pc)
    xn = np.empty((n, 2))
    jac = np.zeros((n if jacobian else 0, 2, 3))
    for i in range(n):
        x, y, z = pc[i, 0], pc[i, 1], pc[i, 2]
        rho2 = x * x + y * y
        rho = np.sqrt(rho2)
        theta = np.arctan2(rho, z)
        if stereographic:
            g, dg = 2.0 * np.tan(theta / 2), 1.0 / np.cos(theta / 2) ** 2
        else:
            g, dg = theta, 1.0
        # g/ρ → 1/Z as ρ → 0 for both bases (θ ≈ ρ/Z): the pinhole limit, and its derivative.
        small = rho < 1e-12 * max(abs(z), 1e-300)
        scale = 1.0 / z if small else g / rho
        xn[i, 0], xn[i, 1] = x * scale, y * scale
        if not jacobian:
            continue
        if small:
            jac[i, 0, 0] = jac[i, 1, 1] = 1.0 / z
            continue
        r2 = rho2 + z * z
        # ∂θ/∂(X, Y, Z) = (X Z / (ρ r²), Y Z / (ρ r²), −ρ / r²);
        # ∂scale/∂P = (dg θ' ρ − g ρ') / ρ², with ρ' = (X, Y, 0)/ρ
        dtheta = (x * z / (rho * r2), y * z / (rho * r2), -rho / r2)
        drho = (x / rho, y / rho, 0.0)
        for c in range(3):
            dscale = (dg * dtheta[c] * rho - g * drho[c]) / rho**2
            jac[i, 0, c] = x * dscale
            jac[i, 1, c] = y * dscale
        jac[i, 0, 0] += scale
        jac[i, 1, 1] += scale
    return xn, jac


def ray_of(xn: np.ndarray, base: str = "pinhole") -> np.ndarray:
    """Unit rays (N, 3) of normalised coordinates (N, 2): the inverse of ``normalise``."""
    x, y = xn[:, 0], xn[:, 1]
    if base == "pinhole":
        rays = np.stack([x, y, np.ones_like(x)], axis=-1)
        return rays / np.linalg.norm(rays, axis=-1, keepdims=True)
    r = np.hypot(x, y)
    theta = r if base == "equidistant" else 2.0 * np.arctan(r / 2)
    safe_r = np.where(r > 0, r, 1.0)
    s = np.where(r > 0, np.sin(theta) / safe_r, 1.0)
    return np.stack([x * s, y * s, np.cos(theta)], axis=-1)
