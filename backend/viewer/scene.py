"""``build_scene(scene, result)``: one finished job drawn in a viser scene, so that it explains itself.

Coordinates are the camera frame (OpenCV: x right, y down, z forward), scaled
so that the median board distance is 1 scene unit (a 25 mm board 900 mm away
and a 1 m board 30 m away both fill the view); the scene's up is −y.

Nodes, by path (tests and the controls find them by these names):

    /cameras/0                  the camera's frame at the origin, its axes drawn
    /cameras/0/frustum          its body (frustum, the image's aspect and vertical field of view)
    /cameras/0/x, /y, /z        the axis labels ("x right", "y down", "z optical axis"); /cameras/0/label "camera"
    /image_plane/outline        the ideal image plane (image rectangle, ideal pixels), nearer than every board
    /image_plane/knots          the knot grid on that plane: only when the model has a field
    /residuals/vectors          residual vectors on that plane, at the observed corners, magnified
    /boards/K/...               view K's board, in its own colour, with its name (``boards.py``)
    /field/dx, /field/dy        the Δx, Δy surfaces under the rig (``field.py``)

``Built.view`` is a camera pose for a new tab: behind and above the camera,
looking at the camera and the boards together.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import colormap
from .boards import add_boards, board_points
from .data import JobResult
from .field import COMPONENTS, add_field
from .field import set_component as _set_component

PLANE_DEPTH = 0.5       # the ideal image plane's distance from the camera (scene units), unless a board is nearer
AXIS_LENGTH = 0.2       # the camera's axes, scene units
__all__ = ["COMPONENTS", "Built", "Pose", "add_camera", "build_scene", "overview", "set_component"]


@dataclass(frozen=True)
class Pose:
    """Where a viewer's camera stands and what it looks at (scene units; up is −y)."""

    position: tuple[float, float, float]
    look_at: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, -1.0, 0.0)


@dataclass
class Built:
    """What build_scene made: handles by node path, the numbers a legend needs, the views in board order,
    and a camera pose for a new tab."""

    handles: dict[str, Any] = field(default_factory=dict)
    legend: dict[str, float] = field(default_factory=dict)
    views: list[str] = field(default_factory=list)
    view: Pose = Pose((0.9, -0.8, -0.9), (0.0, 0.3, 0.9))

    def names(self) -> list[str]:
        return sorted(self.handles)


def scale_and_error_range(boards) -> tuple[float, float]:
    """The scene's scale (the boards' median distance is one unit) and the corner error (px) the colours
    top out at (the 95th percentile)."""
    depths = [float(np.linalg.norm(b.tvec)) for b in boards]
    scale = 1.0 / (float(np.median(depths)) if depths and np.median(depths) > 0 else 1.0)
    errors = np.concatenate([np.hypot(*b.residuals.T) for b in boards]) if boards else np.zeros(1)
    finite = errors[np.isfinite(errors)]
    vmax = float(np.percentile(finite, 95)) if finite.size else 1.0
    return scale, vmax if vmax > 0 else 1.0


def build_scene(scene: Any, result: JobResult, component: str = COMPONENTS[0]) -> Built:
    """Draw ``result`` into ``scene`` (``server.scene`` or ``client.scene``), replacing what was there.

    ``component`` chooses the distortion surfaces shown (one of ``COMPONENTS``).
    """
    built = Built(views=[b.name for b in result.boards])
    cal = result.calibration
    scale, vmax = scale_and_error_range(result.boards)
    built.legend.update(error_max_px=vmax, scene_unit=1.0 / scale)
    points = np.concatenate([board_points(b, scale) for b in result.boards]) if result.boards else np.zeros((0, 3))
    # the image plane stays nearer than every corner, so nothing drawn on it passes through a board
    near = float(points[:, 2].min()) if len(points) else PLANE_DEPTH / 0.8
    depth = float(np.clip(0.8 * near, 0.05, PLANE_DEPTH))

    scene.reset()
    scene.set_up_direction("-y")
    _add_camera(scene, built.handles, result, depth)
    plane = _add_image_plane(scene, built, result, depth, vmax)
    add_boards(scene, built.handles, result.boards, scale, vmax)
    drawn = np.vstack([points, plane, np.zeros((1, 3))])   # boards, image plane, camera
    extent = np.array([drawn.min(axis=0), drawn.max(axis=0)])
    add_field(scene, built.handles, built.legend, cal, extent, component)
    built.view = overview(points)
    return built


def set_component(built: Built, component: str) -> None:
    """Show the surfaces ``component`` names, hide the other (no rebuild)."""
    _set_component(built.handles, component)


def _add_camera(scene: Any, handles: dict[str, Any], result: JobResult, depth: float) -> None:
    """The camera at the origin: its frame with labelled axes, and its frustum reaching the image plane."""
    add_camera(scene, handles, "/cameras/0", result.calibration, depth * 0.6, "camera", axes=AXIS_LENGTH)


def add_camera(scene: Any, handles: dict[str, Any], path: str, calibration: Any, size: float, label: str, *,
               colour: tuple[int, int, int] = (40, 40, 40), axes: float = 0.0,
               wxyz: Any = (1.0, 0.0, 0.0, 0.0), position: Any = (0.0, 0.0, 0.0),
               label_height: float | None = None) -> None:
    """One camera under ``path``: a frame at its pose (camera → scene), its frustum (``size`` deep, the
    image's aspect and vertical field of view) in ``colour``, its name ``label_height`` above it (default
    0.4 of the axes or the frustum); with ``axes`` > 0 its axes that long, labelled x right, y down, z optical
    axis (``path``/x, /y, /z). The rig's scene draws its cameras with it."""
    w, h = calibration.image_size
    fy = calibration.model.intrinsics_json()["fy"]
    handles[path] = scene.add_frame(path, show_axes=axes > 0, axes_length=axes or AXIS_LENGTH,
                                    axes_radius=(axes or AXIS_LENGTH) * 0.03, wxyz=tuple(float(q) for q in wxyz),
                                    position=tuple(float(x) for x in position))
    handles[f"{path}/frustum"] = scene.add_camera_frustum(
        f"{path}/frustum", fov=float(2.0 * np.arctan2(h / 2.0, fy)), aspect=w / h, scale=size,
        color=colour, thickness=0.004)
    if axes > 0:
        tips = {"x": ((axes * 1.1, 0, 0), "x right"), "y": ((0, axes * 1.1, 0), "y down"),
                "z": ((0, 0, axes * 1.1), "z optical axis")}
        for axis, (tip, text) in tips.items():
            handles[f"{path}/{axis}"] = scene.add_label(f"{path}/{axis}", text, position=tip,
                                                        anchor="center-left", font_screen_scale=0.8)
    height = (axes or size) * 0.4 if label_height is None else label_height
    handles[f"{path}/label"] = scene.add_label(f"{path}/label", label, position=(0, -height, 0),
                                               anchor="bottom-center")


def _add_image_plane(scene: Any, built: Built, result: JobResult, depth: float, vmax: float) -> np.ndarray:
    """The ideal image plane at ``depth``: outline, knot grid (a field only), residual vectors; its corners (4, 3)."""
    cal = result.calibration
    w, h = result.image_size
    k = cal.model.intrinsics_json()
    handles = built.handles

    def on_plane(uv: np.ndarray) -> np.ndarray:
        """Ideal pixels (N, 2) → points (N, 3) on the ideal image plane."""
        x = (uv[:, 0] - k["cx"] - k.get("skew", 0.0) * (uv[:, 1] - k["cy"]) / k["fy"]) / k["fx"]
        y = (uv[:, 1] - k["cy"]) / k["fy"]
        return np.column_stack([x, y, np.ones(len(uv))]) * depth

    corners = on_plane(np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float))
    handles["/image_plane/outline"] = scene.add_line_segments(
        "/image_plane/outline", np.stack([corners, np.roll(corners, -1, axis=0)], axis=1),
        colors=(90, 90, 90), thickness=0.002)
    knots = _knot_lines(cal)
    if knots is not None:   # a model without a field has no knots: nothing to draw, no layer to offer
        handles["/image_plane/knots"] = scene.add_line_segments(
            "/image_plane/knots", np.stack([on_plane(knots[:, 0]), on_plane(knots[:, 1])], axis=1),
            colors=(230, 120, 20), thickness=0.0015)

    handles["/residuals"] = scene.add_frame("/residuals", show_axes=False)
    if result.boards:
        obs = np.concatenate([b.image_points for b in result.boards])
        res = np.concatenate([b.residuals for b in result.boards])
        ok = np.all(np.isfinite(res), axis=1)
        # magnify so the 95th-percentile error spans 1/40 of the image width
        gain = (w / 40.0) / vmax
        built.legend["vector_gain"] = gain
        ideal = _ideal(cal, obs[ok])
        col = colormap.sequential(np.hypot(*res[ok].T), vmax)
        handles["/residuals/vectors"] = scene.add_line_segments(
            "/residuals/vectors", np.stack([on_plane(ideal), on_plane(ideal + gain * res[ok])], axis=1),
            colors=np.stack([col, col], axis=1), thickness=0.0015)
    return corners


def overview(points: np.ndarray) -> Pose:
    """Behind, above and to the right of the camera (the origin), far enough to see it and every point."""
    everything = np.vstack([points, np.zeros((1, 3))])
    centre = (everything.min(axis=0) + everything.max(axis=0)) / 2.0
    radius = max(float(np.linalg.norm(everything - centre, axis=1).max()), 0.3)
    direction = np.array([0.45, -0.55, -1.0]) / np.linalg.norm([0.45, -0.55, -1.0])
    position = centre + direction * radius * 1.7
    return Pose(tuple(float(x) for x in position), tuple(float(x) for x in centre))  # type: ignore[arg-type]


def _knot_lines(cal: Any) -> np.ndarray | None:
    """Segments (M, 2, 2) in ideal pixels along the knot breaks of the model's field, or None: no field,
    or one held at zero (a core chosen alone keeps its field's knots, fitting nothing)."""
    breaks = cal.model.knot_breaks()
    if breaks is None or getattr(cal.model, "field_held", False):
        return None
    bu, bv = breaks[0].tolist(), breaks[1].tolist()
    segs = [[[x, bv[0]], [x, bv[-1]]] for x in bu] + [[[bu[0], y], [bu[-1], y]] for y in bv]
    return np.asarray(segs, float)


def _ideal(cal: Any, uv: np.ndarray) -> np.ndarray:
    """Observed pixels → ideal pixels; observed ones where undistortion fails (far off axis)."""
    with np.errstate(all="ignore"):
        ideal = cal.undistort_points(uv)
    return np.where(np.isfinite(ideal), ideal, uv)
