"""Rectified (undistorted) images: a pinhole camera of our choice, and the
maps that take each of its pixels to the source pixel in the photo.

For every pixel ``q`` of the rectified image: ``q → xn = K_rect⁻¹ q → ray
(xn, 1) → Calibration.project(ray) = p`` (a source pixel). This is a direct
evaluation of the forward model, so it is exact for the B-spline model (no
inversion) and the same code serves every model type. Photo pixel → ideal
pixel goes the other way with ``Calibration.undistort_points`` (Newton).

Choice of the rectified camera (square pixels, no skew), like OpenCV's
``getOptimalNewCameraMatrix`` ``alpha`` / fisheye ``balance``:

- ``alpha = 0`` ("valid"): every rectified pixel comes from inside the photo;
  the largest centred axis-aligned box inside the undistorted photo border;
- ``alpha = 1`` ("all"): every photo pixel lands in the rectified image;
- in between: focal length interpolated geometrically, centre linearly;
- ``fixed_camera(focal, size)``: a given focal length and size.

Pixels whose ray is further off axis than any ray of the photo (plus 2 %) are
marked invalid (map value −1): polynomial models fold back beyond their data,
and that would paint ghosts into the corners.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration import Calibration
from ..errors import CalibError, SettingsError

MAX_ANGLE_DEG = 80.0  # rays further off axis are clipped when choosing the camera (a pinhole cannot show 90°)
BORDER_SAMPLES = 96  # photo-border samples per side when choosing the camera
CHUNK = 1 << 18  # pixels projected at a time: bounds memory at ~50 MB for any model
INVALID = -1.0  # map value for rectified pixels with no source (cv2.remap then uses its border value)


class RectifyError(CalibError):
    """The rectified camera or the maps cannot be built as asked."""


@dataclass(frozen=True)
class RectifiedCamera:
    """An ideal pinhole camera: ``u = f x + cx``, ``v = f y + cy`` on pinhole-normalised ``(x, y)``."""

    focal: float
    cx: float
    cy: float
    width: int
    height: int

    @property
    def matrix(self) -> np.ndarray:
        """K (3, 3)."""
        return np.array([[self.focal, 0.0, self.cx], [0.0, self.focal, self.cy], [0.0, 0.0, 1.0]])

    @property
    def size(self) -> tuple[int, int]:
        return self.width, self.height

    def pixels(self, xn: np.ndarray) -> np.ndarray:
        """Rectified pixels (N, 2) of pinhole-normalised coordinates (N, 2)."""
        return xn * self.focal + np.array([self.cx, self.cy])

    def normalised(self, uv: np.ndarray) -> np.ndarray:
        """Pinhole-normalised coordinates (N, 2) of rectified pixels (N, 2)."""
        return (np.asarray(uv, dtype=np.float64) - np.array([self.cx, self.cy])) / self.focal

    def to_json(self) -> dict[str, Any]:
        return {"focal": self.focal, "cx": self.cx, "cy": self.cy, "width": self.width, "height": self.height,
                "camera_matrix": self.matrix.tolist()}


def fixed_camera(focal: float, size: tuple[int, int], centre: tuple[float, float] | None = None) -> RectifiedCamera:
    """A rectified camera of a given focal length (px) and size (width, height); centred by default."""
    w, h = _size(size)
    if not (np.isfinite(focal) and focal > 0):
        raise SettingsError(f"focal: expected a positive number of pixels, got {focal!r}")
    cx, cy = centre if centre is not None else ((w - 1) / 2, (h - 1) / 2)
    return RectifiedCamera(float(focal), float(cx), float(cy), w, h)


def border_normalised(cal: Calibration, samples: int = BORDER_SAMPLES,
                      max_angle_deg: float = MAX_ANGLE_DEG) -> dict[str, np.ndarray]:
    """Pinhole-normalised coordinates of the photo's border, per side:
    ``{"left", "right", "top", "bottom"}`` each (samples, 2), NaN where the
    model cannot unproject; rays beyond ``max_angle_deg`` are pulled in to it."""
    w, h = cal.image_size
    t = np.linspace(0.0, 1.0, samples)
    sides = {
        "left": np.column_stack([np.zeros(samples), t * (h - 1)]),
        "right": np.column_stack([np.full(samples, w - 1.0), t * (h - 1)]),
        "top": np.column_stack([t * (w - 1), np.zeros(samples)]),
        "bottom": np.column_stack([t * (w - 1), np.full(samples, h - 1.0)]),
    }
    pts = np.concatenate(list(sides.values()))
    rays = cal.rays(pts)
    theta = np.arccos(np.clip(rays[:, 2], -1.0, 1.0))
    phi = np.arctan2(rays[:, 1], rays[:, 0])
    r = np.tan(np.minimum(theta, np.radians(max_angle_deg)))
    xn = np.column_stack([r * np.cos(phi), r * np.sin(phi)])
    return dict(zip(sides, np.split(xn, 4), strict=True))


def rectified_camera(cal: Calibration, alpha: float = 0.0, size: tuple[int, int] | None = None) -> RectifiedCamera:
    """The rectified camera for ``alpha`` ∈ [0, 1] (0: valid pixels only, 1: all
    source pixels kept), of ``size`` (width, height; default: the photo's)."""
    if not (0.0 <= alpha <= 1.0):
        raise SettingsError(f"alpha: expected a number in [0, 1] (0: valid pixels only, 1: keep all), got {alpha!r}")
    w, h = _size(size or cal.image_size)
    b = border_normalised(cal)
    if any(np.isnan(s).all() for s in b.values()):
        raise RectifyError("the model cannot unproject a whole side of the image border; "
                           "give the rectified camera explicitly (focal and size)")
    # Inner box: the most inward point of each side (OpenCV's icvGetRectangles does the same).
    left, right = np.nanmax(b["left"][:, 0]), np.nanmin(b["right"][:, 0])
    top, bottom = np.nanmax(b["top"][:, 1]), np.nanmin(b["bottom"][:, 1])
    allp = np.concatenate(list(b.values()))
    o_left, o_top = np.nanmin(allp, axis=0)
    o_right, o_bottom = np.nanmax(allp, axis=0)
    if not (right > left and bottom > top):
        raise RectifyError("the undistorted image border does not enclose a rectangle (the model folds over); "
                           "use alpha=1 or a fixed focal length")
    # valid: the whole rectified image inside the inner box; all: the outer box inside the image.
    f_valid = max((w - 1) / (right - left), (h - 1) / (bottom - top))
    f_all = min((w - 1) / (o_right - o_left), (h - 1) / (o_bottom - o_top))
    focal = float(f_valid ** (1 - alpha) * f_all ** alpha)
    mid = (1 - alpha) * np.array([left + right, top + bottom]) / 2 + alpha * np.array([o_left + o_right, o_top + o_bottom]) / 2
    return RectifiedCamera(focal, float((w - 1) / 2 - focal * mid[0]), float((h - 1) / 2 - focal * mid[1]), w, h)


def max_ray_angle(cal: Calibration) -> float:
    """The largest angle (radians) off axis of any ray the photo's border sees."""
    b = np.concatenate(list(border_normalised(cal, max_angle_deg=89.9).values()))
    return float(np.nanmax(np.arctan(np.hypot(b[:, 0], b[:, 1]))))


def undistort_maps(cal: Calibration, camera: RectifiedCamera) -> tuple[np.ndarray, np.ndarray]:
    """``(map_x, map_y)``, each (height, width) float32: the photo pixel seen by
    each rectified pixel, for ``cv2.remap(photo, map_x, map_y, INTER_LINEAR)``;
    ``INVALID`` (−1) where there is none."""
    w, h = camera.width, camera.height
    limit = np.tan(min(max_ray_angle(cal) * 1.02, np.radians(89.0)))
    out = np.empty((h * w, 2), dtype=np.float32)
    # Row blocks keep memory bounded; within a block everything is vectorised.
    rows_per_chunk = max(1, CHUNK // w)
    u = np.arange(w, dtype=np.float64)
    for r0 in range(0, h, rows_per_chunk):
        v = np.arange(r0, min(h, r0 + rows_per_chunk), dtype=np.float64)
        uu, vv = np.meshgrid(u, v)
        xn = camera.normalised(np.column_stack([uu.ravel(), vv.ravel()]))
        with np.errstate(all="ignore"):
            p = cal.project(np.column_stack([xn, np.ones(len(xn))]))
        bad = ~np.all(np.isfinite(p), axis=1) | (np.hypot(xn[:, 0], xn[:, 1]) > limit)
        p[bad] = INVALID
        out[r0 * w: r0 * w + len(xn)] = p
    return out[:, 0].reshape(h, w), out[:, 1].reshape(h, w)


def rectify_image(cal: Calibration, image: np.ndarray, camera: RectifiedCamera,
                  maps: tuple[np.ndarray, np.ndarray] | None = None, border_value: float = 0) -> np.ndarray:
    """The rectified image (camera.height, camera.width[, channels]) of a photo
    (H, W[, channels]) of ``cal``'s size, bilinear; pass ``maps`` to reuse them."""
    import cv2

    image = np.asarray(image)
    if image.ndim not in (2, 3) or image.shape[:2] != (cal.image_size[1], cal.image_size[0]):
        raise RectifyError(f"image: expected {cal.image_size[0]} × {cal.image_size[1]} pixels (the calibration's "
                           f"image_size), got an array of shape {image.shape}")
    map_x, map_y = maps if maps is not None else undistort_maps(cal, camera)
    return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=border_value)


def save_maps(directory: str | Path, map_x: np.ndarray, map_y: np.ndarray, camera: RectifiedCamera) -> list[Path]:
    """Write the maps two ways into ``directory``:

    - ``maps.npz``: ``map_x``, ``map_y`` (H, W) float32 and ``camera_matrix`` (3, 3);
    - ``map_x.tiff``, ``map_y.tiff``: single-channel float32 TIFFs that
      ``cv2.imread(path, cv2.IMREAD_UNCHANGED)`` loads bit-exactly, ready for
      ``cv2.remap`` (OpenCV writes no 2-channel float images, hence two files).
    """
    import cv2

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    npz = d / "maps.npz"
    np.savez_compressed(npz, map_x=map_x, map_y=map_y, camera_matrix=camera.matrix,
                        size=np.array(camera.size), invalid=np.float32(INVALID))
    paths = [npz]
    for name, m in (("map_x.tiff", map_x), ("map_y.tiff", map_y)):
        if not cv2.imwrite(str(d / name), np.ascontiguousarray(m, dtype=np.float32)):
            raise RectifyError(f"could not write {d / name}")
        paths.append(d / name)
    return paths


def _size(size) -> tuple[int, int]:
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError):
        raise SettingsError(f"size: expected (width, height), got {size!r}") from None
    if w < 2 or h < 2 or w * h > 200_000_000:
        raise SettingsError(f"size: expected a width and height of at least 2 pixels (and a sane total), got {w} × {h}")
    return w, h
