"""A rig on frames it was not fitted to: every camera's model and the
cameras' relative poses held, only the board's pose at each frame refit from
all the cameras that saw it (the rig's form of ``evaluation.evaluate``). A
wrong relative pose shows here: one board pose cannot then meet every camera."""
from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import DataError
from ..fitting import metrics
from ..fitting.init import poses_from_rays
from ..observations import Observations
from ..pipeline import to_data
from .bundle import adjust
from .calibrate import CameraViews, corners_of, frame_key, initial_frames
from .frames import frames_of
from .rig import Rig


def evaluate_rig(rig: Rig, cameras: dict[str, Observations]) -> dict[str, Any]:
    """Errors of ``rig`` on ``cameras`` (name → hold-out observations of
    that camera; cameras the rig lacks are refused, rig cameras absent here
    are skipped), each frame's board pose refit; per camera and overall, and
    how many frames more than one camera saw (those test the relative poses)."""
    unknown = sorted(set(cameras) - {c.name for c in rig.cameras})
    if unknown:
        raise DataError(f"camera(s) {unknown} are not in the rig, whose cameras are {[c.name for c in rig.cameras]}")
    parts, extrinsics = [], []
    for cam in rig.cameras:  # the reference first, as the rig lists it
        if cam.name in cameras:
            parts.append(_views(cam.name, cameras[cam.name], cam.calibration))
            extrinsics.append(cam.pose)
    if len(parts) < 2:
        raise DataError("a rig's hold-out needs the views of two or more of its cameras")
    ext = np.array(extrinsics)
    frame_names = sorted({f for p in parts for f in p.frames}, key=frame_key)
    corners = corners_of(parts, frame_names)
    result = adjust(corners, [p.calibration.model for p in parts], ext, initial_frames(parts, ext, frame_names),
                    refine_models=False, refine_extrinsics=False)
    per_camera = {}
    for c, p in enumerate(parts):
        r = result.residuals[corners.camera == c]
        per_camera[p.name] = {"rmse": metrics.rmse(r), "rmse_axis": metrics.rmse_axis(r), "n_points": int(len(r))}
    seen_by = np.bincount([frame_names.index(f) for p in parts for f in p.frames], minlength=len(frame_names))
    return {"rmse": metrics.rmse(result.residuals), "rmse_axis": metrics.rmse_axis(result.residuals),
            "n_points": int(len(result.residuals)), "n_frames": len(frame_names),
            "n_shared_frames": int(np.sum(seen_by > 1)), "cameras": per_camera}


def _views(name: str, obs: Observations, cal) -> CameraViews:
    """The camera's views with each board pose found through its model (a start)."""
    if tuple(obs.image_size) != tuple(cal.image_size):
        raise DataError(f"camera {name!r}: image_size {list(obs.image_size)} differs from its calibration's "
                        f"{list(cal.image_size)}")
    data, _, _ = to_data(obs)
    poses = poses_from_rays(cal.model, data)
    if poses is None:
        raise DataError(f"camera {name!r}: could not find a board pose for every view through its model")
    return CameraViews(name, cal, frames_of(name, obs.views), poses,
                       [v.object_points for v in obs.views], [v.image_points for v in obs.views])
