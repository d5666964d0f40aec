"""``freecal calibrate --report`` writes the products the results page shows,
from the same calib_core functions the service stores them with."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from backend.cli import main as cli
from calib_core import calibrate
from calib_core.report import tables

from ..conftest import synthetic


@pytest.mark.slow
def test_the_report_holds_the_pages_products_and_their_figures(tmp_path):
    s = synthetic("decentred")
    obs_path = tmp_path / "train.json"
    s.train.save(obs_path)
    folder = tmp_path / "report" / "nested"
    assert cli(["calibrate", str(obs_path), "--method", "bspline", "--intervals", "6", "-q",
                "--report", str(folder)]) == 0
    for name in ("calibration.json", "corner_residuals.json", "corner_residuals.csv", "view_residuals.json",
                 "heatmap.json", "distortion_field.json", "knots.json", "knot_cells.json", "uncertainty.json"):
        assert json.loads((folder / name).read_text()) if name.endswith(".json") else (folder / name).read_text()
    for name in ("residual_heatmap.png", "residual_vectors.png", "view_errors.png", "distortion_field.png",
                 "knot_grid.png", "distortion_maps.png", "uncertainty.png", "coverage.png"):
        image = cv2.imread(str(folder / name))
        assert image is not None and min(image.shape[:2]) > 200, name
    corners = json.loads((folder / "corner_residuals.json").read_text())
    assert len(corners) == s.train.n_points
    cells = json.loads((folder / "knot_cells.json").read_text())
    assert np.array(cells["counts"]).shape == (6, 6)
    inliers = sum(not c["outlier"] for c in corners)
    assert 0.95 * inliers <= np.sum(cells["counts"]) <= inliers
    page = (folder / "report.html").read_text()  # the page freecal report writes, figures inside
    assert page.count("data:image/png;base64,") == 8 and "id='parameters-table'" in page
    params = json.loads((folder / "parameters.json").read_text())
    assert [r["name"] for r in params["parameters"]] == ["fx", "fy", "cx", "cy", "skew"]
    assert params["field"]["knot_intervals"] == [6, 6] and params["parameters"][0]["std"] > 0
    assert json.loads((folder / "coverage.json").read_text())["n_points"] == s.train.n_points


def test_corner_residuals_are_observed_minus_projected_for_every_corner():
    s = synthetic("radial")
    cal = calibrate(s.train, "zhang")
    rows = tables.corner_residuals(cal, s.train)
    view = s.train.views[3]
    mine = [r for r in rows if r["view"] == view.name]
    v = cal.view(view.name)
    expected = view.image_points - cal.project(view.object_points, v.rvec, v.tvec)
    assert [r["index"] for r in mine] == list(range(len(view)))
    assert np.allclose([[r["dx"], r["dy"]] for r in mine], expected, atol=1e-12)
    assert all(r["outlier"] == (r["index"] in v.outliers) for r in mine)
    heat = tables.heatmap(rows, cal.image_size)
    assert sum(map(sum, heat["count"])) == sum(not r["outlier"] for r in rows)


def test_a_model_without_a_field_has_no_knot_products():
    s = synthetic("radial")
    cal = calibrate(s.train, "zhang")
    files = tables.report_files(cal, s.train)
    assert "knots.json" not in files and tables.knot_cells(cal, files["corner_residuals.json"]) is None
    assert "opencv.yaml" in files


def test_a_report_of_other_corners_is_refused_in_one_line(tmp_path, capsys):
    """freecal report CAL.json OBS.json with corners the calibration was not fitted to."""
    cal = calibrate(synthetic("radial").train, "zhang")
    cal.save(tmp_path / "cal.json")
    synthetic("radial").holdout.save(tmp_path / "holdout.json")
    assert cli(["report", str(tmp_path / "cal.json"), str(tmp_path / "holdout.json"), "-o",
                str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "give the observations it was fitted to" in err
    assert not (tmp_path / "r.html").exists()
