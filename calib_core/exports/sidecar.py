"""The projection-uncertainty sidecar of an export: none of the consumers'
files has a slot for it (mrcal's keeps its own solve's inputs for that, not
freecal's), so it goes beside the export as ``freecal.export-uncertainty/1``
JSON (docs/exports.md):

- ``std_worst``, ``std_rms`` (rows of ``v``, columns of ``u``, pixels): the
  calibration's projection uncertainty (``evaluation.uncertainty``: how far the
  projection of a fixed direction would move if the corners were measured
  again with the same noise), worst direction and per-axis rms;
- ``export_error_px``: at the same pixels, what the export adds by not being the
  calibration's model (0 when it is exactly that model);
- ``covered``: an observed corner within reach; -1 marks undefined values.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from ..calibration import Calibration
from .lean_fit import error_at
from .targets import Export

FORMAT = "freecal.export-uncertainty/1"


def uncertainty_sidecar(exported: Export, cal: Calibration, uncertainty: dict[str, Any],
                        export_file: str) -> dict[str, Any]:
    """The sidecar document of ``exported`` (written to ``export_file``), from the
    calibration ``cal`` and its uncertainty map (``report.tables.uncertainty_map``)."""
    u, v = np.asarray(uncertainty["u"], dtype=np.float64), np.asarray(uncertainty["v"], dtype=np.float64)
    uu, vv = np.meshgrid(u, v)
    err = error_at(exported.fit, cal, np.column_stack([uu.ravel(), vv.ravel()])).reshape(len(v), len(u))
    fit = exported.fit
    return {
        "format": FORMAT,
        "export": {"file": export_file, "target": exported.target.name, "model": fit.name,
                   "consumer_model": exported.consumer_model, "exact": fit.exact, "fitted_to": fit.fitted_to,
                   "fit_error": {"covered": fit.covered.to_json(), "image": fit.image.to_json()}},
        "image_size": list(cal.image_size),
        "u": u.tolist(), "v": v.tolist(),
        "sigma": uncertainty["sigma"], "dof": uncertainty["dof"],
        "std_worst": uncertainty["std_worst"], "std_rms": uncertainty["std_rms"],
        "covered": uncertainty["covered"],
        "export_error_px": np.where(np.isfinite(err), err, -1.0).tolist(),
        "units": "pixels; -1 where undefined",
        "note": "std_*: the calibration's projection uncertainty (a fixed direction, the corners measured again "
                "with the same noise); export_error_px: what the export adds at the same pixels",
    }
