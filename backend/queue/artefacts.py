"""The result files of a finished job, computed once by the worker and stored.

Every file is derived from the calibration and the observations it was fitted
to (``calib_core.report``), so results survive restarts and reads
cost nothing. Names here are the download names of ``/api/jobs/{id}/{name}``.
"""
from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from calib_core import Calibration, Observations
from calib_core.calibration import json_safe
from calib_core.errors import CalibError
from calib_core.evaluation.compare import Comparison
from calib_core.observations import json_text
from calib_core.report.tables import report_files, to_csv
from calib_core.rig import Rig

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


# a rig's files: freecal.rig/1, then `freecal export RIG.json --to kalibr|opencv`'s output
RIG_FILE = storage.RIG_FILE
RIG_EXPORTS = {"camchain.yaml": "kalibr", "stereo.yaml": "opencv"}


def write_rig(out: Path, rig: Rig, progress: Callable[[str, float], None]) -> tuple[list[str], dict[str, str]]:
    """rig.json and its exports; returns the names written and, per export that could not be made, why.
    Each export is made from rig.json read back, as `freecal export rig.json` makes it."""
    from calib_core.exports.rig import export_rig

    text = json_text(json_safe(rig.to_json()))  # as `freecal rig -o` writes it
    _write(out, {RIG_FILE: text})
    written, unavailable = [RIG_FILE], {}
    saved = Rig.from_json(json.loads(text))
    for k, (name, to) in enumerate(RIG_EXPORTS.items()):
        progress(f"export: {to}", k / len(RIG_EXPORTS))
        if to == "opencv" and len(saved.cameras) != 2:
            unavailable[name] = (f"OpenCV's stereo file holds two cameras and this rig has {len(saved.cameras)}; "
                                 "download camchain.yaml (Kalibr: every camera in one file)")
            continue
        try:
            written += _write(out, {name: export_rig(saved, to).text})
        except CalibError as exc:  # a model the tool cannot take: the rig itself is fine, say why this file is not
            unavailable[name] = f"the {to} export failed: {exc}"
    return sorted(written), unavailable


def rig_summary(rig: Rig, unavailable: dict[str, str]) -> dict[str, Any]:
    """What the jobs list shows of a rig: each camera's place (its optical centre in the reference camera's frame,
    in the board's units, and its rotation from it), error in the rig (and alone), the rig's, the frames used."""
    report = rig.diagnostics["cameras"]
    cameras = [{"name": c.name, "model": c.calibration.settings.get("chosen", c.calibration.method),
                "centre": c.centre.tolist(), "distance": float(np.linalg.norm(c.centre)),
                "rotation_deg": c.rotation_deg,
                "rmse": report[c.name]["rmse_in_rig"], "rmse_alone": report[c.name]["rmse_alone"],
                "n_frames": report[c.name]["n_frames"]} for c in rig.cameras]
    units = rig.cameras[0].calibration.provenance.get("tvec_units")
    return json_safe({"reference": rig.reference, "units": units, "cameras": cameras, "metrics": rig.metrics.to_json(),
                      "n_frames": len(rig.frames), "models_refined": rig.diagnostics["solver"]["models_refined"],
                      "warnings": rig.diagnostics.get("warnings", []), "exports_unavailable": unavailable})


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
