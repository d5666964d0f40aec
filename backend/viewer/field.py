"""The distortion field as its own surfaces (the paper's Fig. 13): Δx and Δy over the image, colour-mapped.

They lie flat like a floor under everything else in the scene (the camera, the
image plane and every board), their relief rising at most ``RELIEF`` of their
width: placed from the scene's extents, they never cut through a board, however
the boards were held. Each is the image seen from above (u along x, v along z).

    /field            the group the Field surfaces layer shows and hides
    /field/dx, /dy    the surfaces;  /field/dx/label, /field/dy/label  their names and scale
"""
from __future__ import annotations

from typing import Any

import numpy as np

from calib_core.report.distortion import distortion_maps

from . import colormap

GRID = (41, 31)        # surface samples along u, v
RELIEF = 0.25          # height of the largest |Δ|, as a share of a surface's width
COMPONENTS = ("Δx and Δy", "Δx", "Δy")


def add_field(scene: Any, handles: dict[str, Any], legend: dict[str, float], cal: Any,
              extent: np.ndarray, component: str) -> None:
    """Draw the surfaces below ``extent`` ((2, 3): min and max corner of what else is in the scene)."""
    import trimesh

    w, h = cal.image_size
    nu, nv = GRID
    u, v = np.meshgrid(np.linspace(0, w - 1, nu), np.linspace(0, h - 1, nv))
    # the same data and colour scale as the page's 2-D map (calib_core.report.distortion): the field's
    # own part when there is a field over a core, else the offsets against the pinhole; values past
    # the scale (the 98th percentile) saturate
    doc = distortion_maps(cal, GRID)
    m = doc["maps"]["field" if "field" in doc["maps"] else "pinhole"]
    delta = np.column_stack([np.array([np.nan if x is None else x for x in m[c]], float) for c in ("dx", "dy")])
    delta = np.where(np.isfinite(delta), delta, 0.0)
    vabs = float(m["scale"])
    delta = np.clip(delta, -vabs, vabs)
    legend["field_max_px"] = vabs

    lo, hi = extent
    size = float(np.clip(0.45 * (hi[0] - lo[0]), 0.4, 1.5))   # each surface: under half the rig's width
    rise = RELIEF * size
    floor = hi[1] + 0.15 * size + rise      # y is down: below the lowest point, with room for the relief
    centre_x, centre_z = (lo[0] + hi[0]) / 2.0, (lo[2] + hi[2]) / 2.0
    faces = _grid_faces(nu, nv)
    handles["/field"] = scene.add_frame("/field", show_axes=False)
    for j, name in enumerate(("dx", "dy")):
        x = centre_x + (u.ravel() / (w - 1) - 0.5) * size + (j - 0.5) * size * 1.15
        z = centre_z + (v.ravel() / (h - 1) - 0.5) * size * h / w
        y = floor - delta[:, j] / vabs * rise
        rgba = np.column_stack([colormap.diverging(delta[:, j], vabs), np.full(len(x), 255, np.uint8)])
        mesh = trimesh.Trimesh(np.column_stack([x, y, z]), faces, vertex_colors=rgba, process=False)
        path = f"/field/{name}"
        handles[path] = scene.add_mesh_trimesh(path, mesh)
        handles[path + "/label"] = scene.add_label(
            path + "/label", f"{'Δx' if name == 'dx' else 'Δy'} [px], ±{vabs:.3g} px",
            position=(float(x.mean()), float(floor - rise * 1.3), float(z.min())))
    set_component(handles, component)


def set_component(handles: dict[str, Any], component: str) -> None:
    """Show the surfaces ``component`` names, hide the other (no rebuild)."""
    for name, shown in (("dx", component in (COMPONENTS[0], "Δx")), ("dy", component in (COMPONENTS[0], "Δy"))):
        for path in (f"/field/{name}", f"/field/{name}/label"):
            if path in handles:
                handles[path].visible = shown


def _grid_faces(nu: int, nv: int) -> np.ndarray:
    idx = np.arange(nu * nv).reshape(nv, nu)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    # both windings, so the surface is visible from above and below
    return np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d]),
                           np.column_stack([a, c, b]), np.column_stack([a, d, c])])
