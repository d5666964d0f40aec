"""The panel's legend: what each thing in the scene is, and its colour scale, in words."""
from __future__ import annotations

from .data import JobResult
from .scene import Built


def legend(result: JobResult, built: Built) -> str:
    lg = built.legend
    metrics = result.calibration.metrics
    rmse = None if metrics is None else metrics.rmse
    field_px = lg.get("field_max_px", 0)
    return "\n".join([
        f"**{len(result.boards)} board poses**" + (f", rmse {rmse:.3f} px" if rmse else ""),
        "- the camera at the origin: its frustum and axes (x right, y down, z along the optical axis)",
        "- boards: one colour and the photo's name per view; click a board to select its view "
        "(gold edge, also picked in the page's per-view table)",
        f"- corners and vectors: colour = |residual|, 0 to {lg.get('error_max_px', 0):.2f} px (95th percentile);"
        f" vectors ×{lg.get('vector_gain', 0):.0f}, on the ideal image plane (grey rectangle)",
        "- orange lines: the field's knot grid on the ideal image plane" if "/image_plane/knots" in built.handles
        else "- no knot grid: this model has no field",
        f"- surfaces under the rig: Δx, Δy (the field's own part over its core, else observed − ideal pinhole "
        f"pixel: the page's map), blue −{field_px:.1f} px … red +{field_px:.1f} px (98th percentile; beyond it clipped)",
        f"- 1 scene unit = {lg.get('scene_unit', 0):.0f} {result.units} (the median board distance)",
    ])
