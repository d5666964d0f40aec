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
