"""The result files of a finished job, computed once by the worker and stored.

Every file is derived from the calibration and the observations it was fitted
to (``calib_core.report``), so results survive restarts and reads
cost nothing. Names here are the download names of ``/api/jobs/{id}/{name}``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from calib_core import Calibration, Observations
from calib_core.calibration import json_safe
from calib_core.evaluation.compare import Comparison
from calib_core.report.tables import report_files, to_csv

from ..base import storage


def write_calibration(out: Path, cal: Calibration, obs: Observations) -> list[str]:
    """calibration.json and everything derived from it; returns the file names written."""
    return _write(out, report_files(cal, obs))


def write_comparison(out: Path, result: Comparison, obs: Observations,
                     best: Calibration | None = None) -> list[str]:
    """A compare job: the comparison table, plus the winner's calibration files when there is one."""
    names = write_calibration(out, best, obs) if best is not None else []
    names += _write(out, {"comparison.json": result.to_json(), "comparison.csv": to_csv(comparison_rows(result))})
    return sorted(set(names))


def summary(cal: Calibration, excluded: int = 0) -> dict[str, Any]:
    """What the jobs list and the side-by-side table of a set's calibrations show without reading files:
    the figures, the model and verdict in words, the views used and left out, and the error on views left
    out of the fit (``validation``) where the method measured one."""
    camera = cal.diagnostics.camera or {}
    return json_safe({"method": cal.method, "metrics": {} if cal.metrics is None else cal.metrics.to_json(), "n_views": len(cal.views),
                      "dropped_views": len(cal.dropped_views), "excluded_views": excluded,
                      "model": camera.get("model"), "grade": (camera.get("verdict") or {}).get("grade"),
                      **validation_of(cal)})


def validation_of(cal: Calibration) -> dict[str, Any]:
    """The model choice's chosen candidate (method auto: rmse per axis on views left out, px), or the
    B-spline's chosen knot grid (validation error, px²)."""
    choice = cal.diagnostics.model_choice
    if choice is not None and choice.chosen_candidate.validation_rmse is not None:
        return {"choice": choice.summary, "validation": {"rmse_axis": choice.chosen_candidate.validation_rmse,
                                                         "how": "views left out of the fit"}}
    curve = cal.diagnostics.extra.get("smoothing_curve") or []  # the B-spline method's own record
    used = cal.settings.get("intervals_used")
    chosen = next((c for c in curve if c.get("intervals") == used and not c.get("skipped")), None)
    if chosen and chosen.get("cv") is not None:
        return {"validation": {"mse": chosen["cv"], "how": "knot grid chosen on views left out (px²)"}}
    return {}


def compare_summary(result: Comparison) -> dict[str, Any]:
    return json_safe({"methods": list(result.methods), "verdict": result.verdict,
                      "verdict_detail": result.verdict_detail})


def comparison_rows(result: Comparison) -> list[dict[str, Any]]:
    """``compare()``'s methods as flat rows (nested figures as ``a.b`` columns)."""
    return [_flat({"method": name, **entry.to_json()}) for name, entry in result.methods.items()]


def _write(out: Path, files: dict[str, Any]) -> list[str]:
    for name, content in files.items():
        if isinstance(content, str):
            storage.write_text(out / name, content)
        else:
            storage.write_json(out / name, json_safe(content), indent=1 if name == "calibration.json" else None)
    return sorted(files)


def _flat(row: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in row.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        elif v is None or isinstance(v, (str, int, float, bool)):
            out[prefix + k] = json_safe(v)
    return out
