"""The synthetic lenses: each kind's true distortion on normalised coordinates,
the camera behind it, and the protocol's boards (described in the package's
docstring)."""
from __future__ import annotations

import numpy as np

from ..models.camera import off_axis

PAPER_KINDS = ("radial", "fisheye", "asymmetric")  # the paper's Table 4 lenses
KINDS = PAPER_KINDS + ("freeform", "decentred")    # lenses on the pinhole plane (less than 180°)
# Lenses beyond 180°: defined on the angle off the axis, θ = atan2(√(X² + Y²), Z), so a point
# behind the camera's plane (Z < 0) keeps its side of the image (formats.md, fisheye type).
WIDE_KINDS = ("fisheye200",)
ALL_KINDS = KINDS + WIDE_KINDS
WIDE_K = (-0.032, 0.002)           # fisheye200: θd = θ (1 + k1 θ² + k2 θ⁴)
WIDE_HALF_FIELD_DEG = 100.0        # ... seeing 100° off the axis all round: a 200° field, an image circle
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
    "fisheye200": "a circular fisheye of 200 degrees: Kannala-Brandt theta_d = theta (1 - 0.032 theta^2 + "
                  "0.002 theta^4) on theta = atan2(sqrt(X^2 + Y^2), Z), light up to 100 degrees off the axis "
                  "(an image circle of about 490 px radius inside the frame); exactly --method fisheye's model",
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
    if kind in WIDE_KINDS:  # in front of the camera's plane: θ = atan r
        r = np.linalg.norm(x, axis=-1)
        scale = np.where(r > 1e-12, wide_radius(np.arctan(r)) / np.maximum(r, 1e-12), 1.0)
        return x * scale[:, None]
    raise ValueError(f"unknown synthetic kind {kind!r}; expected one of {ALL_KINDS}")


def wide_radius(theta: np.ndarray) -> np.ndarray:
    """fisheye200's distorted radius θd (normalised) of angles θ off the axis."""
    k1, k2 = WIDE_K
    return theta * (1 + k1 * theta**2 + k2 * theta**4)


def in_view(kind: str, pc: np.ndarray) -> np.ndarray:
    """(N,) bool: camera-frame points (N, 3) the lens takes light from (in front of a pinhole-plane
    lens; within a wide lens's field, behind the camera's plane too)."""
    if kind in WIDE_KINDS:
        return off_axis(pc) <= np.radians(WIDE_HALF_FIELD_DEG)
    return pc[:, 2] > 1e-6


def true_project(kind: str, pc: np.ndarray) -> np.ndarray:
    """Pixels (N, 2) of camera-frame points (N, 3) through the true lens (``in_view`` points)."""
    fx, fy, cx, cy = INTRINSICS
    if kind in WIDE_KINDS:
        rho = np.hypot(pc[:, 0], pc[:, 1])
        theta = np.arctan2(rho, pc[:, 2])
        scale = np.where(rho > 1e-12, wide_radius(theta) / np.maximum(rho, 1e-300), 1.0 / np.maximum(pc[:, 2], 1e-300))
        xd = pc[:, :2] * scale[:, None]
    else:
        xd = true_distort(kind, pc[:, :2] / pc[:, 2:])
    return np.stack([fx * xd[:, 0] + cx, fy * xd[:, 1] + cy], axis=-1)


def true_rays(kind: str, pixels: np.ndarray) -> np.ndarray:
    """Unit rays (N, 3) of pixels (N, 2) through a wide lens (NaN outside its image circle):
    θ from θd by Newton's method (θd(θ) rises monotonically over the field)."""
    if kind not in WIDE_KINDS:
        raise ValueError(f"true_rays is for the lenses past 180° ({WIDE_KINDS}); got {kind!r}")
    fx, fy, cx, cy = INTRINSICS
    xd = (pixels - [cx, cy]) / [fx, fy]
    thd = np.hypot(xd[:, 0], xd[:, 1])
    theta = thd.copy()
    k1, k2 = WIDE_K
    for _ in range(30):
        step = (wide_radius(theta) - thd) / (1 + 3 * k1 * theta**2 + 5 * k2 * theta**4)
        theta -= step
        if np.all(np.abs(step) < 1e-14):
            break
    phi = np.arctan2(xd[:, 1], xd[:, 0])
    rays = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=-1)
    rays[theta > np.radians(WIDE_HALF_FIELD_DEG)] = np.nan
    return rays
