"""A calibrated rig, read and written as ``freecal.rig/1`` (formats.md §4)."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration import Calibration, json_safe
from ..errors import FormatError
from ..json_fields import json_object, number, required, whole
from ..models import camera
from ..observations import read_json, write_json
from .poses import inverse

FORMAT = "freecal.rig/1"


@dataclass
class RigCamera:
    """One camera: its pose relative to the reference camera
    (``Pc = R(rvec) · Pc_ref + tvec``) and its own complete calibration."""

    name: str
    rvec: np.ndarray  # (3,)
    tvec: np.ndarray  # (3,)
    calibration: Calibration

    @property
    def pose(self) -> np.ndarray:
        return np.concatenate([self.rvec, self.tvec])

    @property
    def centre(self) -> np.ndarray:
        """(3,) the camera's optical centre in the reference camera's frame (the board's units)."""
        return inverse(self.pose)[3:]

    @property
    def rotation_deg(self) -> float:
        """The angle of its rotation from the reference camera."""
        return float(np.degrees(np.linalg.norm(self.rvec)))


@dataclass
class RigFrame:
    """The board's pose at one moment, in the reference camera's frame."""

    frame: str
    rvec: np.ndarray
    tvec: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        return np.concatenate([self.rvec, self.tvec])


@dataclass(frozen=True)
class RigMetrics:
    """The rig's error over every camera's inlier corners (px)."""

    rmse: float  # per point, OpenCV's figure
    rmse_axis: float  # per axis, mrcal's
    n_points: int

    def to_json(self) -> dict[str, Any]:
        return {"rmse": self.rmse, "rmse_axis": self.rmse_axis, "n_points": self.n_points}

    @classmethod
    def from_json(cls, raw: Any) -> RigMetrics:
        doc = json_object(raw, "metrics")
        return cls(number(required(doc, "rmse", "metrics"), "metrics.rmse"),
                   number(required(doc, "rmse_axis", "metrics"), "metrics.rmse_axis"),
                   whole(required(doc, "n_points", "metrics"), "metrics.n_points"))


@dataclass
class Rig:
    reference: str
    cameras: list[RigCamera]
    frames: list[RigFrame]
    metrics: RigMetrics
    diagnostics: dict[str, Any] = field(default_factory=dict)  # the solver's report, each camera's errors

    def camera(self, name: str) -> RigCamera:
        for c in self.cameras:
            if c.name == name:
                return c
        raise KeyError(name)

    def project(self, camera_name: str, points: np.ndarray, rvec=None, tvec=None) -> np.ndarray:
        """Pixels (N, 2) in camera ``camera_name`` of points (N, 3) in the
        reference camera's frame, or of board points when the board's pose in
        that frame (``rvec, tvec``, as a frame's) is given."""
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if rvec is not None:
            pts = camera.rotate(np.asarray(rvec, dtype=np.float64), pts) + np.asarray(tvec, dtype=np.float64)
        cam = self.camera(camera_name)
        return cam.calibration.model.project(camera.rotate(cam.rvec, pts) + cam.tvec)

    # ---- JSON ----------------------------------------------------------------------
    def to_json(self) -> dict[str, Any]:
        return {
            "format": FORMAT,
            "reference": self.reference,
            "cameras": [{"name": c.name, "rvec": _floats(c.rvec), "tvec": _floats(c.tvec),
                         "calibration": c.calibration.to_json()} for c in self.cameras],
            "frames": [{"frame": f.frame, "rvec": _floats(f.rvec), "tvec": _floats(f.tvec)} for f in self.frames],
            "metrics": self.metrics.to_json(),
            "diagnostics": json_safe(self.diagnostics),
        }

    @classmethod
    def from_json(cls, doc: Any) -> Rig:
        if not isinstance(doc, dict):
            raise FormatError("rig: expected a JSON object at the top level")
        if doc.get("format") != FORMAT:
            raise FormatError(f"format: expected {FORMAT!r}, got {doc.get('format')!r}; this file is not a freecal rig")
        cameras_raw = doc.get("cameras")
        if not isinstance(cameras_raw, list) or not cameras_raw:
            raise FormatError("cameras: expected a non-empty list of cameras")
        cameras = []
        for k, c in enumerate(cameras_raw):
            where = f"cameras[{k}]"
            if not isinstance(c, dict) or not isinstance(c.get("name"), str) or not c["name"]:
                raise FormatError(f"{where}: expected an object with a non-empty \"name\"")
            cameras.append(RigCamera(c["name"], _vector(c.get("rvec"), f"{where}.rvec"),
                                     _vector(c.get("tvec"), f"{where}.tvec"),
                                     Calibration.from_json(c.get("calibration"))))
        names = [c.name for c in cameras]
        if len(set(names)) != len(names):
            raise FormatError(f"cameras: names must be unique, got {names}")
        reference = doc.get("reference")
        if reference not in names:
            raise FormatError(f"reference: expected one of the cameras' names {names}, got {reference!r}")
        frames_raw = doc.get("frames", [])
        if not isinstance(frames_raw, list):
            raise FormatError("frames: expected a list")
        frames = []
        for k, f in enumerate(frames_raw):
            where = f"frames[{k}]"
            if not isinstance(f, dict) or not isinstance(f.get("frame"), str):
                raise FormatError(f"{where}: expected an object with a \"frame\" string")
            frames.append(RigFrame(f["frame"], _vector(f.get("rvec"), f"{where}.rvec"), _vector(f.get("tvec"), f"{where}.tvec")))
        diagnostics = doc.get("diagnostics", {})
        if not isinstance(diagnostics, dict):
            raise FormatError("diagnostics: expected an object")
        return cls(reference, cameras, frames, RigMetrics.from_json(doc.get("metrics")), diagnostics)

    @classmethod
    def load(cls, path: str | Path) -> Rig:
        return cls.from_json(read_json(path))

    def save(self, path: str | Path) -> None:
        write_json(path, self.to_json())


def _floats(v: np.ndarray) -> list[float]:
    return [float(x) for x in v]


def _vector(raw: Any, where: str) -> np.ndarray:
    if not (isinstance(raw, list) and len(raw) == 3
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in raw)):
        raise FormatError(f"{where}: expected 3 numbers, got {raw!r}")
    v = np.asarray(raw, dtype=np.float64)
    if not np.all(np.isfinite(v)):
        raise FormatError(f"{where}: expected finite numbers")
    return v
