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
- ``fixed_camera(focal, size)``: a given focal length and size;
- ``covered_camera(cal)``: the largest rectangle inside the region the
  calibration's corners covered (where the lens is measured, not extrapolated).

When the model folds over inside the photo (a 5-coefficient polynomial on a
GoPro folds back 62° off axis, before the photo's corners), the undistorted
photo border is no boundary at all. The camera is then chosen on the region
of valid rays instead (on the lens's principal branch, their pixel inside the
photo): ``alpha = 0`` is the largest rectangle of the image's shape inside it,
``alpha = 1`` its bounding box, and the camera's ``note`` says so.

Pixels whose ray is further off axis than any ray of the photo (plus 2 %) are
marked invalid (map value −1), and so are those past the fold of the model
along their azimuth: polynomial models fold back beyond their data, and that
would paint ghosts into the corners.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration import Calibration
from ..errors import CalibError, SettingsError
from ..models.unproject import principal_branch

MAX_ANGLE_DEG = 80.0  # rays further off axis are clipped when choosing the camera (a pinhole cannot show 90°)
BORDER_SAMPLES = 96  # photo-border samples per side when choosing the camera
CHUNK = 1 << 18  # pixels projected at a time: bounds memory at ~50 MB for any model
INVALID = -1.0  # map value for rectified pixels with no source (cv2.remap then uses its border value)
POLAR = (400, 360)  # (angles off axis, azimuths) sampling the valid region: 0.22° × 1°
REGION_CELLS = 480  # grid points across the valid region when looking for its largest rectangle


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
    note: str = ""  # how the camera was chosen when it is not the usual way (a fallback)

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
        out = {"focal": self.focal, "cx": self.cx, "cy": self.cy, "width": self.width, "height": self.height,
               "camera_matrix": self.matrix.tolist()}
        if self.note:
            out["note"] = self.note
        return out


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


Box = tuple[float, float, float, float]  # left, top, right, bottom in pinhole-normalised coordinates


def rectified_camera(cal: Calibration, alpha: float = 0.0, size: tuple[int, int] | None = None) -> RectifiedCamera:
    """The rectified camera for ``alpha`` ∈ [0, 1] (0: valid pixels only, 1: all
    source pixels kept), of ``size`` (width, height; default: the photo's).
    Where the photo border folds over, on the region of valid rays (module text)."""
    if not (0.0 <= alpha <= 1.0):
        raise SettingsError(f"alpha: expected a number in [0, 1] (0: valid pixels only, 1: keep all), got {alpha!r}")
    w, h = _size(size) if size else photo_size(cal)
    boxes = _border_boxes(cal)
    note = ""
    if isinstance(boxes, str):  # the border is no boundary: work on the region of valid rays
        w_photo, h_photo = cal.image_size
        inner = largest_rectangle(cal, lambda uv: _inside_photo(uv, w_photo, h_photo), (w - 1) / (h - 1))
        outer = _valid_bounds(cal, lambda uv: _inside_photo(uv, w_photo, h_photo))
        kept = "the largest rectangle of valid pixels" if alpha == 0 else (
            "the bounding box of the valid rays" if alpha == 1 else f"alpha {alpha:g} between the largest rectangle "
            "of valid pixels and their bounding box")
        note = f"{boxes}; the rectified camera shows {kept} instead (past the fold the maps are invalid)"
        boxes = inner, outer
    return _camera_of_boxes(*boxes, alpha, w, h, note)


def covered_camera(cal: Calibration, size: tuple[int, int] | None = None,
                   hull: np.ndarray | None = None) -> RectifiedCamera:
    """The rectified camera whose image is the largest rectangle inside the
    region the corners covered: the convex hull ``hull`` (M, 2) of observed
    pixels, by default the one the calibration recorded (``coverage_hull``)."""
    from scipy.spatial import Delaunay

    w, h = _size(size) if size else photo_size(cal)
    pts = np.asarray(cal.diagnostics.coverage_hull or [] if hull is None else hull, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 3:
        raise RectifyError("the calibration records no covered region (coverage_hull); give the observations")
    tri = Delaunay(pts)
    box = largest_rectangle(cal, lambda uv: tri.find_simplex(np.nan_to_num(uv, nan=-1e9)) >= 0, (w - 1) / (h - 1))
    return _camera_of_boxes(box, box, 0.0, w, h, "the largest rectangle inside the region the corners covered")


def _border_boxes(cal: Calibration) -> tuple[Box, Box] | str:
    """(inner, outer) boxes of the undistorted photo border, or why there are none."""
    b = border_normalised(cal)
    if any(np.isnan(s).all() for s in b.values()):
        return "the model cannot unproject a whole side of the photo's border (it folds over before the border)"
    if any(np.isnan(s).any() for s in b.values()):  # a box from the rest would hold pixels with no ray
        return "the model cannot unproject part of the photo's border (it folds over before the border's corners)"
    # Inner box: the most inward point of each side (OpenCV's icvGetRectangles does the same).
    left, right = np.nanmax(b["left"][:, 0]), np.nanmin(b["right"][:, 0])
    top, bottom = np.nanmax(b["top"][:, 1]), np.nanmin(b["bottom"][:, 1])
    allp = np.concatenate(list(b.values()))
    o_left, o_top = np.nanmin(allp, axis=0)
    o_right, o_bottom = np.nanmax(allp, axis=0)
    if not (right > left and bottom > top):
        return "the undistorted photo border does not enclose a rectangle (the model folds over)"
    return (left, top, right, bottom), (o_left, o_top, o_right, o_bottom)


def _camera_of_boxes(inner: Box, outer: Box, alpha: float, w: int, h: int, note: str = "") -> RectifiedCamera:
    """valid: the whole rectified image inside the inner box; all: the outer box inside the image;
    in between the focal length geometrically, the centre linearly."""
    left, top, right, bottom = inner
    o_left, o_top, o_right, o_bottom = outer
    f_valid = max((w - 1) / (right - left), (h - 1) / (bottom - top))
    f_all = min((w - 1) / (o_right - o_left), (h - 1) / (o_bottom - o_top))
    focal = float(f_valid ** (1 - alpha) * f_all ** alpha)
    mid = (1 - alpha) * np.array([left + right, top + bottom]) / 2 + alpha * np.array([o_left + o_right, o_top + o_bottom]) / 2
    return RectifiedCamera(focal, float((w - 1) / 2 - focal * mid[0]), float((h - 1) / 2 - focal * mid[1]), w, h, note)


def _inside_photo(uv: np.ndarray, w: int, h: int) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return (uv[:, 0] >= 0) & (uv[:, 0] <= w - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= h - 1)


def branch_radius(cal: Calibration, max_angle_deg: float = 89.0, samples: tuple[int, int] = POLAR):
    """Azimuths φ (n_phi,) and, for each, how far off axis (pinhole-normalised radius
    tan θ, capped at ``max_angle_deg``) the lens's principal branch reaches (n_phi,)."""
    theta, phi, _, _, branch = principal_branch(cal.model, *samples)
    last = np.maximum(branch.sum(axis=1) - 1, 0)
    return phi, np.tan(np.minimum(theta[last], np.radians(max_angle_deg)))


def _within_branch(xn: np.ndarray, phi: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Whether normalised points (N, 2) lie within the branch radius of their azimuth:
    the smaller of the two sampled azimuths around each point's (a conservative bound)."""
    step = phi[1] - phi[0]
    i = np.floor((np.arctan2(xn[:, 1], xn[:, 0]) - phi[0]) / step).astype(np.int64) % len(phi)
    bound = np.minimum(radius[i], radius[(i + 1) % len(phi)])
    return np.hypot(xn[:, 0], xn[:, 1]) <= bound


def _valid_polar(cal: Calibration, inside, samples: tuple[int, int] = POLAR) -> np.ndarray:
    """Pinhole-normalised points (M, 2) of the rays that reach ``inside(pixels)``
    along their azimuth without leaving it or the principal branch (within ``MAX_ANGLE_DEG``)."""
    theta, phi, _, uv, branch = principal_branch(cal.model, *samples)
    tt, pp = np.meshgrid(theta, phi)
    ok = branch & (tt <= np.radians(MAX_ANGLE_DEG))
    ok &= inside(uv.reshape(-1, 2)).reshape(ok.shape)
    ok[:, 0] = True  # the axis itself
    ok = np.cumprod(ok, axis=1).astype(bool)
    r = np.tan(tt[ok])
    return np.column_stack([r * np.cos(pp[ok]), r * np.sin(pp[ok])])


def _valid_bounds(cal: Calibration, inside) -> Box:
    pts = _valid_polar(cal, inside)
    (left, top), (right, bottom) = pts.min(axis=0), pts.max(axis=0)
    if not (right > left and bottom > top):
        raise RectifyError("no region of valid rays around the axis: the model folds over at once; "
                           "give the rectified camera explicitly (focal and size)")
    return float(left), float(top), float(right), float(bottom)


def largest_rectangle(cal: Calibration, inside, aspect: float, cells: int = REGION_CELLS) -> Box:
    """The largest box of width/height ``aspect`` (pinhole-normalised) all of whose rays
    lie on the principal branch with their pixel ``inside(pixels (N, 2)) -> (N,) bool``;
    of those, the one centred nearest the optical axis. Searched on a grid of ``cells``
    points across the region's bounding box (binary search on the height, each size
    tested at every position at once by an integral image)."""
    left, top, right, bottom = _valid_bounds(cal, inside)
    d = max(right - left, bottom - top) / (cells - 1)
    xs, ys = np.arange(left, right + d, d), np.arange(top, bottom + d, d)
    xx, yy = np.meshgrid(xs, ys)
    xn = np.column_stack([xx.ravel(), yy.ravel()])
    phi, radius = branch_radius(cal, MAX_ANGLE_DEG)
    ok = _within_branch(xn, phi, radius)
    with np.errstate(all="ignore"):
        uv = cal.project(np.column_stack([xn[ok], np.ones(int(ok.sum()))]))
    ok[ok] = inside(uv) & np.all(np.isfinite(uv), axis=1)
    bad = np.pad((~ok).reshape(len(ys), len(xs)).astype(np.int64), ((1, 0), (1, 0))).cumsum(0).cumsum(1)

    def fits(k: int):
        """Top-left grid indices (iy, ix) of every all-valid window k rows × m columns of points."""
        m = max(2, int(round(aspect * (k - 1))) + 1)
        if k > len(ys) or m > len(xs):
            return m, np.empty((0,), dtype=np.int64), np.empty((0,), dtype=np.int64)
        s = bad[k:, m:] - bad[:-k, m:] - bad[k:, :-m] + bad[:-k, :-m]
        iy, ix = np.nonzero(s == 0)
        return m, iy, ix

    lo, hi = 1, len(ys)  # lo: a height known to fit (a single point: the axis), hi: upper bound
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if len(fits(mid)[1]):
            lo = mid
        else:
            hi = mid - 1
    m, iy, ix = fits(lo)
    if lo < 3 or not len(iy):
        raise RectifyError("the region of valid pixels holds no rectangle of the image's shape; "
                           "give the rectified camera explicitly (focal and size)")
    k = lo
    centre = np.column_stack([xs[ix] + (m - 1) * d / 2, ys[iy] + (k - 1) * d / 2])
    best = int(np.argmin(np.hypot(centre[:, 0], centre[:, 1])))
    x0, y0 = xs[ix[best]], ys[iy[best]]
    # half a cell in from the outermost valid points: the boundary lies between them and the next
    return (float(x0 + d / 2), float(y0 + d / 2), float(x0 + (m - 1) * d - d / 2), float(y0 + (k - 1) * d - d / 2))


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
    phi, radius = branch_radius(cal)  # the rectangle's own sampling: its pixels all stay valid
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
        bad = ~np.all(np.isfinite(p), axis=1) | (np.hypot(xn[:, 0], xn[:, 1]) > limit) | ~_within_branch(xn, phi, radius)
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


def photo_size(cal: Calibration) -> tuple[int, int]:
    """The calibration's photo size as a rectified size: a bad one is the calibration's fault, and said so."""
    return _size(cal.image_size, "the calibration's image_size")


def _size(size, where: str = "size") -> tuple[int, int]:
    try:
        w, h = (int(s) for s in size)
    except (TypeError, ValueError):
        raise SettingsError(f"{where}: expected (width, height), got {size!r}") from None
    if w < 2 or h < 2 or w * h > 200_000_000:
        raise SettingsError(f"{where}: expected a width and height of at least 2 pixels (and a sane total), "
                            f"got {w} × {h}")
    return w, h
