"""The paper's synthetic protocol (method.md §"Evaluation protocol"), with
ground truth.

Camera: fx = 305.18, fy = 302.45, cx = 511.61, cy = 631.89, 1024 × 1280
(≈ 118° × 129° through a pinhole). Five lenses (``KINDS``), all on normalised
coordinates ``(x, y) = (X/Z, Y/Z)``; ``LENSES`` describes each in a sentence
(it is the truth's ``lens``). The paper's three (``PAPER_KINDS``):

- ``radial``: OpenCV's model, k1 = 0.05, k2 = 0.0267, k3 = 0.0067,
  p1 = 0.0067, p2 = 0.01 (exactly representable by ``--method zhang``);
- ``fisheye``: Kannala–Brandt angle polynomial k1..k4 = 0.05, 0.02, 0.01,
  0.005 on θ = atan r, then OpenCV tangential p1 = p2 = 1e-4;
- ``asymmetric``: the paper leaves it unspecified; ours is a mild radial
  term, quadrant-dependent cubic offsets blended smoothly across the axes,
  and two global sinusoids (``asymmetric_offset`` below): no parametric model
  represents it.

and two more that no textbook model (OpenCV 5/8 coefficients, Kannala–Brandt)
represents either, each smooth, one-to-one and with a positive Jacobian over
the whole half-space in front of the camera (so the Newton inversion of
``render`` and the models' unprojection converge everywhere):

- ``freeform``: a freeform surface with no symmetry: a mild radial term plus
  a vector Zernike-like expansion (different x and y barrel, trefoil,
  quadrafoil, a 5th-order anisotropic term) and a Gaussian bump, all in the
  ray's direction cosines (``freeform_offset``);
- ``decentred``: a decentred, tilted element: radial distortion about a
  centre 0.1 off the principal point, then the keystone of the element's
  tilt, a projective map about that centre (``decentred_distort``).

Their radial terms have OpenCV's positive sign, like the paper's: an
expanding map, which stays one-to-one however far off axis (a negative k1
folds back at r = 1/√(3|k1|), inside this field of view).

Training views see a large 22 × 22 board of 50 mm squares from close by,
filling the frame, from 10 poses tilted every way; corners outside the image are dropped; noise is
Gaussian, σ per axis. Hold-out views are noise-free views of a much larger
board that together cover the whole image, corners included.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from .observations import Observations, View

PAPER_KINDS = ("radial", "fisheye", "asymmetric")  # the paper's Table 4 lenses
KINDS = PAPER_KINDS + ("freeform", "decentred")
LENSES = {  # the truth's "lens": what each kind is, in a sentence
    "radial": "OpenCV's model, k1 = 0.05, k2 = 0.0267, k3 = 0.0067, p1 = 0.0067, p2 = 0.01 "
              "(exactly representable by --method zhang)",
    "fisheye": "Kannala-Brandt angle polynomial k1..k4 = 0.05, 0.02, 0.01, 0.005 on theta = atan r, "
               "then OpenCV tangential p1 = p2 = 1e-4",
    "asymmetric": "a mild radial term, quadrant-dependent cubic offsets blended smoothly across the axes "
                  "and two global sinusoids (synth.asymmetric_offset): no parametric model represents it",
    "freeform": "a freeform surface with no symmetry: OpenCV radial k1 = 0.04, k2 = 0.004, plus a vector "
                "Zernike-like offset in the ray's direction cosines (different x/y barrel, trefoil, "
                "quadrafoil, 5th-order anisotropic term, Gaussian bump; synth.freeform_offset): "
                "no parametric model represents it",
    "decentred": "a decentred, tilted element: radial k1 = 0.065, k2 = 0.006 about a centre (0.08, -0.06) "
                 "off the principal point, then the tilt's keystone x/(1 + 0.03 x - 0.025 y) about that "
                 "centre (synth.decentred_distort): no parametric model represents it",
}
IMAGE_SIZE = (1024, 1280)
INTRINSICS = (305.18, 302.45, 511.61, 631.89)
SQUARE = 50.0
TRAIN_BOARD = (22, 22)  # inner corners (cols, rows)
HOLDOUT_BOARD = (80, 80)
TRUTH_FORMAT = "freecal.synth-truth/1"


def opencv_distort(x: np.ndarray, k1, k2, k3, p1, p2) -> np.ndarray:
    r2 = np.sum(x * x, axis=-1)
    radial = 1 + k1 * r2 + k2 * r2**2 + k3 * r2**3
    xx, yy = x[:, 0], x[:, 1]
    return np.stack(
        [xx * radial + 2 * p1 * xx * yy + p2 * (r2 + 2 * xx * xx), yy * radial + p1 * (r2 + 2 * yy * yy) + 2 * p2 * xx * yy],
        axis=-1,
    )


def _blend(t: np.ndarray, a, b, width: float = 0.5) -> np.ndarray:
    """a for t ≪ 0, b for t ≫ 0, smooth in between."""
    s = 0.5 * (1 + np.tanh(t / width))
    return a + (b - a) * s


def asymmetric_offset(x: np.ndarray) -> np.ndarray:
    """Offset of the asymmetric lens in normalised units, (N, 2) → (N, 2)."""
    xx, yy = x[:, 0], x[:, 1]
    r2 = xx * xx + yy * yy
    # Quadrant-dependent cubic terms: each half-plane pulls differently.
    ax = _blend(xx, 0.035, 0.055) + _blend(yy, -0.006, 0.008)
    ay = _blend(yy, 0.030, 0.050) + _blend(xx, 0.007, -0.005)
    dx = ax * xx * r2 + 0.004 * yy * yy
    dy = ay * yy * r2 - 0.003 * xx * xx
    # Global sinusoids (about ±1.2 px).
    dx += 0.004 * np.sin(2.4 * xx + 0.8) * np.cos(1.6 * yy)
    dy += 0.004 * np.cos(2.1 * xx) * np.sin(2.6 * yy + 0.4)
    return np.stack([dx, dy], axis=-1)


def direction_cosines(x: np.ndarray) -> np.ndarray:
    """(X, Y)/|P| of the ray through normalised ``x`` (N, 2): bounded by 1 over the
    whole half-space in front of the camera, with derivatives ≤ 1: the unit disk
    a Zernike expansion lives on (ρ ≈ 0.9 at the corners of this camera's image)."""
    return x / np.sqrt(1.0 + np.sum(x * x, axis=-1, keepdims=True))


def freeform_offset(x: np.ndarray) -> np.ndarray:
    """Offset of the freeform lens in normalised units, (N, 2) → (N, 2).

    Models a freeform (non-rotationally-symmetric) surface, as in off-axis and
    head-mounted optics; ``true_distort`` adds it to OpenCV radial k1 = 0.04,
    k2 = 0.004 (an expanding map B). It is a vector expansion of the image
    displacement in the ray's direction cosines w = a + ib
    (``direction_cosines``), as a complex number d = dx + i·dy:

    - different radial terms in x and y (ρ² = |w|²):        (0.050·a − 0.020i·b)·ρ²
    - trefoil (3-fold):                                    0.012·e^{0.6i}·w̄²
    - quadrafoil (4-fold):                                 0.010·e^{-1.1i}·w̄³
    - 5th-order anisotropic term:                          (−0.020·a + 0.030i·b)·ρ⁴
    - a local Gaussian bump (a surface blemish):           0.006·e^{1.2i}·exp(−|w − w₀|²/(2·0.2²)),
      w₀ = 0.35 − 0.30i

    None is radial (OpenCV's radial terms are w·ρ^{2k}, its tangential ones
    2P·ρ² + P̄·w²), so no textbook model represents it. Every term is a
    polynomial or a bump on the unit disk, so the offset is bounded (|d| < 0.11,
    ≈ 33 px) and Lipschitz with a constant < 0.4: added to an expanding radial
    map (Jacobian singular values ≥ 1, so |B(x) − B(y)| ≥ |x − y|) it keeps the
    lens one-to-one with a positive Jacobian everywhere (det ≥ 0.99 measured).
    The departure from the best OpenCV-rational fit is ≈ 1.6 px rms, 14 px at
    worst, on the hold-out views.
    """
    w = direction_cosines(x)
    a, b = w[:, 0], w[:, 1]
    z = a + 1j * b
    zc = np.conj(z)
    rho2 = a * a + b * b
    d = (0.050 * a - 0.020j * b) * rho2
    d += 0.012 * np.exp(0.6j) * zc**2
    d += 0.010 * np.exp(-1.1j) * zc**3
    d += (-0.020 * a + 0.030j * b) * rho2**2
    d += 0.006 * np.exp(1.2j) * np.exp(-np.abs(z - (0.35 - 0.30j)) ** 2 / (2 * 0.2**2))
    return np.stack([d.real, d.imag], axis=-1)


DECENTRE = (0.08, -0.06)  # the element's axis, normalised units from the principal point
TILT = (0.03, -0.025)     # keystone of the element's tilt, per normalised unit


def decentred_distort(x: np.ndarray) -> np.ndarray:
    """The decentred, tilted lens: distorted normalised coordinates of ``x`` (N, 2).

    Models an element mounted off the optical axis and slightly tilted, as in a
    badly assembled or shifted lens: in the element's frame ``e = x − c``
    (c = ``DECENTRE``) a radial distortion e·(1 + 0.065·|e|² + 0.006·|e|⁴), then
    the tilt's keystone, the projective map e' = e / (1 + t·e) (t = ``TILT``),
    and back: x' = c + e'. To first order in c a decentred radial term is
    OpenCV's tangential one; its higher orders (the decentred k2 term, the
    keystone's quadratic terms −e·(t·e), the cross terms) are not in any
    textbook model: ≈ 0.7 px rms, 9 px at worst from the best OpenCV-rational
    fit on the hold-out views.

    The radial map is expanding and one-to-one, the projective one is one-to-one
    with a positive Jacobian on the half-plane 1 + t·e > 0, and the rest of the
    plane maps to t·e' > 1, i.e. ≥ 25 normalised units away: far outside the image.
    """
    c = np.asarray(DECENTRE)
    t = np.asarray(TILT)
    e = x - c
    r2 = np.sum(e * e, axis=-1, keepdims=True)
    e = e * (1 + 0.065 * r2 + 0.006 * r2 * r2)
    return c + e / (1 + e @ t)[:, None]


def true_distort(kind: str, x: np.ndarray) -> np.ndarray:
    """Distorted normalised coordinates of pinhole-normalised ``x`` (N, 2)."""
    if kind == "radial":
        return opencv_distort(x, 0.05, 0.0267, 0.0067, 0.0067, 0.01)
    if kind == "fisheye":
        r = np.linalg.norm(x, axis=-1)
        th = np.arctan(r)
        thd = th * (1 + 0.05 * th**2 + 0.02 * th**4 + 0.01 * th**6 + 0.005 * th**8)
        scale = np.where(r > 1e-12, thd / np.maximum(r, 1e-12), 1.0)
        return opencv_distort(x * scale[:, None], 0, 0, 0, 1e-4, 1e-4)
    if kind == "asymmetric":
        return x + asymmetric_offset(x)
    if kind == "freeform":
        return opencv_distort(x, 0.04, 0.004, 0, 0, 0) + freeform_offset(x)
    if kind == "decentred":
        return decentred_distort(x)
    raise ValueError(f"unknown synthetic kind {kind!r}; expected one of {KINDS}")


def true_project(kind: str, pc: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of camera-frame points (N, 3) through the true lens."""
    fx, fy, cx, cy = INTRINSICS
    xd = true_distort(kind, pc[:, :2] / pc[:, 2:])
    return np.stack([fx * xd[:, 0] + cx, fy * xd[:, 1] + cy], axis=-1)


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
    pc = Rotation.from_rotvec(pose[:3]).apply(pts) + pose[3:]
    ok = pc[:, 2] > 1e-6
    uv = np.full((len(pts), 2), np.nan)
    uv[ok] = true_project(kind, pc[ok])
    w, h = IMAGE_SIZE
    # Keep corners seen at most ~80° off axis: a real board corner further out
    # is too foreshortened to detect.
    cos_angle = pc[:, 2] / np.linalg.norm(pc, axis=1)
    ok &= (cos_angle > np.cos(np.radians(80))) & np.all(np.isfinite(uv), axis=1)
    ok &= (uv[:, 0] >= margin) & (uv[:, 0] <= w - 1 - margin) & (uv[:, 1] >= margin) & (uv[:, 1] <= h - 1 - margin)
    return ok, uv


def _pose_looking_at(target: np.ndarray, dist: float, tilt: np.ndarray, roll: float) -> np.ndarray:
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
        poses.append(_pose_looking_at(target, rng.uniform(160, 220), tilt, rng.uniform(-0.5, 0.5)))
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


def _views(kind, poses, pts, sigma, rng, prefix):
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
    if kind not in KINDS:
        raise ValueError(f"unknown synthetic kind {kind!r}; expected one of {KINDS}")
    rng = np.random.default_rng(seed)
    cols, rows = TRAIN_BOARD
    board = {"type": "chessboard", "cols": cols, "rows": rows, "square_size": SQUARE, "units": "mm"}
    train_views, train_poses = _views(kind, _train_poses(rng, n_views), board_points(cols, rows), sigma, rng, "train_")
    hc, hr = HOLDOUT_BOARD
    hboard = {"type": "chessboard", "cols": hc, "rows": hr, "square_size": SQUARE, "units": "mm"}
    hold_views, hold_poses = _views(kind, _holdout_poses(), board_points(hc, hr), 0.0, rng, "holdout_")
    fx, fy, cx, cy = INTRINSICS
    truth = {
        "format": TRUTH_FORMAT,
        "kind": kind,
        "sigma": sigma,
        "seed": seed,
        "image_size": list(IMAGE_SIZE),
        "intrinsics": {"fx": fx, "fy": fy, "cx": cx, "cy": cy, "skew": 0.0},
        "lens": LENSES[kind],
        "train_views": [{"name": v.name, "rvec": p[:3].tolist(), "tvec": p[3:].tolist()} for v, p in zip(train_views, train_poses)],
        "holdout_views": [{"name": v.name, "rvec": p[:3].tolist(), "tvec": p[3:].tolist()} for v, p in zip(hold_views, hold_poses)],
    }
    return SynthSet(Observations(IMAGE_SIZE, train_views, board), Observations(IMAGE_SIZE, hold_views, hboard), truth)
