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
from ..errors import DataError
from ..evaluation.view_flags import view_flags
from ..exports import opencv_yaml
from ..models.base import fitted_parameter_count
from ..observations import Observations
from .distortion import distortion_maps

HEATMAP_CELLS = (16, 12)   # columns, rows over the image
FIELD_SAMPLES = (33, 25)   # distortion field sample grid (u, v)
UNCERTAINTY_STEP = 32.0    # px between the uncertainty map's samples


def report_files(cal: Calibration, obs: Observations) -> dict[str, Any]:
    """File name → content (str for text, anything else as JSON) of every
    product of one calibration."""
    if cal.diagnostics.camera is None:  # the parameters' table the page leads with, in the calibration itself
        cal.diagnostics.camera = camera(cal, obs)
    corners = corner_residuals(cal, obs)
    files = calibration_files(cal, with_flags(view_residuals(cal, corners), view_flags(cal, obs)))
    files["corner_residuals.json"] = corners
    files["corner_residuals.csv"] = to_csv(corners)
    files["heatmap.json"] = heatmap(corners, cal.image_size)
    return files


def calibration_files(cal: Calibration, views: list[dict[str, Any]]) -> dict[str, Any]:
    """The products the calibration alone gives (``views``: its per-view rows)."""
    files: dict[str, Any] = {
        "calibration.json": cal.to_json(),
        "view_residuals.json": views,
        "view_residuals.csv": to_csv(views),
        "distortion_field.json": distortion_field(cal),
    }
    knots = knot_grid(cal)
    if knots is not None:
        files["knots.json"] = knots
    yaml = opencv_yaml(cal)
    if yaml is not None:
        files["opencv.yaml"] = yaml
    solver = cal.diagnostics.solver
    row = {"method": cal.method, **({} if cal.metrics is None else cal.metrics.to_json()),
           "n_params": fitted_parameter_count(cal.model), "seconds": None if solver is None else solver.seconds}
    files["comparison.json"] = {"rows": [row]}
    files["comparison.csv"] = to_csv([row])
    return files


def report_products(cal: Calibration, obs: Observations | None = None) -> dict[str, Any]:
    """Everything the report shows (``freecal calibrate --report``, ``freecal report``):
    ``report_files``, the products the service computes on request (knot cells, the
    uncertainty map), the parameters with their standard deviations and the coverage
    of the image. Without ``obs`` (the corners), only what the calibration alone gives."""
    from ..evaluation.parameters import describe_without_corners

    if obs is None:
        products = calibration_files(cal, view_residuals(cal, []))
        products["parameters.json"] = describe_without_corners(cal)
    else:
        obs = fitted_corners(cal, obs)
        products = report_files(cal, obs)
        products["knot_cells.json"] = knot_cells(cal, products["corner_residuals.json"])
        products["uncertainty.json"] = uncertainty_map(cal, obs)
        products["coverage.json"] = coverage_of(obs)
        products["parameters.json"] = cal.diagnostics.camera
    return {name: content for name, content in products.items() if content is not None}


def fitted_corners(cal: Calibration, obs: Observations) -> Observations:
    """The views of ``obs`` the calibration was fitted to; a DataError if ``obs`` is not where it came from."""
    if tuple(obs.image_size) != tuple(cal.image_size):
        raise DataError(f"the observations are of a {obs.image_size[0]} x {obs.image_size[1]} image, the calibration "
                        f"of a {cal.image_size[0]} x {cal.image_size[1]} one: give the observations it was fitted to")
    have = {v.name for v in obs.views}
    missing = [v.name for v in cal.views if v.name not in have]
    if missing:
        raise DataError(f"the observations lack {len(missing)} of the calibration's {len(cal.views)} views "
                        f"(e.g. {missing[0]!r}): give the observations it was fitted to")
    # A view the calibration was fitted to with no corners here leaves its pose free: its covariance is singular.
    empty = [v.name for v in cal.views if not len(obs.view(v.name))]
    if empty:
        raise DataError(f"the observations hold no corners in {len(empty)} of the calibration's {len(cal.views)} "
                        f"views (e.g. {empty[0]!r}): give the observations it was fitted to")
    return obs.select([v.name for v in cal.views])


def coverage_of(obs: Observations) -> dict[str, Any]:
    """Where the corners fall in the image (``evaluation.coverage``), with the image size;
    inside the image circle the detection recorded, if the photos have one."""
    from ..evaluation.coverage import coverage

    points = np.concatenate([v.image_points for v in obs.views]) if obs.views else np.zeros((0, 2))
    circle = obs.image_circle
    return {**coverage(points, obs.image_size, circle=circle), "image_size": list(obs.image_size), "n_points": int(len(points))}


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
    """The distortion maps over the image (``distortion.distortion_maps``: against
    the pinhole, the field's own part, the lens as angles; ``default`` the one
    that reads on this lens), with the pinhole map's Δx, Δy also at the top
    level (observed − ideal pinhole pixel), as earlier readers take them."""
    doc = distortion_maps(cal, FIELD_SAMPLES)
    pinhole = doc["maps"]["pinhole"]
    doc.update(dx=pinhole["dx"], dy=pinhole["dy"],
               note="observed pixel minus its ideal pinhole pixel; null where the ray is 90 degrees or more off "
                    "axis; 'maps' holds every view of the lens, 'default' the one that reads on it")
    return doc


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


def camera(cal: Calibration, obs: Observations) -> dict[str, Any]:
    """The calibration's ``diagnostics.camera``: the model in words, every
    parameter ± one standard deviation, the field of view and the verdict
    (``evaluation.parameters``), from the corners it was fitted to."""
    from ..evaluation.parameters import describe_camera
    from ..evaluation.uncertainty import inlier_data

    data, poses = inlier_data(cal, obs)
    return describe_camera(cal, data, poses)


def uncertainty_map(cal: Calibration, obs: Observations, step: float = UNCERTAINTY_STEP) -> dict[str, Any]:
    """Projection uncertainty over a pixel grid (``evaluation.uncertainty``,
    boards frame), from the calibration's own views and inliers; σ is
    estimated from their residuals."""
    from ..evaluation.uncertainty import inlier_data, projection_uncertainty

    data, poses = inlier_data(cal, obs)
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
