"""Lenses and boards simulated with OpenCV's own projections (or a plain
Kannala-Brandt formula past 180°), independent of the paper's synthetic
protocol (``protocol.py``) that the method was developed on: observations as
``freecal.observations/1`` would carry them, for the tests and for
``python -m benchmarks lenses``."""
from __future__ import annotations

import cv2
import numpy as np

from calib_core.models.camera import off_axis
from calib_core.observations import Observations

BOARD = np.array([[c * 30.0, r * 30.0, 0.0] for r in range(8) for c in range(11)])


def views_of(project, size, n, seed, sigma, distance, spread, bend=0.0):
    """Observations of BOARD seen ``n`` times (tilted up to 40°, shifted up to
    ``spread`` of the distance; the corners inside the image, at least 40 %
    of the board, as a board partly out of the frame is seen); ``bend`` (mm,
    a normal deviate's scale per view) bows the board out of its plane while
    its object points still say flat, as a printed board on card does."""
    rng = np.random.default_rng(seed)
    centre = BOARD[:, :2].mean(axis=0)
    q = (BOARD[:, :2] - centre) / np.abs(BOARD[:, :2] - centre).max()
    views: list[dict] = []
    while len(views) < n:
        rot = cv2.Rodrigues(np.radians(rng.uniform(-40, 40, 3)) * [1, 1, 0.5])[0]
        shift = np.r_[rng.uniform(-spread, spread, 2) * distance, distance * rng.uniform(0.8, 1.2)]
        bent = BOARD.copy()
        bent[:, 2] = rng.normal(0, bend) * np.sum(q**2, axis=1) + rng.normal(0, bend) * q[:, 0] * q[:, 1]
        pc = (bent - [*centre, 0.0]) @ rot.T + shift
        pixels = project(pc)
        inside = np.all((pixels >= 0) & (pixels <= np.array(size) - 1), axis=1) & (pc[:, 2] > 0)
        if inside.mean() >= 0.4:
            seen = pixels[inside] + rng.normal(0, sigma, (inside.sum(), 2))
            views.append({"name": f"v{len(views)}", "object_points": BOARD[inside].tolist(),
                          "image_points": seen.tolist(), "ids": np.flatnonzero(inside).tolist()})
    return Observations.from_json({"format": "freecal.observations/1", "image_size": list(size), "views": views})


def fisheye_lens(pc):
    k = np.array([[330.0, 0, 645], [0, 331, 508], [0, 0, 1]])
    d = np.array([0.02, -0.01, 0.003, -0.0005])
    return cv2.fisheye.projectPoints(pc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, d)[0].reshape(-1, 2)


WEBCAM = np.array([[600.0, 0, 327], [0, 600, 235], [0, 0, 1]])  # 640 x 480
HD = np.array([[700.0, 0, 641], [0, 700, 357], [0, 0, 1]])  # 1280 x 720


def opencv_lens(coefficients):
    """A 640 x 480 camera through OpenCV's model with these distortion coefficients (5, 8, 12 or 14)."""
    d = np.asarray(coefficients, dtype=float)
    return lambda pc: cv2.projectPoints(pc, np.zeros(3), np.zeros(3), WEBCAM, d)[0].reshape(-1, 2)


WEBCAM_DISTORTION = [-0.3, 0.12, 0.001, -0.002, -0.02]
webcam_lens = opencv_lens(WEBCAM_DISTORTION)
mustache_lens = opencv_lens([0.2, -0.4, 0, 0, 0.25])  # barrel in the middle, pincushion at the edge
prism_lens = opencv_lens([*WEBCAM_DISTORTION, 0, 0, 0, 0.004, -0.002, 0.003, 0.001])  # thin prism
tilted_lens = opencv_lens([*WEBCAM_DISTORTION, 0, 0, 0, 0, 0, 0, 0, 0.02, -0.015])  # tilted sensor


def through(lens, camera=HD, own=WEBCAM):
    """``lens`` (a 640 x 480 one, ``own`` its camera matrix) with its distortion seen through
    another ``camera``: the same normalised mapping, other pixels (at HD, the webcam lens's
    polynomial reaches 1.6 times further out)."""
    def project(pc):
        pixels = lens(pc)
        normalised = (pixels - own[:2, 2]) / np.diag(own)[:2]
        return normalised * np.diag(camera)[:2] + camera[:2, 2]
    return project


def elliptic_lens(pc, stretch=1.3, camera=WEBCAM):
    """Barrel distortion radial in a frame stretched ``stretch`` times along x (an
    anamorphic element's), through ``camera`` (3 x 3): no parametric model's, and
    smooth enough that each view's pose absorbs part of its error."""
    x, y = pc[:, 0] / pc[:, 2], pc[:, 1] / pc[:, 2]
    r2 = (x / stretch) ** 2 + y**2
    f = 1 - 0.3 * r2 + 0.08 * r2 * r2
    return np.column_stack([camera[0, 0] * x * f + camera[0, 2], camera[1, 1] * y * f + camera[1, 2]])


def rippled_lens(pc, amplitude=1.2):
    """The webcam lens and a smooth ripple of about ``amplitude`` pixels that no parametric model has (a moulded element's)."""
    pixels = webcam_lens(pc)
    x, y = pixels[:, 0] / 640, pixels[:, 1] / 480
    return pixels + amplitude * np.column_stack([np.sin(2 * np.pi * x) * np.cos(np.pi * y),
                                                 0.75 * np.cos(2 * np.pi * x + 0.5) * np.sin(np.pi * y)])


def equisolid_lens(pc, f=380.0, centre=(640.0, 512.0)):
    """An equisolid-angle fisheye, r = 2f sin(θ/2), on 1280 x 1024: a projection no model of
    freecal's has in closed form (Kannala-Brandt's polynomial approximates it)."""
    return _radial_projection(pc, 2 * f * np.sin(off_axis(pc) / 2), centre)


def stereographic_lens(pc, f=300.0, centre=(640.0, 512.0)):
    """A stereographic fisheye, r = 2f tan(θ/2), on 1280 x 1024."""
    return _radial_projection(pc, 2 * f * np.tan(off_axis(pc) / 2), centre)


def _radial_projection(pc, radius, centre):
    scale = radius / np.hypot(pc[:, 0], pc[:, 1])
    return np.column_stack([scale * pc[:, 0] + centre[0], scale * pc[:, 1] + centre[1]])


def beyond_180(pc):
    """A Kannala-Brandt lens of ~200° on 1280 x 1024 (θ from the optical axis, any sign of Z)."""
    k, d = (300.0, 301.0, 641.0, 509.0), (0.01, -0.005, 0.001, -0.0002)
    theta = off_axis(pc)
    scale = theta * (1 + d[0] * theta**2 + d[1] * theta**4 + d[2] * theta**6 + d[3] * theta**8) / np.hypot(pc[:, 0], pc[:, 1])
    return np.column_stack([k[0] * scale * pc[:, 0] + k[2], k[1] * scale * pc[:, 1] + k[3]])


def around(n, seed, sigma):
    """Views of BOARD facing the camera from up to 100° off its axis, 250-400 mm away."""
    rng = np.random.default_rng(seed)
    centre = BOARD[:, :2].mean(axis=0)
    views: list[dict] = []
    while len(views) < n:
        azimuth, off_axis = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(0, 100))
        towards = np.array([np.sin(off_axis) * np.cos(azimuth), np.sin(off_axis) * np.sin(azimuth), np.cos(off_axis)])
        x = np.cross([0.0, 1.0, 0.0], -towards)
        x /= np.linalg.norm(x)
        rot = np.column_stack([x, np.cross(-towards, x), -towards]) @ cv2.Rodrigues(np.radians(rng.uniform(-30, 30, 3)))[0]
        pixels = beyond_180((BOARD - [*centre, 0.0]) @ rot.T + towards * rng.uniform(250, 400))
        inside = np.all((pixels >= 0) & (pixels <= [1279, 1023]), axis=1)
        if inside.mean() >= 0.4:
            seen = pixels[inside] + rng.normal(0, sigma, (inside.sum(), 2))
            views.append({"name": f"v{len(views)}", "object_points": BOARD[inside].tolist(),
                          "image_points": seen.tolist(), "ids": np.flatnonzero(inside).tolist()})
    return Observations.from_json({"format": "freecal.observations/1", "image_size": [1280, 1024], "views": views})


RANDOM_KINDS = ("rational", "bumpy", "tilted", "fisheye")
RANDOM_SIZES = ((640, 480), (1280, 720), (1920, 1080), (1024, 1024))
FISHEYE_SIZES = ((1280, 1024), (1600, 1200))


def random_lens(kind: str, seed: int):
    """A lens drawn at random, none of them tuned for: (projection, image size, board
    distance [mm], spread) for ``views_of``.

    - ``rational``: OpenCV's 8-coefficient model, a half field of view of 25-55°, barrel
      or pincushion, a principal point up to 2 % off centre;
    - ``bumpy``: the same with smooth bumps of 0.3-1.5 px that no parametric model has;
    - ``tilted``: the same with a sensor tilted by up to 3° (OpenCV's 14 coefficients);
    - ``fisheye``: OpenCV's Kannala-Brandt fisheye model at 1280 x 1024 or 1600 x 1200.

    A real lens maps every ray to one pixel: past the angle where a drawn model first turns a
    ray back inwards, no ray is seen (``_seen_within``; the views would otherwise hold corners
    from beyond the field of view that the model maps back inside the image). And a lens that
    is not a fisheye images the whole frame: a draw whose rays stop short of the frame's
    border in some direction is drawn again."""
    rng = np.random.default_rng([RANDOM_KINDS.index(kind), seed])
    if kind == "fisheye":
        w, h = FISHEYE_SIZES[seed % len(FISHEYE_SIZES)]
        f = rng.uniform(0.22, 0.35) * w
        k = camera_matrix(f, f, w / 2 + rng.normal(0, 8), h / 2 + rng.normal(0, 8))
        d = np.array([rng.uniform(-0.05, 0.08), rng.uniform(-0.03, 0.02), rng.uniform(-0.005, 0.005),
                      rng.uniform(-0.001, 0.001)])

        def fisheye(pc):
            return cv2.fisheye.projectPoints(pc.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, d)[0].reshape(-1, 2)
        return _seen_within(fisheye)[0], (w, h), 0.9 * f * 330 / (w / 2), 0.7
    w, h = RANDOM_SIZES[seed % len(RANDOM_SIZES)]
    while True:
        f = (w / 2) / np.tan(np.radians(rng.uniform(25, 55))) * rng.uniform(0.95, 1.05)
        k = camera_matrix(f, f * rng.uniform(0.98, 1.02), w / 2 + rng.normal(0, 0.02 * w), h / 2 + rng.normal(0, 0.02 * h))
        k1 = rng.uniform(-0.4, 0.2)
        d = np.zeros(14 if kind == "tilted" else 8)
        d[:6] = [k1, rng.uniform(-0.2, 0.3) * abs(k1), rng.normal(0, 0.002), rng.normal(0, 0.002),
                 rng.uniform(-0.05, 0.05), rng.uniform(-0.1, 0.3) if rng.random() < 0.5 else 0.0]
        if kind == "tilted":
            d[12:] = np.radians(rng.uniform(-3, 3, 2))
        amplitude, centres = rng.uniform(0.3, 1.5), rng.uniform([0, 0], [w, h], (4, 2))
        widths, pushes = rng.uniform(0.15, 0.4, 4) * w, rng.normal(0, 1, (4, 2))

        def project(pc, k=k, d=d, amplitude=amplitude, centres=centres, widths=widths, pushes=pushes):
            uv = cv2.projectPoints(pc, np.zeros(3), np.zeros(3), k, d)[0].reshape(-1, 2)
            if kind == "bumpy":
                near = np.exp(-np.sum((uv[:, None, :] - centres) ** 2, axis=2) / (2 * widths**2))
                uv = uv + amplitude * near @ pushes / 2
            return uv
        seen, rim = _seen_within(project)
        if not np.any(np.all((rim >= 0) & (rim <= [w - 1, h - 1]), axis=1)):  # the frame is imaged to its border
            return seen, (w, h), 0.9 * f * 330 / (w / 2), 0.5


def _seen_within(project):
    """``project`` seeing no ray past 95 % of the angle off axis where, in some azimuth, it
    first stops moving the image outwards (NaN pixels there); and the pixels (36, 2) of the
    last rays seen, in 36 azimuths."""
    theta = np.radians(np.linspace(0.05, 89.9, 1800))
    azimuth = np.linspace(0, 2 * np.pi, 36, endpoint=False)[:, None]
    rays = np.stack([np.sin(theta) * np.cos(azimuth), np.sin(theta) * np.sin(azimuth),
                     np.broadcast_to(np.cos(theta), (36, len(theta)))], axis=-1).reshape(-1, 3)
    with np.errstate(all="ignore"):
        pixels = project(rays).reshape(36, len(theta), 2)
        radius = np.linalg.norm(pixels - project(np.array([[0.0, 0.0, 1.0]])), axis=2)
        outwards = np.diff(radius, axis=1) > 0  # False where it turns back, or is not finite
    first_turn = np.where(outwards.all(axis=1), len(theta) - 1, np.argmin(outwards, axis=1))
    last = int(np.searchsorted(theta, 0.95 * theta[first_turn.min()], side="right")) - 1
    reach = float(theta[last])

    def seen(pc):
        uv = project(pc)
        uv[off_axis(pc) > reach] = np.nan
        return uv
    return seen, pixels[:, last]


def camera_matrix(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """OpenCV's camera matrix (3, 3), skew 0."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
