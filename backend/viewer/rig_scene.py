"""``build_rig_scene(scene, result)``: a done rig job drawn in a viser scene, with the calibration scene's parts.

Coordinates are the reference camera's frame (OpenCV: x right, y down, z forward),
scaled so that the median board distance from it is 1 scene unit, as
``scene.build_scene`` does for one camera; the scene's up is −y.

Nodes, by path:

    /cameras/K              camera K's frame at its pose in the rig (its optical centre, its orientation);
                            the reference's at the origin with the world axes drawn and labelled
    /cameras/K/frustum      its body, in its own colour (``scene.add_camera``)
    /cameras/K/label        its name; the reference's says "(reference)"
    /boards/K/...           the board at frame K of the rig, in the reference camera's frame: its own colour,
                            "frame 003", corners coloured by |residual| in a camera that saw it (``boards.py``)

Camera K's frame maps camera coordinates to the reference's: ``Pc_ref = Rᵀ (Pc − t)``
for the rig's ``Pc = R(rvec) · Pc_ref + tvec``, so it stands at ``RigCamera.centre``
turned by ``Rᵀ``.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import colormap
from .boards import add_boards, board_points
from .data import RigResult
from .scene import AXIS_LENGTH, PLANE_DEPTH, Built, add_camera, overview, scale_and_error_range

FRUSTUM_SHARE = 0.6   # a frustum's depth, as a share of the distance to the nearest other camera
LABEL_STEP = 0.8      # each camera's name this many frustums higher than the one before: close cameras' names
                      # (a stereo pair's, side by side) would otherwise print over each other


def camera_poses(result: RigResult, scale: float) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each camera's (wxyz, position) in the scene: camera → reference frame, scene units."""
    import viser.transforms as tf

    return [(tf.SO3.exp(c.rvec).inverse().wxyz, c.centre * scale) for c in result.rig.cameras]


def camera_colours(n: int) -> np.ndarray:
    """One colour per camera (n, 3) uint8, darker than the boards' so the two never read as one."""
    return (colormap.categorical(n).astype(float) * 0.7).round().astype(np.uint8)


def build_rig_scene(scene: Any, result: RigResult) -> Built:
    """Draw the rig ``result`` into ``scene`` (``client.scene``), replacing what was there."""
    rig = result.rig
    built = Built(views=[b.name for b in result.boards])
    scale, vmax = scale_and_error_range(result.boards)
    centres = np.array([c.centre for c in rig.cameras]) * scale
    gaps = [float(np.linalg.norm(a - b)) for i, a in enumerate(centres) for b in centres[i + 1:]]
    nearest = min((g for g in gaps if g > 1e-9), default=PLANE_DEPTH)
    size = float(np.clip(FRUSTUM_SHARE * nearest, 0.03, PLANE_DEPTH * 0.6))
    built.legend.update(error_max_px=vmax, scene_unit=1.0 / scale, frustum=size)

    scene.reset()
    scene.set_up_direction("-y")
    colours = camera_colours(len(rig.cameras))
    for k, (cam, (wxyz, position)) in enumerate(zip(rig.cameras, camera_poses(result, scale), strict=True)):
        reference = cam.name == rig.reference
        add_camera(scene, built.handles, f"/cameras/{k}", cam.calibration, size,
                   f"{cam.name} (reference)" if reference else cam.name,
                   colour=tuple(int(c) for c in colours[k]),  # type: ignore[arg-type]
                   axes=min(AXIS_LENGTH, size * 1.5) if reference else 0.0, wxyz=wxyz, position=position,
                   label_height=(0.4 + LABEL_STEP * k) * size)
    add_boards(scene, built.handles, result.boards, scale, vmax)
    points = np.concatenate([board_points(b, scale) for b in result.boards]) if result.boards else np.zeros((0, 3))
    built.view = overview(np.vstack([points, centres]))
    return built


def rig_legend(result: RigResult, built: Built) -> str:
    """The panel's legend for a rig."""
    lg, rig = built.legend, result.rig
    return "\n".join([
        f"**Rig of {len(rig.cameras)} cameras, {len(result.boards)} frames**, rmse {rig.metrics.rmse:.3f} px",
        f"- cameras: a frustum each, in its own colour, with its name, placed from the reference camera "
        f"({rig.reference}, at the origin: its axes x right, y down, z along the optical axis)",
        "- boards: the board at each frame of the rig, in the reference camera's frame, one colour per frame; "
        f"corners: colour = |residual| in a camera that saw it, 0 to {lg.get('error_max_px', 0):.2f} px "
        "(95th percentile)",
        f"- 1 scene unit = {lg.get('scene_unit', 0):.0f} {result.units} (the median board distance)",
    ])
