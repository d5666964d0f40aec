"""Figures the page asks for once a job is done, computed from its stored
files by the same functions as the CLI's report (``calib_core.report``)."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from calib_core import Calibration, Observations
from calib_core.evaluation.diff import projection_diff as diff_of
from calib_core.report import tables


def _calibration(job_dir: Path) -> Calibration:
    return Calibration.from_json(json.loads((job_dir / "calibration.json").read_text()))


def knot_cells(job_dir: Path) -> dict[str, Any] | None:
    """The knot grid with the corners per knot cell; None without knots."""
    if not (job_dir / "knots.json").exists():
        return None
    corners = json.loads((job_dir / "corner_residuals.json").read_text())
    return tables.knot_cells(_calibration(job_dir), corners)


def uncertainty(job_dir: Path, observations: Path) -> dict[str, Any] | None:
    """The projection uncertainty map; None when the corners are gone."""
    if not observations.exists():
        return None
    return tables.uncertainty_map(_calibration(job_dir), Observations.load(observations))


def projection_diff(job_dir: Path, other_dir: Path, grid: int, fit_region: str) -> dict[str, Any]:
    """How far the other job's calibration puts each direction from where this job's does
    (``freecal diff``'s map and summary)."""
    return diff_of(_calibration(job_dir), _calibration(other_dir), grid, fit_region).to_json()
