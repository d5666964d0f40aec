"""The projection difference between two calibrations of one camera: do they agree
on where a direction lands in the image? (``mrcal-show-projection-diff``'s question.)

Over a grid of pixels q (``grid`` samples across, mrcal's ``sample_imager``): the
direction A sees at q, ``v = A⁻¹(q)``, rotated by R and projected through B:
``diff(q) = B(R v) − q``, in pixels. R is the rotation the intrinsics imply: two
calibrations of one camera may put its frame at slightly different angles (a common
rotation of every board pose is nearly absorbed by the principal point and the
distortion), and that is no difference of the lens. It is the rotation that best maps
A's rays onto B's rays of the same pixels (least squares on the unit vectors:
orthogonal Procrustes, closed form), fitted over

- ``"covered"``: the pixels inside both calibrations' coverage hulls
  (``diagnostics.coverage_hull``: where each had corners), the default;
- ``"centre"``: a disc of radius min(W, H)/6 at the image centre (mrcal's default
  when it has no uncertainties);
- ``"none"``: no rotation (the camera frames are taken as the same).

mrcal fits a robust (Huber) cost of the squared angles; for the small rotations
two calibrations of one camera differ by, the two agree (tests compare them).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..calibration import Calibration, json_safe
from ..errors import DataError, SettingsError

FIT_REGIONS = ("covered", "centre", "none")
DEFAULT_GRID = 60        # samples across the image, as mrcal-show-projection-diff
CENTRE_RADIUS = 1 / 6    # of min(W, H): mrcal's focus radius without uncertainties
MIN_FIT_POINTS = 3


@dataclass
class ProjectionDiff:
    """The difference B(R A⁻¹(q)) − q over a grid of pixels q."""

    u: np.ndarray          # (nu,) grid columns, px
    v: np.ndarray          # (nv,) grid rows, px
    diff: np.ndarray       # (nv, nu, 2) px; NaN where A cannot unproject or B cannot project
    covered: np.ndarray | None  # (nv, nu) inside both coverage hulls; None if a calibration has no hull
    fitted: np.ndarray     # (nv, nu) the pixels the rotation was fitted on
    rotation: np.ndarray   # (3, 3) R, A's camera frame → B's
    fit_region: str        # what was asked for
    fitted_on: str         # what it was fitted on ("covered", "centre", "none"), and why if it differs
    image_size: tuple[int, int]

    @property
    def magnitude(self) -> np.ndarray:
        """(nv, nu) |diff|, px (NaN where undefined)."""
        return np.hypot(self.diff[..., 0], self.diff[..., 1])

    @property
    def rotation_deg(self) -> float:
        """The angle of the fitted rotation, degrees."""
        return float(np.degrees(np.arccos(np.clip((np.trace(self.rotation) - 1) / 2, -1.0, 1.0))))

    def summary(self) -> dict[str, Any]:
        """Median, 95th percentile and maximum of |diff| over the image and the covered region."""
        mag = self.magnitude
        return {"image": _stats(mag[np.isfinite(mag)]),
                "covered": None if self.covered is None else _stats(mag[self.covered & np.isfinite(mag)]),
                "rotation_deg": self.rotation_deg, "rotation_vector": _rotvec(self.rotation).tolist(),
                "fit_region": self.fit_region, "fitted_on": self.fitted_on,
                "grid": [len(self.u), len(self.v)], "image_size": list(self.image_size), "units": "px"}

    def to_json(self) -> dict[str, Any]:
        """The map and its summary, JSON-ready (null where undefined)."""
        mag = self.magnitude
        return {**self.summary(), "u": self.u.tolist(), "v": self.v.tolist(),
                "dx": _nulls(self.diff[..., 0]), "dy": _nulls(self.diff[..., 1]), "magnitude": _nulls(mag),
                "covered_mask": None if self.covered is None else self.covered.tolist(),
                "fitted_mask": self.fitted.tolist(),
                "note": "B(R A^-1(q)) - q in pixels over a grid of pixels q, R the rotation between the two "
                        "calibrations' camera frames fitted out; 'covered': the summary inside both coverage "
                        "hulls, 'covered_mask': the grid cells there"}


def projection_diff(a: Calibration, b: Calibration, grid: int = DEFAULT_GRID,
                    fit_region: str = "covered") -> ProjectionDiff:
    """The projection difference from calibration ``a`` to ``b`` of one camera over
    ``grid`` × (proportional) pixels, the implied rotation fitted out over
    ``fit_region`` (``FIT_REGIONS``, see the module text)."""
    if fit_region not in FIT_REGIONS:
        raise SettingsError(f"fit region: expected one of {', '.join(FIT_REGIONS)}, got {fit_region!r}")
    if not 2 <= int(grid) <= 1000:
        raise SettingsError(f"grid: expected 2 to 1000 samples across the image, got {grid}")
    if tuple(a.image_size) != tuple(b.image_size):
        raise DataError(f"the calibrations have different image sizes ({a.image_size[0]} x {a.image_size[1]} and "
                        f"{b.image_size[0]} x {b.image_size[1]} px): they are not of one camera at one resolution")
    w, h = a.image_size
    u = np.linspace(0, w - 1, int(grid))
    v = np.linspace(0, h - 1, int(round(h / w * int(grid))))
    q = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
    ray_a, ray_b = _rays(a, q), _rays(b, q)
    both = np.all(np.isfinite(ray_a), axis=1) & np.all(np.isfinite(ray_b), axis=1)
    covered = _covered(a, b, q)
    fitted, fitted_on = _fit_set(fit_region, covered, q, (w, h), both)
    rotation = np.eye(3) if fitted_on == "none" else _procrustes(ray_a[fitted], ray_b[fitted])
    diff = np.full(q.shape, np.nan)
    ok = np.all(np.isfinite(ray_a), axis=1)
    moved = ray_a[ok] @ rotation.T
    projectable = _in_front(b, moved)
    with np.errstate(all="ignore"):
        diff[np.flatnonzero(ok)[projectable]] = b.project(moved[projectable]) - q[ok][projectable]
    diff[~np.all(np.isfinite(diff), axis=1)] = np.nan
    shape = (len(v), len(u))
    return ProjectionDiff(u, v, diff.reshape(*shape, 2), None if covered is None else covered.reshape(shape),
                          fitted.reshape(shape), rotation, fit_region, fitted_on, (w, h))


def _rays(cal: Calibration, q: np.ndarray) -> np.ndarray:
    with np.errstate(all="ignore"):
        rays = cal.rays(q)
    return rays / np.linalg.norm(rays, axis=1, keepdims=True)


def _in_front(cal: Calibration, rays: np.ndarray) -> np.ndarray:
    """Rays ``cal`` can project: in front of the camera for the pinhole base, any for the wide bases."""
    if cal.model.base == "pinhole":
        return rays[:, 2] > 1e-9
    return np.ones(len(rays), dtype=bool)


def _covered(a: Calibration, b: Calibration, q: np.ndarray) -> np.ndarray | None:
    """(G,) pixels inside both calibrations' coverage hulls, or None if one has none."""
    hulls = [np.asarray(c.diagnostics.coverage_hull or [], dtype=np.float64).reshape(-1, 2) for c in (a, b)]
    if any(len(hull) < 3 for hull in hulls):
        return None
    return inside_convex(hulls[0], q) & inside_convex(hulls[1], q)


def inside_convex(polygon: np.ndarray, points: np.ndarray) -> np.ndarray:
    """(N,) points (N, 2) inside (or on) a convex polygon (M, 2), either orientation."""
    edges = np.roll(polygon, -1, axis=0) - polygon                    # (M, 2)
    rel = points[:, None, :] - polygon[None, :, :]                     # (N, M, 2)
    cross = edges[None, :, 0] * rel[..., 1] - edges[None, :, 1] * rel[..., 0]
    tol = 1e-9 * max(1.0, float(np.abs(polygon).max()))
    return np.all(cross >= -tol, axis=1) | np.all(cross <= tol, axis=1)


def _fit_set(fit_region: str, covered: np.ndarray | None, q: np.ndarray, size, both: np.ndarray):
    """The pixels the rotation is fitted on, and the region's name (with the reason for a fallback)."""
    if fit_region == "none":
        return np.zeros(len(q), dtype=bool), "none"
    if fit_region == "covered":
        if covered is not None and np.count_nonzero(covered & both) >= MIN_FIT_POINTS:
            return covered & both, "covered"
        why = ("a calibration records no coverage hull" if covered is None
               else "the calibrations' coverage hulls hardly overlap")
        fit_region = f"centre ({why})"
    w, h = size
    centre = np.array([(w - 1) / 2, (h - 1) / 2])
    disc = np.sum((q - centre) ** 2, axis=1) < (CENTRE_RADIUS * min(w, h)) ** 2
    if np.count_nonzero(disc & both) < MIN_FIT_POINTS:
        raise DataError("too few pixels of the image centre can be unprojected by both calibrations to fit "
                        "the rotation between them (use a finer grid, or fit region none)")
    return disc & both, fit_region


def _procrustes(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The rotation R minimising Σ |R aᵢ − bᵢ|² over unit vectors (Kabsch)."""
    u, _, vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(u @ vt)) or 1.0
    return u @ np.diag([1.0, 1.0, d]) @ vt


def _rotvec(r: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_matrix(r).as_rotvec()


def _stats(values: np.ndarray) -> dict[str, Any]:
    if values.size == 0:
        return {"n": 0, "median": None, "p95": None, "max": None}
    return {"n": int(values.size), "median": float(np.median(values)), "p95": float(np.percentile(values, 95)),
            "max": float(values.max())}


def _nulls(a: np.ndarray) -> list:
    return json_safe(np.round(a, 6))
