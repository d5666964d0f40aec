"""Calibration: the result of one calibration, read and written as
``freecal.calibration/1`` (formats.md §2), and what a user does with it:
project board points, distort ideal pixels, undistort observed pixels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .errors import FormatError
from .fit_report import Diagnostics, FitMetrics
from .models import MODEL_TYPES, CameraModel, camera, unproject
from .observations import read_json, write_json

FORMAT = "freecal.calibration/1"


@dataclass
class ViewResult:
    name: str
    rvec: np.ndarray  # (3,)
    tvec: np.ndarray  # (3,)
    rmse: float = float("nan")
    rmse_axis: float = float("nan")
    n_points: int = 0
    outliers: list[int] = field(default_factory=list)

    @property
    def pose(self) -> np.ndarray:
        return np.concatenate([self.rvec, self.tvec])


@dataclass
class Calibration:
    """A calibrated camera: ``model`` (intrinsics and distortion) plus the board
    pose and errors of every view used."""

    model: CameraModel
    image_size: tuple[int, int]
    method: str
    views: list[ViewResult] = field(default_factory=list)
    dropped_views: list[dict[str, str]] = field(default_factory=list)
    metrics: FitMetrics | None = None  # None: a model with no fit of its own (a lean export, a lens's truth)
    # The method's settings as the fit used them: the method's settings dataclass, the
    # pipeline's (``method``, ``outlier_sigma``), what the fit chose (``intervals_used``,
    # ``chosen``, …) and the model's ``settings_json`` (what ``CameraModel.restored``
    # reads back), merged flat in one object. Kept a dict: its keys depend on the
    # method, and a type per method would change the format's flat object.
    settings: dict[str, Any] = field(default_factory=dict)
    diagnostics: Diagnostics = field(default_factory=Diagnostics)
    # where it came from (``provenance.py``): version, date, observations' hash, tvec units
    provenance: dict[str, Any] = field(default_factory=dict)

    # ---- using it -------------------------------------------------------------
    def project(self, points: np.ndarray, rvec=None, tvec=None) -> np.ndarray:
        """Pixels (N, 2) of points (N, 3): camera-frame points, or board points
        when the board pose ``rvec, tvec`` is given."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if rvec is not None:
            pts = camera.rotate(np.asarray(rvec, dtype=np.float64), pts) + np.asarray(tvec, dtype=np.float64)
        return self.model.project(pts)

    def distort(self, ideal_uv: np.ndarray) -> np.ndarray:
        """Ideal pinhole pixels ``K (X/Z, Y/Z)`` (N, 2) → observed pixels (N, 2)."""
        uv = np.asarray(ideal_uv, dtype=np.float64).reshape(-1, 2)
        xn = self.model.normalised_of_ideal(uv)
        return self.project(np.column_stack([xn, np.ones(len(xn))]))

    def undistort_points(self, uv: np.ndarray) -> np.ndarray:
        """Observed pixels (N, 2) → ideal pinhole pixels (N, 2), by Newton's method
        to 1e-9 px in the image (principal branch, see ``rays``); NaN where the
        ray is 90° or more off axis."""
        rays = self.rays(uv)
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = np.where(rays[:, 2:] > 0, rays[:, :2] / rays[:, 2:], np.nan)
        return self.model.ideal_pixel(xn)

    def rays(self, uv: np.ndarray) -> np.ndarray:
        """Unit rays (N, 3) in the camera frame of observed pixels (N, 2), on the
        lens's principal branch (``unproject.py``: wide models fold back, and a
        plain Newton start can land on the folded sheet); NaN where none."""
        xn = unproject.normalised_of_pixel(self.model, np.asarray(uv, dtype=np.float64).reshape(-1, 2))
        return camera.ray_of(xn, self.model.base)

    def view(self, name: str) -> ViewResult:
        for v in self.views:
            if v.name == name:
                return v
        raise KeyError(name)

    # ---- JSON ------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        doc = {
            "format": FORMAT,
            "image_size": list(self.image_size),
            "model": self.method,
            "base": self.model.base_json(),
            "intrinsics": self.model.intrinsics_json(),
            "distortion": self.model.distortion_json(),
            "views": [
                {
                    "name": v.name,
                    "rvec": [float(x) for x in v.rvec],
                    "tvec": [float(x) for x in v.tvec],
                    "rmse": _num(v.rmse),
                    "rmse_axis": _num(v.rmse_axis),
                    "n_points": int(v.n_points),
                    "outliers": [int(i) for i in v.outliers],
                }
                for v in self.views
            ],
            "dropped_views": list(self.dropped_views),
            "metrics": {} if self.metrics is None else self.metrics.to_json(),
            "settings": json_safe(self.settings),
            "diagnostics": json_safe(self.diagnostics.to_json()),
        }
        if self.provenance:
            doc["provenance"] = json_safe(self.provenance)
        return doc

    @classmethod
    def from_json(cls, doc: Any) -> Calibration:
        try:
            return cls._from_json(doc)
        except (TypeError, ValueError, OverflowError, KeyError, IndexError, AttributeError) as exc:
            # a shape no check below foresaw (e.g. in a model's own reader): still a format error
            raise FormatError(f"calibration: malformed document ({type(exc).__name__}: {exc}); "
                              f"expected {FORMAT} as in docs/formats.md") from None

    @classmethod
    def _from_json(cls, doc: Any) -> Calibration:
        if not isinstance(doc, dict):
            raise FormatError("calibration: expected a JSON object at the top level")
        if doc.get("format") != FORMAT:
            raise FormatError(f"format: expected {FORMAT!r}, got {doc.get('format')!r}")
        image_size = doc.get("image_size")
        if not (isinstance(image_size, list) and len(image_size) == 2 and all(isinstance(x, int) and not isinstance(x, bool) and 0 < x < 2**31 for x in image_size)):
            raise FormatError(f"image_size: expected [width, height] as positive integers, got {image_size!r}")
        base = doc.get("base", "pinhole")
        if base not in camera.BASES:
            raise FormatError(f"base: expected one of {list(camera.BASES)}, got {base!r}")
        intrinsics = _intrinsics(doc.get("intrinsics"))
        dist = doc.get("distortion")
        if not isinstance(dist, dict) or "type" not in dist:
            raise FormatError("distortion: expected an object with a 'type'")
        if not isinstance(dist["type"], str):
            raise FormatError(f"distortion.type: expected a string, one of {sorted(MODEL_TYPES)}")
        for key, kind in (("metrics", dict), ("settings", dict), ("diagnostics", dict), ("dropped_views", list),
                          ("views", list)):
            if not isinstance(doc.get(key, kind()), kind):
                raise FormatError(f"{key}: expected {'an object' if kind is dict else 'a list'}")
        reader = MODEL_TYPES.get(dist["type"])
        if reader is None:
            raise FormatError(f"distortion.type: unknown type {dist['type']!r}; known: {sorted(MODEL_TYPES)}")
        model = reader.from_json(intrinsics, dist, base).restored(doc.get("settings", {}))
        _field_within(model, (image_size[0], image_size[1]))
        views = []
        for k, v in enumerate(doc.get("views", [])):
            try:
                views.append(ViewResult(
                    str(v["name"]), np.asarray(v["rvec"], dtype=np.float64).reshape(3),
                    np.asarray(v["tvec"], dtype=np.float64).reshape(3),
                    _float(v.get("rmse")), _float(v.get("rmse_axis")), int(v.get("n_points", 0)),
                    [int(i) for i in v.get("outliers", [])],
                ))
            except (KeyError, TypeError, ValueError, OverflowError, AttributeError):
                raise FormatError(f"views[{k}]: expected name, rvec [3 numbers] and tvec [3 numbers]") from None
        provenance = doc.get("provenance")  # an extra field: kept when it is ours, ignored otherwise
        metrics = doc.get("metrics", {})
        return cls(model, (image_size[0], image_size[1]), str(doc.get("model", dist["type"])), views,
                   list(doc.get("dropped_views", [])), FitMetrics.from_json(metrics) if metrics else None,
                   dict(doc.get("settings", {})), Diagnostics.from_json(doc.get("diagnostics", {})),
                   dict(provenance) if isinstance(provenance, dict) else {})

    @classmethod
    def load(cls, path: str | Path) -> Calibration:
        return cls.from_json(read_json(path))

    def save(self, path: str | Path) -> None:
        write_json(path, self.to_json())


def _intrinsics(raw: Any) -> np.ndarray:
    if not isinstance(raw, dict):
        raise FormatError("intrinsics: expected an object {fx, fy, cx, cy, skew}")
    out = []
    for key in ("fx", "fy", "cx", "cy", "skew"):
        val = raw.get(key, 0.0 if key == "skew" else None)
        if not isinstance(val, (int, float)) or isinstance(val, bool) or not _finite(val):
            raise FormatError(f"intrinsics.{key}: expected a finite number, got {val!r}")
        out.append(float(val))
    if out[0] == 0 or out[1] == 0:
        raise FormatError("intrinsics: fx and fy must be non-zero")
    return np.array(out)


def _finite(x: int | float) -> bool:
    try:
        return math.isfinite(x)
    except OverflowError:  # an int past float64
        return False


MAX_SUPPORT_DIAGONALS = 4  # an MLS field's reach: past the image's diagonal it adds nothing, and at 1e300 exports hang
# A B-spline field's control values are pixel offsets. Bounded only where they stop being numbers a fit could
# write (at 1e300 the evaluation overflows, FloatingPointError, and the exports' fits are singular): a field on a
# base that does not suit the lens may bend far, and a calibration freecal wrote must read back (1e12 px: no error).
MAX_CONTROL_PIXELS = 1e15


def _field_within(model: CameraModel, image_size: tuple[int, int]) -> None:
    """An MLS field's ``support`` is at most a few image diagonals, a B-spline field's control values finite numbers
    a fit could write (pixels)."""
    from .models.bspline_basis import BSplineField
    from .models.hybrid import HybridModel
    from .models.mls import MLSField

    field = getattr(model, "field", None)
    diagonal = math.hypot(*image_size)
    if isinstance(field, MLSField):
        most = MAX_SUPPORT_DIAGONALS * diagonal
        if not field.support <= most:
            raise FormatError(f"distortion.support: expected a positive number of pixels at most {most:.0f} "
                              f"({MAX_SUPPORT_DIAGONALS} image diagonals), got {field.support:g}")
    if isinstance(field, BSplineField):
        where = "distortion.field" if isinstance(model, HybridModel) else "distortion"
        for axis, key in enumerate(("control_x", "control_y")):
            largest = float(np.max(np.abs(field.control[..., axis])))
            if not largest <= MAX_CONTROL_PIXELS:
                raise FormatError(f"{where}.{key}: expected pixel offsets of at most {MAX_CONTROL_PIXELS:g}, got "
                                  f"{largest:g}: not a lens's field")


def _float(x) -> float:
    return float("nan") if x is None else float(x)


def _num(x: float):
    """JSON has no NaN: write null instead."""
    return None if x is None or not math.isfinite(float(x)) else float(x)


def json_safe(obj):
    """A nested structure made JSON-safe: numpy scalars and arrays → Python,
    NaN/inf → null, anything with ``to_json()`` (a Calibration) → its JSON."""
    if hasattr(obj, "to_json"):
        return obj.to_json()
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _num(float(obj))
    return obj
