"""The lens's distortion over the image, in the views that read on its lens.

Measured against a pinhole, a wide lens's distortion runs to hundreds of
pixels (GoPro ±585 px) or is undefined past 90° off axis (BabelCalib's
fisheye: ±8 211 px), and a colour scale spanning that shows nothing inside.
So each map here is one way of looking, and ``default`` names the one that
reads on this lens:

- ``pinhole``: observed pixel − its ideal pinhole pixel, Δx and Δy [px]
  (for the paper's field this is the field itself: its core is the pinhole);
- ``field``: a field over a parametric core (hybrid, MLS, TPS): the field's
  own part, observed pixel − the core's pixel [px];
- ``angle``: the lens as angles: each pixel's angle off axis θ [°] and its
  departure from the equidistant lens with the same focal length and centre,
  θ − r/f [°] (zero for an ideal fisheye, −atan-shaped for a pinhole; finite
  past 90°).

Every map carries its colour ``scale``: the 98th percentile of its magnitude
(an image corner without corners can extrapolate to hundreds of pixels and
would flatten the rest; values past it saturate). The page's 2-D map and the
3-D view's surfaces read the same ``scale`` for the same map.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ..calibration import json_safe
from ..models import HybridModel, camera
from ..models.residual_field import ResidualFieldModel

if TYPE_CHECKING:
    from ..calibration import Calibration

WIDE_DEGREES = 60.0   # a pixel this far off axis: the pinhole view reads badly, the angle view is the default
SCALE_PERCENTILE = 98


def _scale(*arrays: np.ndarray) -> float:
    """The colour scale's half-range: the 98th percentile of |value| (1 when there is nothing)."""
    values = np.abs(np.concatenate([a[np.isfinite(a)] for a in arrays]))
    top = float(np.percentile(values, SCALE_PERCENTILE)) if values.size else 0.0
    return top if top > 0 else 1.0


def _core_of(model):
    if isinstance(model, HybridModel) and not model.field_held:
        return model.core, f"the field's own part: observed pixel − the {model.core.kind} core's pixel"
    if isinstance(model, ResidualFieldModel):
        return model.parametric, f"the {model.kind} field's own part: observed pixel − its OpenCV model's pixel"
    return None, ""


def distortion_maps(cal: Calibration, samples: tuple[int, int]) -> dict[str, Any]:
    """The maps above on a grid of ``samples`` (nu, nv) observed pixels, corners of the image included."""
    w, h = cal.image_size
    nu, nv = samples
    u, v = np.meshgrid(np.linspace(0, w - 1, nu), np.linspace(0, h - 1, nv))
    uv = np.column_stack([u.ravel(), v.ravel()])
    with np.errstate(all="ignore"):
        rays = cal.rays(uv)
        z = np.where(rays[:, 2:] > 0, rays[:, 2:], np.nan)
        pinhole = uv - cal.model.ideal_pixel(rays[:, :2] / z)
        theta = np.degrees(np.arccos(np.clip(rays[:, 2], -1.0, 1.0)))
        theta_eq = np.degrees(np.linalg.norm(cal.model.normalised_of_ideal(uv), axis=1))
    maps: dict[str, dict[str, Any]] = {
        "pinhole": {"label": "against the pinhole", "unit": "px", "dx": pinhole[:, 0], "dy": pinhole[:, 1],
                    "scale": _scale(pinhole[:, 0], pinhole[:, 1]),
                    "note": "observed pixel − its ideal pinhole pixel; none where the ray is 90° or more off axis"},
    }
    core, note = _core_of(cal.model)
    if core is not None:
        with np.errstate(all="ignore"):  # the core's pixel of each ray (principal branch, as above)
            own = uv - core.pixel_of(camera.normalise(rays, cal.model.base))
        maps["field"] = {"label": "the field's own part", "unit": "px", "dx": own[:, 0], "dy": own[:, 1],
                         "scale": _scale(own[:, 0], own[:, 1]), "note": note}
    dtheta = theta - theta_eq
    # past the corners' farthest angle the model extrapolates (a circular fisheye's black frame): shown,
    # but kept out of the scale, which would otherwise be that extrapolation's
    reach = (cal.diagnostics.camera or {}).get("max_corner_angle_deg")
    within = theta <= reach if isinstance(reach, (int, float)) else np.isfinite(theta)
    maps["angle"] = {"label": "angle off axis, against the equidistant lens", "unit": "°", "theta": theta,
                     "dtheta": dtheta, "scale": _scale(dtheta[within]), "reach_deg": reach,
                     "note": "θ: each pixel's angle off axis; θ − r/f: its departure from the equidistant lens "
                             "(r: distance from the principal point, f the focal length); past reach_deg (the "
                             "corners' farthest angle) the model extrapolates"}
    widest = float(np.nanmax(theta)) if np.isfinite(theta).any() else 0.0
    wide = widest > WIDE_DEGREES or not np.all(np.isfinite(pinhole))
    default = "field" if core is not None else "angle" if wide else "pinhole"
    return json_safe({"grid": [nu, nv], "image_size": [w, h], "u": uv[:, 0], "v": uv[:, 1], "maps": maps,
                      "default": default, "wide": wide, "max_angle_deg": widest})
