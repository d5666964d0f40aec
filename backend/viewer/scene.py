"""``build_scene(scene, result)``: one finished job drawn in a viser scene.

Coordinates are the camera frame (OpenCV: x right, y down, z forward), scaled
so that the median board distance is 1 scene unit (a 25 mm board 900 mm away
and a 1 m board 30 m away both fill the view); the scene's up is −y.

Nodes, by path (tests and the controls find them by these names):

    /cameras/0/frustum          the camera, at the origin
    /image_plane/outline        the ideal image plane (image rectangle, ideal pixels) in front of it
    /image_plane/knots          the B-spline knot grid on that plane (B-spline methods)
    /residuals/vectors          residual vectors on that plane, at the observed corners, magnified
    /boards/K                   board K's pose (frame: rotation and translation of view K)
    /boards/K/corners           its corners, coloured by |residual| (px)
    /boards/K/outline           its outline
    /field/dx, /field/dy        Δx, Δy surfaces (observed − ideal pixel over the ideal image), colour-mapped
    /field/dx/label, ...        their labels
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from calib_core.report.distortion import distortion_maps

from . import colormap
from .data import JobResult

PLANE_DEPTH = 0.5       # the ideal image plane's distance from the camera, scene units
FIELD_SIZE = 0.9        # width of each distortion surface, scene units
FIELD_HEIGHT = 0.25     # height of the largest |Δ| on the surfaces, scene units
FIELD_GRID = (41, 31)   # surface samples along u, v
COMPONENTS = ("Δx and Δy", "Δx", "Δy")


@dataclass
class Built:
    """What build_scene made: handles by node path, and the numbers a legend needs."""

    handles: dict[str, Any] = field(default_factory=dict)
    legend: dict[str, float] = field(default_factory=dict)

    def names(self) -> list[str]:
        return sorted(self.handles)


def build_scene(scene: Any, result: JobResult, component: str = COMPONENTS[0]) -> Built:
    """Draw ``result`` into ``scene`` (``server.scene`` or ``client.scene``), replacing what was there.

    ``component`` chooses the distortion surfaces shown (one of ``COMPONENTS``).
    """
    import viser.transforms as tf

    built = Built()
    cal = result.calibration
    w, h = result.image_size
    k = cal.to_json()["intrinsics"]
    depths = [float(np.linalg.norm(b.tvec)) for b in result.boards]
    scale = 1.0 / (float(np.median(depths)) if depths and np.median(depths) > 0 else 1.0)
    errors = np.concatenate([np.hypot(*b.residuals.T) for b in result.boards]) if result.boards else np.zeros(1)
    finite = errors[np.isfinite(errors)]
    vmax = float(np.percentile(finite, 95)) if finite.size else 1.0
    vmax = vmax if vmax > 0 else 1.0
    built.legend.update(error_max_px=vmax, scene_unit=1.0 / scale)

    scene.reset()
    scene.set_up_direction("-y")
    add = built.handles.__setitem__

    fov_y = 2.0 * np.arctan2(h / 2.0, k["fy"])
    add("/cameras/0/frustum", scene.add_camera_frustum(
        "/cameras/0/frustum", fov=float(fov_y), aspect=w / h, scale=PLANE_DEPTH * 0.6,
        color=(40, 40, 40), thickness=0.004))

    def on_plane(uv: np.ndarray) -> np.ndarray:
        """Ideal pixels (N, 2) → points (N, 3) on the ideal image plane."""
        x = (uv[:, 0] - k["cx"] - k.get("skew", 0.0) * (uv[:, 1] - k["cy"]) / k["fy"]) / k["fx"]
        y = (uv[:, 1] - k["cy"]) / k["fy"]
        return np.column_stack([x, y, np.ones(len(uv))]) * PLANE_DEPTH

    rect = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], float)
    corners3 = on_plane(rect)
    add("/image_plane/outline", scene.add_line_segments(
        "/image_plane/outline", np.stack([corners3, np.roll(corners3, -1, axis=0)], axis=1),
        colors=(90, 90, 90), thickness=0.002))

    knots = _knot_lines(cal, w, h)
    if knots is not None:
        add("/image_plane/knots", scene.add_line_segments(
            "/image_plane/knots", np.stack([on_plane(knots[:, 0]), on_plane(knots[:, 1])], axis=1),
            colors=(230, 120, 20), thickness=0.0015))

    if result.boards:
        obs = np.concatenate([b.image_points for b in result.boards])
        res = np.concatenate([b.residuals for b in result.boards])
        ok = np.all(np.isfinite(res), axis=1)
        # magnify so the 95th-percentile error spans 1/40 of the image width
        gain = (w / 40.0) / vmax
        built.legend["vector_gain"] = gain
        start = on_plane(_ideal(cal, obs[ok]))
        end = on_plane(_ideal(cal, obs[ok]) + gain * res[ok])
        col = colormap.sequential(np.hypot(*res[ok].T), vmax)
        add("/residuals/vectors", scene.add_line_segments(
            "/residuals/vectors", np.stack([start, end], axis=1), colors=np.stack([col, col], axis=1),
            thickness=0.0015))

    for i, b in enumerate(result.boards):
        base = f"/boards/{i}"
        add(base, scene.add_frame(base, show_axes=False, wxyz=tf.SO3.exp(b.rvec).wxyz,
                                  position=b.tvec * scale))
        pts = b.object_points * scale
        err = np.hypot(*b.residuals.T)
        spacing = _spacing(b.object_points) * scale
        add(base + "/corners", scene.add_point_cloud(
            base + "/corners", pts, colors=colormap.sequential(err, vmax), point_size=spacing * 0.22,
            point_shape="circle", point_shading="flat"))
        lo, hi = b.object_points.min(axis=0) * scale, b.object_points.max(axis=0) * scale
        box = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]])
        add(base + "/outline", scene.add_line_segments(
            base + "/outline", np.stack([box, np.roll(box, -1, axis=0)], axis=1), colors=(60, 60, 160),
            thickness=0.002))

    _add_field(scene, built, cal, w, h, component)
    return built


def set_component(built: Built, component: str) -> None:
    """Show the surfaces ``component`` names, hide the other (no rebuild)."""
    for name, shown in (("dx", component in (COMPONENTS[0], "Δx")), ("dy", component in (COMPONENTS[0], "Δy"))):
        for path in (f"/field/{name}", f"/field/{name}/label"):
            if path in built.handles:
                built.handles[path].visible = shown


def _add_field(scene: Any, built: Built, cal: Any, w: int, h: int, component: str) -> None:
    """The Fig. 13 surfaces: Δx and Δy over the image, side by side below the rig."""
    import trimesh

    nu, nv = FIELD_GRID
    u, v = np.meshgrid(np.linspace(0, w - 1, nu), np.linspace(0, h - 1, nv))
    # the same data and colour scale as the page's 2-D map (calib_core.report.distortion): the field's
    # own part when there is a field over a core, else the offsets against the pinhole; values past
    # the scale (the 98th percentile) saturate
    doc = distortion_maps(cal, FIELD_GRID)
    m = doc["maps"]["field" if "field" in doc["maps"] else "pinhole"]
    delta = np.column_stack([np.array([np.nan if x is None else x for x in m[c]], float) for c in ("dx", "dy")])
    delta = np.where(np.isfinite(delta), delta, 0.0)
    vabs = float(m["scale"])
    delta = np.clip(delta, -vabs, vabs)
    built.legend["field_max_px"] = vabs
    size_v = FIELD_SIZE * h / w
    faces = _grid_faces(nu, nv)
    for j, name in enumerate(("dx", "dy")):
        # lay each surface flat below the rig (y is down, so +y), the value rising upward (−y)
        x = (u.ravel() / (w - 1) - 0.5) * FIELD_SIZE + (j - 0.5) * FIELD_SIZE * 1.15
        z = 1.0 + (v.ravel() / (h - 1) - 0.5) * size_v
        y = 0.75 - delta[:, j] / vabs * FIELD_HEIGHT
        rgba = np.column_stack([colormap.diverging(delta[:, j], vabs), np.full(len(x), 255, np.uint8)])
        mesh = trimesh.Trimesh(np.column_stack([x, y, z]), faces, vertex_colors=rgba, process=False)
        path = f"/field/{name}"
        built.handles[path] = scene.add_mesh_trimesh(path, mesh)
        label = "Δx" if name == "dx" else "Δy"
        built.handles[path + "/label"] = scene.add_label(
            path + "/label", f"{label} [px], ±{vabs:.3g} px", position=(float(x.mean()), 0.75 - FIELD_HEIGHT * 1.3,
                                                                        float(z.min())))
    set_component(built, component)


def _grid_faces(nu: int, nv: int) -> np.ndarray:
    idx = np.arange(nu * nv).reshape(nv, nu)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    # both windings, so the surface is visible from above and below
    return np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d]),
                           np.column_stack([a, c, b]), np.column_stack([a, d, c])])


def _knot_lines(cal: Any, w: int, h: int) -> np.ndarray | None:
    """Segments (M, 2, 2) in ideal pixels along the knot breaks of a B-spline field, or None."""
    breaks = cal.model.knot_breaks()
    if breaks is None:
        return None
    bu, bv = breaks[0].tolist(), breaks[1].tolist()
    segs = [[[x, bv[0]], [x, bv[-1]]] for x in bu] + [[[bu[0], y], [bu[-1], y]] for y in bv]
    return np.asarray(segs, float)


def _ideal(cal: Any, uv: np.ndarray) -> np.ndarray:
    """Observed pixels → ideal pixels; observed ones where undistortion fails (far off axis)."""
    with np.errstate(all="ignore"):
        ideal = cal.undistort_points(uv)
    return np.where(np.isfinite(ideal), ideal, uv)


def _spacing(object_points: np.ndarray) -> float:
    """Typical distance between neighbouring corners (board units)."""
    if len(object_points) < 2:
        return 1.0
    d = np.linalg.norm(object_points[1:] - object_points[:-1], axis=1)
    d = d[d > 0]
    return float(np.median(d)) if d.size else 1.0
