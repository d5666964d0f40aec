"""Figures the page draws that need the calibration, not just the stored tables.

``knot_cells``: the paper's Figure 11, the B-spline knot grid with the number
of corners in each knot cell. Knots live in ideal pixels (``bspline``) or in
the parametric core's pixels (``hybrid``, where they are close to observed
pixels), so the corners are mapped there before counting.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np


def knot_cells(job_dir: Path) -> dict[str, Any] | None:
    """Breaks, per-cell corner counts (rows along v, columns along u) and the corners; None without knots."""
    from calib_core import Calibration

    knots_path = job_dir / "knots.json"
    if not knots_path.exists():
        return None
    knots = json.loads(knots_path.read_text())
    corners = json.loads((job_dir / "corner_residuals.json").read_text())
    obs = np.array([[c["x"], c["y"]] for c in corners if not c["outlier"]], float).reshape(-1, 2)
    if knots["type"] == "bspline":
        cal = Calibration.from_json(json.loads((job_dir / "calibration.json").read_text()))
        with np.errstate(all="ignore"):
            pos = cal.undistort_points(obs)
        where = "ideal pixels"
    else:
        pos, where = obs, "observed pixels (the hybrid field's knots are in the core's pixels, close to these)"
    bu = np.asarray(sorted(set(knots["knots_u"])), float)
    bv = np.asarray(sorted(set(knots["knots_v"])), float)
    ok = np.all(np.isfinite(pos), axis=1)
    counts, _, _ = np.histogram2d(pos[ok, 1], pos[ok, 0], bins=[bv, bu])
    return {"breaks_u": bu.tolist(), "breaks_v": bv.tolist(), "counts": counts.astype(int).tolist(),
            "positions": where, "corners": np.round(pos[ok], 2).tolist(), "type": knots["type"]}


def uncertainty(job_dir: Path, observations: Path, step: float = 32.0) -> dict[str, Any] | None:
    """Projection uncertainty over a pixel grid (calib_core.evaluation.uncertainty, boards frame), or None.

    The calibration's own views and inliers are the data; σ is estimated from their residuals.
    """
    from calib_core import Calibration, Observations
    from calib_core.pipeline import to_data
    from calib_core.evaluation.uncertainty import projection_uncertainty

    if not observations.exists():
        return None
    cal = Calibration.from_json(json.loads((job_dir / "calibration.json").read_text()))
    obs = Observations.load(observations).select([v.name for v in cal.views])
    data, names, local = to_data(obs)
    outliers = {(n, i) for n in names for i in cal.view(n).outliers}
    if outliers:
        keep = np.array([(names[k], int(i)) not in outliers for k, i in zip(data.view_index, local)])
        data = type(data)(data.object_points[keep], data.image_points[keep], data.view_index[keep], data.n_views)
    poses = np.array([cal.view(n).pose for n in names])
    um = projection_uncertainty(cal.model, poses, data, cal.image_size, step=step)
    doc = um.to_json()
    doc.update(covered=um.covered.tolist(), image_size=list(cal.image_size), step=step,
               note="standard deviation of the projection of a fixed direction if the corners were measured "
                    "again with the same noise; 'covered': an observed corner within reach")
    return doc
