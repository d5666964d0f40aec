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
    matrices = _matrices(np.ascontiguousarray(poses[:, :3]))
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


def off_axis(pc: np.ndarray) -> np.ndarray:
    """Each camera-frame point's angle off the optical axis (N,), θ = atan2(ρ, Z)
    (formats.md): past 90° for points behind the camera's plane."""
    return np.arctan2(np.hypot(pc[:, 0], pc[:, 1]), pc[:, 2])


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
    return _retracted(np.ascontiguousarray(poses, dtype=np.float64), np.ascontiguousarray(delta, dtype=np.float64))


# Rotations for the solver's few dozen poses an iteration, compiled: scipy's Rotation
# costs ~50 µs a call in object creation, more than the arithmetic. Its algorithms:
# unit quaternions (x, y, z, w), Taylor series below 1e-3 rad.
@njit(cache=True, nogil=True)
def _quaternion(rx, ry, rz):  # pragma: no cover (compiled)
    angle = np.sqrt(rx * rx + ry * ry + rz * rz)
    if angle <= 1e-3:
        a2 = angle * angle
        scale = 0.5 - a2 / 48 + a2 * a2 / 3840
    else:
        scale = np.sin(angle / 2) / angle
    return scale * rx, scale * ry, scale * rz, np.cos(angle / 2)


@njit(cache=True, nogil=True)
def _matrix(x, y, z, w, out):  # pragma: no cover (compiled)
    x2, y2, z2, w2 = x * x, y * y, z * z, w * w
    xy, zw, xz, yw, yz, xw = x * y, z * w, x * z, y * w, y * z, x * w
    out[0, 0], out[0, 1], out[0, 2] = x2 - y2 - z2 + w2, 2 * (xy - zw), 2 * (xz + yw)
    out[1, 0], out[1, 1], out[1, 2] = 2 * (xy + zw), -x2 + y2 - z2 + w2, 2 * (yz - xw)
    out[2, 0], out[2, 1], out[2, 2] = 2 * (xz - yw), 2 * (yz + xw), -x2 - y2 + z2 + w2


@njit(cache=True, nogil=True)
def _matrices(rvecs):  # pragma: no cover (compiled)
    """(V, 3, 3) rotation matrices of rotation vectors (V, 3)."""
    out = np.empty((len(rvecs), 3, 3))
    for v in range(len(rvecs)):
        x, y, z, w = _quaternion(rvecs[v, 0], rvecs[v, 1], rvecs[v, 2])
        _matrix(x, y, z, w, out[v])
    return out


@njit(cache=True, nogil=True)
def _retracted(poses, delta):  # pragma: no cover (compiled)
    """``retract_poses``: the quaternion product exp(ω)·R, back to a rotation
    vector, and exp(ω) t + ν."""
    out = np.empty_like(poses)
    m = np.empty((3, 3))
    for v in range(len(poses)):
        px, py, pz, pw = _quaternion(delta[v, 0], delta[v, 1], delta[v, 2])
        qx, qy, qz, qw = _quaternion(poses[v, 0], poses[v, 1], poses[v, 2])
        w = pw * qw - (px * qx + py * qy + pz * qz)
        x = pw * qx + qw * px + (py * qz - pz * qy)
        y = pw * qy + qw * py + (pz * qx - px * qz)
        z = pw * qz + qw * pz + (px * qy - py * qx)
        if w < 0:  # the rotation vector of angle ≤ π
            x, y, z, w = -x, -y, -z, -w
        angle = 2 * np.arctan2(np.sqrt(x * x + y * y + z * z), w)
        if angle <= 1e-3:
            a2 = angle * angle
            scale = 2 + a2 / 12 + 7 * a2 * a2 / 2880
        else:
            scale = angle / np.sin(angle / 2)
        out[v, 0], out[v, 1], out[v, 2] = scale * x, scale * y, scale * z
        _matrix(px, py, pz, pw, m)
        for r in range(3):
            out[v, 3 + r] = m[r, 0] * poses[v, 3] + m[r, 1] * poses[v, 4] + m[r, 2] * poses[v, 5] + delta[v, 3 + r]
    return out


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
