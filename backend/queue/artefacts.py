"""The result files of a finished job, computed once by the worker and stored.

Every file is derived from the calibration and the observations it was fitted
to, so results survive restarts and reads cost nothing. Names here are the
download names of ``/api/jobs/{id}/{name}``.
"""
from __future__ import annotations

import csv
import io
import math
from pathlib import Path
from typing import Any

import numpy as np

from calib_core import Calibration, Observations
from calib_core.calibration import json_safe
from calib_core.exports import opencv_yaml

from ..app import storage

HEATMAP_CELLS = (16, 12)   # columns, rows over the image
FIELD_SAMPLES = (17, 13)   # distortion field sample grid (u, v)


def write_calibration(out: Path, cal: Calibration, obs: Observations) -> list[str]:
    """calibration.json and everything derived from it; returns the file names written."""
    files: dict[str, str | bytes | Any] = {"calibration.json": cal.to_json()}
    corners = corner_residuals(cal, obs)
    views = view_residuals(cal, corners)
    files["corner_residuals.json"] = corners
    files["corner_residuals.csv"] = to_csv(corners)
    files["view_residuals.json"] = views
    files["view_residuals.csv"] = to_csv(views)
    files["heatmap.json"] = heatmap(corners, cal.image_size)
    files["distortion_field.json"] = distortion_field(cal)
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
    return _write(out, files)


def write_comparison(out: Path, result: dict[str, Any], obs: Observations,
                     best: Calibration | None = None) -> list[str]:
    """A compare job: the comparison table, plus the winner's calibration files when there is one."""
    names: list[str] = []
    best = best or _best_calibration(result)
    if best is not None:
        names += write_calibration(out, best, obs)
    rows = comparison_rows(result)
    doc = json_safe({k: v for k, v in result.items() if not _is_calibration_map(v)})
    names += _write(out, {"comparison.json": doc, "comparison.csv": to_csv(rows)})
    return sorted(set(names))


def summary(cal: Calibration) -> dict[str, Any]:
    return json_safe({"method": cal.method, "metrics": cal.metrics, "n_views": len(cal.views),
                   "dropped_views": len(cal.dropped_views)})


def compare_summary(result: dict[str, Any]) -> dict[str, Any]:
    return json_safe({"methods": [r.get("method") for r in comparison_rows(result)],
                   "verdict": result.get("verdict", result.get("best")),
                   "verdict_detail": result.get("verdict_detail")})


# ---- derived tables ---------------------------------------------------------------
def corner_residuals(cal: Calibration, obs: Observations) -> list[dict[str, Any]]:
    """One row per observed corner of every used view: observed − projected, pixels."""
    rows: list[dict[str, Any]] = []
    for v in cal.views:
        try:
            ov = obs.view(v.name)
        except KeyError:
            continue
        proj = cal.project(ov.object_points, v.rvec, v.tvec)
        d = ov.image_points - proj
        err = np.hypot(d[:, 0], d[:, 1])
        out = set(v.outliers)
        ids = ov.ids if ov.ids is not None else np.arange(len(ov))
        for i in range(len(ov)):
            rows.append({"view": v.name, "index": i, "id": int(ids[i]),
                         "x": float(ov.image_points[i, 0]), "y": float(ov.image_points[i, 1]),
                         "dx": _num(d[i, 0]), "dy": _num(d[i, 1]), "error": _num(err[i]),
                         "outlier": i in out})
    return rows


def view_residuals(cal: Calibration, corners: list[dict[str, Any]]) -> list[dict[str, Any]]:
    worst: dict[str, float] = {}
    for c in corners:
        if not c["outlier"] and c["error"] is not None:
            worst[c["view"]] = max(worst.get(c["view"], 0.0), c["error"])
    return [{"view": v.name, "n_points": v.n_points, "rmse": _num(v.rmse), "rmse_axis": _num(v.rmse_axis),
             "max_error": worst.get(v.name), "outliers": len(v.outliers)} for v in cal.views]


def heatmap(corners: list[dict[str, Any]], image_size: tuple[int, int]) -> dict[str, Any]:
    """Mean per-point error (Euclidean, pixels) of inliers in a grid of image cells."""
    nx, ny = HEATMAP_CELLS
    w, h = image_size
    total, count = np.zeros((ny, nx)), np.zeros((ny, nx), dtype=int)
    pts = [(c["x"], c["y"], c["error"]) for c in corners if not c["outlier"] and c["error"] is not None]
    if pts:
        a = np.asarray(pts)
        ix = np.clip((a[:, 0] / w * nx).astype(int), 0, nx - 1)
        iy = np.clip((a[:, 1] / h * ny).astype(int), 0, ny - 1)
        np.add.at(total, (iy, ix), a[:, 2])
        np.add.at(count, (iy, ix), 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return {"cells": [nx, ny], "image_size": list(image_size), "metric": "mean per-point error [px]",
            "mean_error": json_safe(mean), "count": count.tolist()}


def distortion_field(cal: Calibration) -> dict[str, Any]:
    """Samples of observed pixel → its offset from the ideal pinhole pixel (observed − ideal)."""
    w, h = cal.image_size
    nu, nv = FIELD_SAMPLES
    u, v = np.meshgrid(np.linspace(0, w - 1, nu), np.linspace(0, h - 1, nv))
    uv = np.column_stack([u.ravel(), v.ravel()])
    ideal = cal.undistort_points(uv)
    d = uv - ideal
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


def comparison_rows(result: dict[str, Any]) -> list[dict[str, Any]]:
    """The comparison as flat rows, whatever shape compare() gave (list of rows or method → row)."""
    for key in ("table", "rows", "methods", "results"):
        val = result.get(key)
        if isinstance(val, list) and all(isinstance(r, dict) for r in val):
            return [_flat(r) for r in val]
        if isinstance(val, dict) and all(isinstance(r, dict) for r in val.values()):
            return [_flat({"method": name, **r}) for name, r in val.items()]
    return []


# ---- helpers ------------------------------------------------------------------------
def to_csv(rows: list[dict[str, Any]]) -> str:
    cols: list[str] = []
    for r in rows:
        cols += [k for k in r if k not in cols and _scalar(r[k])]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in cols})
    return buf.getvalue()


def _write(out: Path, files: dict[str, Any]) -> list[str]:
    for name, content in files.items():
        if isinstance(content, str):
            storage.write_text(out / name, content)
        else:
            storage.write_json(out / name, json_safe(content), indent=1 if name == "calibration.json" else None)
    return sorted(files)


def _best_calibration(result: dict[str, Any]) -> Calibration | None:
    cals = next((v for v in result.values() if _is_calibration_map(v)), None)
    if not cals:
        return None
    name = next((result[k] for k in ("verdict", "best") if result.get(k) in cals), next(iter(cals)))
    cal = cals[name]
    return cal if isinstance(cal, Calibration) else Calibration.from_json(cal)


def _is_calibration_map(v: Any) -> bool:
    return isinstance(v, dict) and bool(v) and all(
        isinstance(c, Calibration) or (isinstance(c, dict) and c.get("format") == "freecal.calibration/1")
        for c in v.values())


def _flat(row: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in row.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        elif _scalar(v):
            out[prefix + k] = json_safe(v)
    return out


def _scalar(v: Any) -> bool:
    return v is None or isinstance(v, (str, int, float, bool, np.integer, np.floating))


def _num(x: float) -> float | None:
    x = float(x)
    return x if math.isfinite(x) else None


