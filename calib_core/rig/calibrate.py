"""Calibrating a rig: each camera alone, then the cameras' relative poses and
the board's pose at every frame fitted to every camera's corners together."""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from ..board import BoardSpec
from ..calibration import Calibration
from ..errors import CalibError, DataError
from ..fit_report import FitMetrics
from ..fitting import metrics
from ..methods.common import Progress, named, no_progress, scaled
from ..observations import Observations
from ..pipeline import calibrate
from .bundle import Corners, adjust
from .frames import frames_of, padding_hint, unlinked
from .poses import compose, inverse
from .rig import Rig, RigCamera, RigFrame, RigMetrics

# A camera whose corners the rig fits this much worse than its own calibration
# does is named in a warning: its frames are probably not simultaneous with the
# others' (unsynchronised shutters, a mislabelled frame) or it moved.
INCONSISTENT_RATIO = 1.5
INCONSISTENT_MARGIN_PX = 0.1
# Views matched as one frame are of one moment when the pose of one camera relative to the other
# is the same at each: measured per frame from the cameras' own calibrations it scatters by a
# few tenths of a degree (a tenth on the tests' pairs); frames off by one (a mislabelled frame,
# a dropped image) scatter by tens of degrees. The median frame's angle from their mean.
MAX_FRAME_SCATTER_DEG = 5.0
# A camera placed from fewer shared frames than this rests on them alone: a warning says so.
FEW_SHARED_FRAMES = 3


@dataclass
class CameraViews:
    """One camera's part: its own calibration, and per used view its frame,
    board pose and inlier corners."""

    name: str
    calibration: Calibration
    frames: list[str]
    poses: np.ndarray  # (V, 6) board → camera, per used view
    object_points: list[np.ndarray]
    image_points: list[np.ndarray]


def calibrate_rig(cameras: dict[str, Observations], method: str = "auto", reference: str | None = None,
                  progress: Progress | None = None, refine_models: bool = True, **settings: Any) -> Rig:
    """Calibrate each camera of ``cameras`` (name → its observations, views
    matched across cameras by frame: formats.md §4) with ``method`` and
    ``settings``, then the rig: each camera's pose relative to ``reference``
    (default the first camera) and the board's pose at every frame, fitted to
    all corners. ``refine_models``: each camera's model is refined in that fit
    too (its free parameters and regularisation as its own fit had them: the
    frames both cameras saw constrain each); False holds them as calibrated
    alone (OpenCV's ``stereoCalibrate`` with ``CALIB_FIX_INTRINSIC``)."""
    progress = progress or no_progress
    names = list(cameras)
    if len(names) < 2:
        raise DataError(f"a rig needs at least two cameras, got {len(names)}")
    reference = names[0] if reference is None else reference
    if reference not in cameras:
        raise DataError(f"reference camera {reference!r} is not one of the cameras {names}")
    # another board, duplicate and unshared frames fail before any calibration
    check_boards(cameras, reference)
    frames = {name: frames_of(name, obs.views) for name, obs in cameras.items()}
    lonely = unlinked(frames, reference)
    if lonely:
        raise DataError(_unlinked_words(lonely, reference) + padding_hint(frames, reference))
    parts = []
    for k, name in enumerate(names):
        part = named(scaled(progress, 0.8 * k / len(names), 0.8 * (k + 1) / len(names)), f"camera {name}")
        try:
            cal = calibrate(cameras[name], method, part, **settings)
        except CalibError as exc:  # say which camera
            raise type(exc)(f"camera {name!r}: {exc}") from None
        parts.append(_camera_part(name, cameras[name], cal))
    progress("rig: relative poses", 0.8)
    order = [names.index(reference)] + [k for k in range(len(names)) if names[k] != reference]
    parts = [parts[k] for k in order]
    extrinsics, placed_from = _initial_extrinsics(parts)
    frame_names = sorted({f for p in parts for f in p.frames}, key=frame_key)
    frame_poses = initial_frames(parts, extrinsics, frame_names)
    corners = corners_of(parts, frame_names)
    t0 = time.perf_counter()
    result = adjust(corners, [p.calibration.model for p in parts], extrinsics, frame_poses, refine_models)
    progress("rig: done", 1.0)
    return _rig(parts, frame_names, corners, result, time.perf_counter() - t0, refine_models, placed_from)


def _camera_part(name: str, obs: Observations, cal: Calibration) -> CameraViews:
    frame_of_view = dict(zip([v.name for v in obs.views], frames_of(name, obs.views), strict=True))
    frames, poses, obj, img = [], [], [], []
    for v in cal.views:
        view = obs.view(v.name)
        keep = np.ones(len(view), dtype=bool)
        keep[v.outliers] = False
        frames.append(frame_of_view[v.name])
        poses.append(v.pose)
        obj.append(view.object_points[keep])
        img.append(view.image_points[keep])
    return CameraViews(name, cal, frames, np.array(poses).reshape(-1, 6), obj, img)


def frame_key(frame: str):
    return (0, int(frame), frame) if frame.isdigit() else (1, 0, frame)


def check_boards(cameras: dict[str, Observations], reference: str) -> None:
    """Every camera's corners of one board: frames are moments when the cameras saw the same board,
    so a camera whose observations name another (its size, squares, units) was given the wrong file
    or spec, and its corners would pull every camera's model (a board in cm among mm: 120 px)."""
    ref = cameras[reference].board
    if ref is None:
        return
    ref_board = BoardSpec.from_json(ref).to_json()
    for name, obs in cameras.items():
        if obs.board is None or name == reference:
            continue
        board = BoardSpec.from_json(obs.board).to_json()
        differ = [k for k in dict.fromkeys([*ref_board, *board]) if ref_board.get(k) != board.get(k)]
        if differ:
            raise DataError(f"camera {name!r} saw another board than camera {reference!r}: "
                            + ", ".join(f"{k} {board.get(k)!r} against {ref_board.get(k)!r}" for k in differ)
                            + "; the cameras of a rig photograph one board together: give every camera the same "
                            "board spec (detect each camera's photos with it)")


def _unlinked_words(lonely: list[str], reference: str) -> str:
    return (f"camera(s) {lonely} share no frame with camera {reference!r} or any camera linked to it: photograph "
            "the board with them at the same moments, and number the images alike (left07.jpg, right07.jpg) or set "
            "each view's \"frame\"")


# ---- the starting point -----------------------------------------------------------
def _initial_extrinsics(parts: list[CameraViews]) -> tuple[np.ndarray, dict[int, tuple[int, int]]]:
    """(C, 6) each camera's pose relative to the first (the reference), from
    the frames it shares with a camera already placed: rotations averaged,
    translations by their median; and per camera placed so, (the camera it was
    placed from, the frames they share). Cameras are placed through any chain
    of shared frames. Views that are not of one moment (their relative pose
    scatters by more than MAX_FRAME_SCATTER_DEG) are refused."""
    placed = {0: np.zeros(6)}
    placed_from: dict[int, tuple[int, int]] = {}
    while len(placed) < len(parts):
        progress_made = False
        for c in range(len(parts)):
            if c in placed:
                continue
            for p, pose_p in list(placed.items()):
                shared = sorted(set(parts[c].frames) & set(parts[p].frames))
                if not shared:
                    continue
                relative = np.array([compose(parts[c].poses[parts[c].frames.index(f)],
                                              inverse(parts[p].poses[parts[p].frames.index(f)])) for f in shared])
                rotation = Rotation.from_rotvec(relative[:, :3]).mean()
                scatter = np.degrees(np.median((Rotation.from_rotvec(relative[:, :3]) * rotation.inv()).magnitude()))
                if scatter > MAX_FRAME_SCATTER_DEG:
                    raise DataError(
                        f"cameras {parts[c].name!r} and {parts[p].name!r}: the pose of one relative to the other "
                        f"differs by {scatter:.0f}° (median) between the {len(shared)} frames they share, where a rigid "
                        "rig's differs by under a degree: views matched as one frame are not of one moment; check "
                        "the frame numbers (left07 with right07; a dropped or extra image shifts them) or set each "
                        "view's \"frame\"")
                step = np.concatenate([rotation.as_rotvec(), np.median(relative[:, 3:], axis=0)])
                placed[c] = compose(step, pose_p)
                placed_from[c] = (p, len(shared))
                progress_made = True
                break
        if not progress_made:
            # possible still: views a camera's own calibration could not use
            raise DataError(_unlinked_words([parts[c].name for c in range(len(parts)) if c not in placed], parts[0].name))
    return np.array([placed[c] for c in range(len(parts))]), placed_from


def initial_frames(parts: list[CameraViews], extrinsics: np.ndarray, frame_names: list[str]) -> np.ndarray:
    """(F, 6) the board's pose in the reference camera's frame at each frame,
    from the first camera (reference first) that saw it."""
    out = np.zeros((len(frame_names), 6))
    for i, f in enumerate(frame_names):
        c = next(c for c, p in enumerate(parts) if f in p.frames)
        out[i] = compose(inverse(extrinsics[c]), parts[c].poses[parts[c].frames.index(f)])
    return out


def corners_of(parts: list[CameraViews], frame_names: list[str]) -> Corners:
    index = {f: i for i, f in enumerate(frame_names)}
    cam, frame, view, obj, img = [], [], [], [], []
    for c, p in enumerate(parts):
        for v, f in enumerate(p.frames):
            n = len(p.image_points[v])
            cam.append(np.full(n, c))
            frame.append(np.full(n, index[f]))
            view.append(np.full(n, v))
            obj.append(p.object_points[v])
            img.append(p.image_points[v])
    return Corners(np.concatenate(cam), np.concatenate(frame), np.concatenate(view),
                   np.vstack(obj), np.vstack(img))


# ---- the result -------------------------------------------------------------------
def _rig(parts: list[CameraViews], frame_names: list[str], corners: Corners, result, seconds: float,
         refine_models: bool, placed_from: dict[int, tuple[int, int]]) -> Rig:
    cameras, report = [], {}
    warnings = [f"camera {parts[c].name!r} was placed on the rig from {n} frame{'s' * (n != 1)} shared with camera "
                f"{parts[p].name!r}: its pose rests on {'that' if n == 1 else 'those'} alone; photograph the board "
                f"with both at {FEW_SHARED_FRAMES} or more moments" for c, (p, n) in placed_from.items()
                if n < FEW_SHARED_FRAMES]
    for c, p in enumerate(parts):
        mine = corners.camera == c
        res = result.residuals[mine]
        alone = p.calibration.metrics.rmse if p.calibration.metrics else float("nan")
        in_rig = metrics.rmse(res)
        report[p.name] = {"rmse_alone": alone, "rmse_in_rig": in_rig, "n_frames": len(p.frames),
                          "frames_shared_with_reference": len(set(p.frames) & set(parts[0].frames))}
        if in_rig > INCONSISTENT_RATIO * alone + INCONSISTENT_MARGIN_PX:
            warnings.append(f"camera {p.name!r}: the rig fits its corners at {in_rig:.3f} px where its own "
                            f"calibration reaches {alone:.3f} px; its frames may not be simultaneous with the "
                            "others' (check the frame numbers and the shutters' sync) or it moved on the rig")
        cameras.append(RigCamera(p.name, result.extrinsics[c, :3].copy(), result.extrinsics[c, 3:].copy(),
                                 _in_rig(p, c, corners, result, parts[0].name)))
    frames = [RigFrame(f, result.frames[i, :3].copy(), result.frames[i, 3:].copy()) for i, f in enumerate(frame_names)]
    diagnostics: dict[str, Any] = {
        "solver": {"iterations": result.iterations, "status": result.status, "cost": result.cost,
                   "seconds": seconds, "models_refined": refine_models},
        "cameras": report,
        # the cameras each one shares a frame with (Kalibr's cam_overlaps)
        "overlaps": {p.name: [q.name for q in parts if q is not p and set(p.frames) & set(q.frames)] for p in parts},
    }
    if warnings:
        diagnostics["warnings"] = warnings
    summary = RigMetrics(metrics.rmse(result.residuals), metrics.rmse_axis(result.residuals), len(result.residuals))
    return Rig(parts[0].name, cameras, frames, summary, diagnostics)


def _in_rig(part: CameraViews, c: int, corners: Corners, result, reference: str) -> Calibration:
    """The camera's calibration with its views' poses and errors those of the
    rig (the frame's pose composed with the camera's), complete on its own."""
    cal = part.calibration
    views = []
    for v, old in enumerate(cal.views):
        mine = (corners.camera == c) & (corners.view == v)
        res = result.residuals[mine]
        pose = compose(result.extrinsics[c], result.frames[corners.frame[mine][0]]) if mine.any() else old.pose
        views.append(dataclasses.replace(old, rvec=pose[:3], tvec=pose[3:], rmse=metrics.rmse(res),
                                         rmse_axis=metrics.rmse_axis(res)))
    mine = corners.camera == c
    summary = FitMetrics.of(result.residuals[mine], corners.image_points[mine], cal.image_size)
    return dataclasses.replace(cal, model=result.models[c], views=views, metrics=summary,
                               settings={**cal.settings, "rig_reference": reference})
