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
