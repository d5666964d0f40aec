"""The projection-uncertainty sidecar: beside any export, the calibration's
uncertainty map and, at the same pixels, what the export adds (checked with
the consumer's own projection)."""
from __future__ import annotations

import functools
import json

import numpy as np

from backend.cli import main as cli
from calib_core.pipeline import calibrate
from calib_core.report.tables import uncertainty_map

from ..conftest import synthetic
from . import consumers


@functools.cache
def radial_zhang():
    return calibrate(synthetic("radial").train, "zhang")


def test_the_sidecar_holds_the_uncertainty_map_and_the_exports_own_error(tmp_path, capsys):
    cal, obs = radial_zhang(), synthetic("radial").train
    cal.save(tmp_path / "cal.json")
    obs.save(tmp_path / "obs.json")
    out = tmp_path / "cameras.txt"
    assert cli(["export", str(tmp_path / "cal.json"), "--to", "colmap", "--model", "opencv4", "-o", str(out),
                "--observations", str(tmp_path / "obs.json"), "--uncertainty"]) == 0
    assert f"{out}.uncertainty.json" in capsys.readouterr().out
    doc = json.loads((tmp_path / "cameras.txt.uncertainty.json").read_text())
    assert doc["format"] == "freecal.export-uncertainty/1"
    assert doc["export"]["target"] == "colmap" and doc["export"]["consumer_model"] == "OPENCV"
    want = uncertainty_map(cal, obs)
    assert doc["u"] == want["u"] and doc["v"] == want["v"] and doc["std_worst"] == want["std_worst"]
    std = np.array(doc["std_worst"])
    assert (std[np.array(doc["covered"])] > 0).all()
    # the export's error at the map's pixels, as COLMAP projects their rays
    uu, vv = np.meshgrid(doc["u"], doc["v"])
    pixels = np.column_stack([uu.ravel(), vv.ravel()])
    camera = consumers.colmap_cameras(out.read_text())[1]
    err = np.linalg.norm(consumers.colmap_project(camera, cal.rays(pixels)) - pixels, axis=1)
    got = np.array(doc["export_error_px"]).ravel()
    known = got >= 0
    assert known.mean() > 0.9 and np.abs(got[known] - err[known]).max() < 1e-6 and got[known].max() > 0


def test_the_sidecar_needs_the_corners(tmp_path, capsys):
    radial_zhang().save(tmp_path / "cal.json")
    assert cli(["export", str(tmp_path / "cal.json"), "--to", "mrcal", "-o", str(tmp_path / "m"), "--uncertainty"]) == 2
    assert "--uncertainty needs --observations" in capsys.readouterr().err


def test_json_reports_the_choice_and_both_errors(tmp_path, capsys):
    radial_zhang().save(tmp_path / "cal.json")
    assert cli(["export", str(tmp_path / "cal.json"), "--to", "kalibr", "-o", str(tmp_path / "camchain.yaml"),
                "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["format"] == "kalibr" and doc["exact"] is False and doc["consumer_model"] in ("radtan", "equidistant")
    assert {c["model"] for c in doc["candidates"]} == {"opencv4", "kb4"}
    assert doc["fit_error"]["covered"]["n_samples"] > 100 and doc["fit_error"]["image"]["max_px"] >= 0
