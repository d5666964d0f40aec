"""The board poses of a job in the 3D view: one group per view, in that view's own colour, with its name.

Each ``/boards/K`` is a frame at view K's pose (board → camera) holding:

    /boards/K/plane       the board, a translucent sheet in the view's colour (click it: that view is selected)
    /boards/K/outline     its edge, in the view's colour
    /boards/K/corners     its corners, coloured by |residual| (px), the same scale as the residual vectors
    /boards/K/label       the view's name (the photo's), as the page's per-view table names it
    /boards/K/highlight   a thick bright edge, shown only for the selected view (``layers.highlight``)
"""
from __future__ import annotations

from typing import Any

import numpy as np

from . import colormap
from .data import BoardView

HIGHLIGHT = (255, 215, 0)   # gold: no view colour is this saturated and this bright at once
SHEET_OPACITY = 0.35        # enough to tell the boards apart, little enough to see those behind


def board_points(board: BoardView, scale: float) -> np.ndarray:
    """The board's corners in the camera frame, scene units (for extents: where the boards are)."""
    import viser.transforms as tf

    rot = tf.SO3.exp(board.rvec).as_matrix()
    return (board.object_points @ rot.T + board.tvec) * scale


def add_boards(scene: Any, handles: dict[str, Any], boards: list[BoardView], scale: float, vmax: float) -> None:
    """Draw every board under ``/boards`` (a group the Boards layer shows and hides)."""
    import viser.transforms as tf

    handles["/boards"] = scene.add_frame("/boards", show_axes=False)
    colours = colormap.categorical(len(boards))
    for i, b in enumerate(boards):
        base = f"/boards/{i}"
        colour = tuple(int(c) for c in colours[i])
        handles[base] = scene.add_frame(base, show_axes=False, wxyz=tf.SO3.exp(b.rvec).wxyz, position=b.tvec * scale)
        pts = b.object_points * scale
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        box = np.array([[lo[0], lo[1], 0], [hi[0], lo[1], 0], [hi[0], hi[1], 0], [lo[0], hi[1], 0]])
        edges = np.stack([box, np.roll(box, -1, axis=0)], axis=1)
        handles[base + "/plane"] = scene.add_mesh_simple(
            base + "/plane", box, np.array([[0, 1, 2], [0, 2, 3]]), color=colour, opacity=SHEET_OPACITY,
            side="double", cast_shadow=False, receive_shadow=False)
        handles[base + "/outline"] = scene.add_line_segments(base + "/outline", edges, colors=colour, thickness=0.003)
        handles[base + "/highlight"] = scene.add_line_segments(
            base + "/highlight", edges, colors=HIGHLIGHT, thickness=0.012, visible=False)
        err = np.hypot(*b.residuals.T)
        handles[base + "/corners"] = scene.add_point_cloud(
            base + "/corners", pts, colors=colormap.sequential(err, vmax), point_size=_spacing(b.object_points) * scale * 0.22,
            point_shape="circle", point_shading="flat")
        handles[base + "/label"] = scene.add_label(base + "/label", b.name, position=(float(lo[0]), float(lo[1]), 0.0),
                                                   anchor="bottom-left", font_screen_scale=0.8)


def board_colours(handles: dict[str, Any]) -> dict[str, tuple[int, ...]]:
    """Board path → its colour, as drawn (for tests and the legend)."""
    return {path[: -len("/outline")]: tuple(int(c) for c in np.asarray(h.colors).reshape(-1, 3)[0])
            for path, h in handles.items() if path.startswith("/boards/") and path.endswith("/outline")}


def _spacing(object_points: np.ndarray) -> float:
    """Typical distance between neighbouring corners (board units)."""
    if len(object_points) < 2:
        return 1.0
    d = np.linalg.norm(object_points[1:] - object_points[:-1], axis=1)
    d = d[d > 0]
    return float(np.median(d)) if d.size else 1.0
