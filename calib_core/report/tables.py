"""A calibration's report: the tables and figure data the page, the 3D view and
``freecal calibrate --report`` show, from the calibration and the corners it
was fitted to.

Every product is plain JSON-ready data (lists, dicts, floats; ``None`` where a
value is not finite). ``report_files`` names them as the service's downloads
(``/api/jobs/{id}/{name}``) and the CLI's report folder do.
"""
from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np

from ..calibration import Calibration, json_safe
from ..evaluation.view_flags import view_flags
from ..exports import opencv_yaml
from ..observations import Observations

HEATMAP_CELLS = (16, 12)   # columns, rows over the image
FIELD_SAMPLES = (17, 13)   # distortion field sample grid (u, v)
UNCERTAINTY_STEP = 32.0    # px between the uncertainty map's samples


def report_files(cal: Calibration, obs: Observations) -> dict[str, Any]:
    """File name → content (str for text, anything else as JSON) of every
    product of one calibration."""
    corners = corner_residuals(cal, obs)
    views = with_flags(view_residuals(cal, corners), view_flags(cal, obs))
    files: dict[str, Any] = {
        "calibration.json": cal.to_json(),
        "corner_residuals.json": corners,
        "corner_residuals.csv": to_csv(corners),
        "view_residuals.json": views,
        "view_residuals.csv": to_csv(views),
        "heatmap.json": heatmap(corners, cal.image_size),
        "distortion_field.json": distortion_field(cal),
    }
    knots = knot_grid(cal)
    if knots is not None:
        files["knots.json"] = knots
    yaml = opencv_yaml(cal)
    if yaml is not None:
        files["opencv.yaml"] = yaml
    row = {"method": cal.method, **{k: v for k, v in cal.metrics.items() if _scalar(v)},
           "seconds": cal.diagnostics.get("solver", {}).get("seconds")}
    files["comparison.json"] = {"rows": [row]}
    files["comparison.csv"] = to_csv([row])
    return files


def corner_residuals(cal: Calibration, obs: Observations) -> list[dict[str, Any]]:
    """One row per observed corner of every used view: observed − projected, pixels."""
    rows: list[dict[str, Any]] = []
    known = {v.name for v in obs.views}
    for v in cal.views:
        if v.name not in known:
            continue
        ov = obs.view(v.name)
        d = ov.image_points - cal.project(ov.object_points, v.rvec, v.tvec)
        table = {
            "index": np.arange(len(ov)),
            "id": ov.ids if ov.ids is not None else np.arange(len(ov)),
            "x": ov.image_points[:, 0], "y": ov.image_points[:, 1],
            "dx": d[:, 0], "dy": d[:, 1], "error": np.hypot(d[:, 0], d[:, 1]),
            "outlier": np.isin(np.arange(len(ov)), v.outliers),
        }
        columns = {k: json_safe(np.asarray(a)) for k, a in table.items()}
        rows += [{"view": v.name, **dict(zip(columns, values, strict=True))}
                 for values in zip(*columns.values(), strict=True)]
    return rows


def view_residuals(cal: Calibration, corners: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per used view: its rmse, worst inlier and outlier count."""
    worst: dict[str, float] = {}
    for c in corners:
        if not c["outlier"] and c["error"] is not None:
            worst[c["view"]] = max(worst.get(c["view"], 0.0), c["error"])
    return [{"view": v.name, "n_points": v.n_points, "rmse": json_safe(v.rmse), "rmse_axis": json_safe(v.rmse_axis),
             "max_error": worst.get(v.name), "outliers": len(v.outliers)} for v in cal.views]


def with_flags(views: list[dict[str, Any]], flags: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The per-view rows with their curation figures (``evaluation.view_flags``): corners detected and kept,
    the flags in words, and ``flagged`` (their codes, for the CSV)."""
    by_name = {f["view"]: f for f in flags}
    keys = ("n_detected", "n_kept", "outlier_share", "rmse_z", "structure", "structure_rms", "structure_z", "flags")
    out = []
    for row in views:
        f = by_name.get(row["view"], {})
        extra = {k: json_safe(f.get(k)) if k != "flags" else f.get(k, []) for k in keys}
        out.append({**row, **extra, "flagged": " ".join(x["code"] for x in extra["flags"])})
    return out


def _inliers(corners: list[dict[str, Any]]) -> np.ndarray:
    """(N, 5) x, y, dx, dy, error of the inlier corners with a finite error."""
    rows = [(c["x"], c["y"], c["dx"], c["dy"], c["error"]) for c in corners
            if not c["outlier"] and c["error"] is not None]
    return np.asarray(rows, dtype=float).reshape(-1, 5)


def heatmap(corners: list[dict[str, Any]], image_size: tuple[int, int]) -> dict[str, Any]:
    """Mean per-point error (Euclidean, pixels) of inliers in a grid of image cells."""
    nx, ny = HEATMAP_CELLS
    w, h = image_size
    a = _inliers(corners)
    total, _, _ = np.histogram2d(a[:, 1], a[:, 0], bins=[ny, nx], range=[[0, h], [0, w]], weights=a[:, 4])
    count, _, _ = np.histogram2d(a[:, 1], a[:, 0], bins=[ny, nx], range=[[0, h], [0, w]])
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return {"cells": [nx, ny], "image_size": list(image_size), "metric": "mean per-point error [px]",
            "mean_error": json_safe(mean), "count": count.astype(int).tolist()}


def distortion_field(cal: Calibration) -> dict[str, Any]:
    """Samples of observed pixel → its offset from the ideal pinhole pixel (observed − ideal)."""
    w, h = cal.image_size
    nu, nv = FIELD_SAMPLES
    u, v = np.meshgrid(np.linspace(0, w - 1, nu), np.linspace(0, h - 1, nv))
    uv = np.column_stack([u.ravel(), v.ravel()])
    d = uv - cal.undistort_points(uv)
    return {"grid": [nu, nv], "image_size": [w, h], "u": json_safe(uv[:, 0]), "v": json_safe(uv[:, 1]),
            "dx": json_safe(d[:, 0]), "dy": json_safe(d[:, 1]),
            "note": "observed pixel minus its ideal pinhole pixel; null where the ray is 90 degrees or more off axis"}


def knot_grid(cal: Calibration) -> dict[str, Any] | None:
    """The B-spline field's knots and interval breaks, or None for a model without one."""
    field, breaks = cal.model.bspline_field, cal.model.knot_breaks()
    if field is None or breaks is None:
        return None
    doc = field.to_json()
    return {"type": cal.model.kind, "degree": doc["degree"], "knots_u": doc["knots_u"], "knots_v": doc["knots_v"],
            "breaks_u": breaks[0].tolist(), "breaks_v": breaks[1].tolist(),
            "coordinates": "ideal pixels" if cal.model.kind == "bspline" else "pixels of the parametric core"}


def knot_cells(cal: Calibration, corners: list[dict[str, Any]]) -> dict[str, Any] | None:
    """The paper's Figure 11: the knot grid with the number of inlier corners
    in each knot cell (rows along v, columns along u), None without knots.
    Knots live in ideal pixels (``bspline``) or in the parametric core's
    pixels (``hybrid``, close to observed pixels), so the corners are mapped
    there before counting."""
    grid = knot_grid(cal)
    if grid is None:
        return None
    observed = _inliers(corners)[:, :2]
    if grid["type"] == "bspline":
        with np.errstate(all="ignore"):
            pos = cal.undistort_points(observed)
        where = "ideal pixels"
    else:
        pos, where = observed, "observed pixels (the hybrid field's knots are in the core's pixels, close to these)"
    bu, bv = np.asarray(grid["breaks_u"], float), np.asarray(grid["breaks_v"], float)
    ok = np.all(np.isfinite(pos), axis=1)
    counts, _, _ = np.histogram2d(pos[ok, 1], pos[ok, 0], bins=[bv, bu])
    return {"breaks_u": bu.tolist(), "breaks_v": bv.tolist(), "counts": counts.astype(int).tolist(),
            "positions": where, "corners": np.round(pos[ok], 2).tolist(), "type": grid["type"]}


def uncertainty_map(cal: Calibration, obs: Observations, step: float = UNCERTAINTY_STEP) -> dict[str, Any]:
    """Projection uncertainty over a pixel grid (``evaluation.uncertainty``,
    boards frame), from the calibration's own views and inliers; σ is
    estimated from their residuals."""
    from ..evaluation.uncertainty import projection_uncertainty
    from ..pipeline import to_data

    data, names, local = to_data(obs.select([v.name for v in cal.views]))
    outliers = {(n, i) for n in names for i in cal.view(n).outliers}
    if outliers:
        keep = np.array([(names[k], int(i)) not in outliers for k, i in zip(data.view_index, local, strict=True)])
        data = data.points(keep)
    poses = np.array([cal.view(n).pose for n in names])
    um = projection_uncertainty(cal.model, poses, data, cal.image_size, step=step)
    doc = um.to_json()
    doc.update(covered=um.covered.tolist(), image_size=list(cal.image_size), step=step,
               note="standard deviation of the projection of a fixed direction if the corners were measured "
                    "again with the same noise; 'covered': an observed corner within reach")
    return doc


def to_csv(rows: list[dict[str, Any]]) -> str:
    """Rows as CSV: every scalar column any row has, in order of appearance."""
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols and _scalar(r[k])]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in cols})
    return buf.getvalue()


def _scalar(v: Any) -> bool:
    return v is None or isinstance(v, (str, int, float, bool, np.integer, np.floating))
