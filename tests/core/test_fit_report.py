"""A calibration's metrics and diagnostics as typed objects (``calib_core/fit_report.py``):
a file as earlier versions wrote it reads into them and writes back the same JSON,
and a malformed one is a FormatError naming the field."""
from __future__ import annotations

import copy
import json
import math

import pytest

from calib_core import Calibration, FormatError
from calib_core.fit_report import ChoiceReport, Diagnostics, ExcludedPoints, FitMetrics, Restart, SolverReport

CHOICE = {
    "chosen": "zhang", "summary": "OpenCV 5-coefficient model: it predicts the views left out of its fit best",
    "rule": "the simplest candidate within one standard error", "how": "error per axis on each of the 10 views",
    "n_views": 10, "n_points": 540,
    "candidates": [
        {"name": "zhang", "label": "OpenCV 5-coefficient model", "chosen": True, "validation_rmse": 0.2976,
         "validation_mse": 0.1771, "standard_error_rmse": 0.0, "within_noise": True, "n_params": 9},
        {"name": "bspline", "label": "B-spline field (the paper's model)", "chosen": False, "validation_rmse": None,
         "validation_mse": None, "standard_error_rmse": None, "within_noise": None, "n_params": None,
         "error": "57 corners give 114 equations for 300 unknowns"}]}

# Every part of the format's metrics and diagnostics, in the order and shape the
# pipeline, the CLI and the service write them (as of freecal.calibration/1).
OLD_FILE = {
    "format": "freecal.calibration/1", "image_size": [640, 480], "model": "auto", "base": "pinhole",
    "intrinsics": {"fx": 500.0, "fy": 501.0, "cx": 319.5, "cy": 239.5, "skew": 0.0},
    "distortion": {"type": "opencv", "coefficients": [-0.1, 0.02, 0.0, 0.0, 0.0]},
    "views": [{"name": "a.png", "rvec": [0.1, -0.2, 0.0], "tvec": [10.0, 5.0, 900.0], "rmse": 0.21,
               "rmse_axis": 0.15, "n_points": 54, "outliers": [3]}],
    "dropped_views": [{"name": "b.png", "reason": "board not found"}],
    "metrics": {"rmse": 0.24, "rmse_axis": 0.17, "rmse_center": None, "rmse_edge": 0.25, "n_points": 54},
    "settings": {"method": "auto", "outlier_sigma": 5.0, "chosen": "zhang", "decision_views": 20},
    "diagnostics": {
        "design": {"rank": 49, "n_controls": 49}, "initialisation": {"focal_source": "homographies", "rmse": 1.5},
        "smoothing_curve": [{"intervals": [6, 6], "bandwidth_factor": 1.0, "skipped": "too few corners"}],
        "restart": {"reason": "its focal length is 27 % from the parametric camera's",
                    "first": {"rmse": 17.1, "fx": 224.0, "fy": 224.5, "iterations": 40},
                    "restarted": {"rmse": 0.04, "fx": 305.1, "fy": 305.2, "iterations": 12}, "kept": "restarted",
                    "warning": "the field cannot follow this lens: use method auto"},
        "model_choice": CHOICE,
        "solver": {"iterations": 7, "status": "converged", "message": "relative cost change below ftol",
                   "cost": 3.1, "n_unknowns": 15, "seconds": 0.25},
        "coverage_hull": [[64.58, 58.58], [600.12, 58.58], [600.12, 420.05]],
        "excluded_points": {"outliers": 1, "outside_model": 2, "outside_model_reason": "more than 85° off axis"},
        "camera": {"model": "OpenCV model, 5 coefficients", "parameters": [{"name": "fx", "value": 500.0}]},
        "excluded_views": ["c.png"]},
    "provenance": {"freecal_version": "0.1.0", "tvec_units": "mm"},
}


def test_an_earlier_file_reads_into_typed_parts_and_writes_back_the_same_json():
    cal = Calibration.from_json(copy.deepcopy(OLD_FILE))
    assert json.dumps(cal.to_json(), indent=1) == json.dumps(OLD_FILE, indent=1)
    m = cal.metrics
    assert isinstance(m, FitMetrics) and (m.rmse, m.rmse_edge, m.n_points) == (0.24, 0.25, 54)
    assert math.isnan(m.rmse_center)  # null: no corner in the image's central half
    d = cal.diagnostics
    assert isinstance(d.solver, SolverReport) and d.solver.iterations == 7 and d.solver.status == "converged"
    assert d.excluded_points == ExcludedPoints(1, 2, "more than 85° off axis")
    assert isinstance(d.restart, Restart) and d.restart.kept == "restarted" and d.restart.restarted.fx == 305.1
    assert isinstance(d.model_choice, ChoiceReport) and d.model_choice.chosen_candidate.name == "zhang"
    assert d.model_choice.candidates[1].error.startswith("57 corners")
    assert d.coverage_hull == OLD_FILE["diagnostics"]["coverage_hull"] and d.excluded_views == ["c.png"]
    assert d.camera == OLD_FILE["diagnostics"]["camera"]
    assert list(d.extra) == ["design", "initialisation", "smoothing_curve"]  # the method's own records, as read


def test_a_model_alone_writes_empty_metrics_and_diagnostics():
    doc = copy.deepcopy(OLD_FILE)
    doc["metrics"], doc["diagnostics"] = {}, {}
    cal = Calibration.from_json(doc)
    assert cal.metrics is None and cal.diagnostics == Diagnostics()
    assert cal.to_json() == doc


@pytest.mark.parametrize("metrics, message", [
    ([1], "metrics: expected an object"),
    ({"rmse": 0.2, "rmse_axis": 0.1, "rmse_center": 0.2, "n_points": 5}, "metrics: missing 'rmse_edge'"),
    ({"rmse": "0.2", "rmse_axis": 0.1, "rmse_center": 0.2, "rmse_edge": 0.2, "n_points": 5},
     r"metrics\.rmse: expected a number or null"),
    ({"rmse": 0.2, "rmse_axis": 0.1, "rmse_center": 0.2, "rmse_edge": 0.2, "n_points": -1},
     r"metrics\.n_points: expected a whole number"),
    ({"rmse": 0.2, "rmse_axis": 0.1, "rmse_center": 0.2, "rmse_edge": 0.2, "n_points": True},
     r"metrics\.n_points: expected a whole number"),
])
def test_malformed_metrics_are_a_format_error_naming_the_field(metrics, message):
    doc = copy.deepcopy(OLD_FILE)
    doc["metrics"] = metrics
    with pytest.raises(FormatError, match=message):
        Calibration.from_json(doc)


@pytest.mark.parametrize("key, value, message", [
    ("solver", {"status": "converged", "n_unknowns": 15}, r"diagnostics\.solver: missing 'iterations'"),
    ("excluded_points", {"outliers": "1", "outside_model": 0}, r"diagnostics\.excluded_points\.outliers"),
    ("restart", {"reason": "x", "kept": "first", "first": {}, "restarted": {}}, r"diagnostics\.restart\.first"),
    ("model_choice", {**CHOICE, "candidates": [{**c, "chosen": True} for c in CHOICE["candidates"]]},
     "exactly one chosen candidate"),
    ("coverage_hull", [[1.0, 2.0, 3.0]], r"diagnostics\.coverage_hull"),
    ("camera", [], r"diagnostics\.camera: expected an object"),
])
def test_malformed_diagnostics_are_a_format_error_naming_the_part(key, value, message):
    doc = copy.deepcopy(OLD_FILE)
    doc["diagnostics"][key] = value
    with pytest.raises(FormatError, match=message):
        Calibration.from_json(doc)
