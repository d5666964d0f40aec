"""The projection difference between two calibrations (calib_core/evaluation/diff.py,
``freecal diff``): a rotation of the camera frame is no difference, a focal change is
the difference it must be, and mrcal's own projection_diff agrees."""
from __future__ import annotations

import dataclasses
import json
import subprocess

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from backend.cli import main
from benchmarks import mrcal_bridge
from calib_core import Calibration, calibrate
from calib_core.evaluation.diff import projection_diff
from calib_core.exports import cameramodel, fit_lean
from calib_core.fit_report import Diagnostics
from calib_core.models.opencv import OpenCVModel

from ..conftest import synthetic

W, H = 1024, 1280
CENTRE = ((W - 1) / 2, (H - 1) / 2)


@dataclasses.dataclass
class Turned(Calibration):
    """The same lens behind a camera frame turned by ``turn``: B(v) = A(turnᵀ v)."""

    turn: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(3))

    def rays(self, uv):
        return super().rays(uv) @ self.turn.T

    def project(self, points, rvec=None, tvec=None):
        return super().project(np.asarray(points, dtype=np.float64) @ self.turn)


def pinhole(f: float, hull=None) -> Calibration:
    model = OpenCVModel([f, f, CENTRE[0], CENTRE[1], 0.0], np.zeros(5))
    return Calibration(model, (W, H), "zhang", diagnostics=Diagnostics(coverage_hull=hull))


def test_a_turned_camera_frame_is_no_difference():
    a = calibrate(synthetic("radial").train, "zhang")
    turn = Rotation.from_rotvec([0.004, -0.007, 0.002]).as_matrix()  # half a degree
    b = Turned(**{f.name: getattr(a, f.name) for f in dataclasses.fields(Calibration)}, turn=turn)
    d = projection_diff(a, b)
    assert d.fitted_on == "covered"
    assert np.allclose(d.rotation, turn, atol=1e-9)
    s = d.summary()
    assert s["image"]["max"] < 1e-6 and s["covered"]["max"] < 1e-6 and s["image"]["n"] == 60 * 75
    assert s["rotation_deg"] == pytest.approx(np.degrees(np.linalg.norm([0.004, -0.007, 0.002])), rel=1e-6)
    unfitted = projection_diff(a, b, fit_region="none").summary()
    assert unfitted["image"]["median"] > 5.0, "without the rotation fitted out, the turn is a difference of pixels"


def test_a_focal_change_is_the_analytic_difference():
    """B = A with the focal length 0.2 % longer: B(A⁻¹(q)) − q = 0.002 (q − c); the
    symmetric fit region leaves no rotation to fit."""
    hull = [[CENTRE[0] + x, CENTRE[1] + y] for x, y in ((-400, -500), (400, -500), (400, 500), (-400, 500))]
    a, b = pinhole(800.0, hull), pinhole(801.6, hull)
    d = projection_diff(a, b)
    q = np.stack(np.meshgrid(d.u, d.v), axis=-1)
    expected = 0.002 * (q - np.array(CENTRE))
    assert np.allclose(d.rotation, np.eye(3), atol=1e-12)
    assert np.abs(d.diff - expected).max() < 1e-9
    s = d.summary()
    assert s["image"]["max"] == pytest.approx(0.002 * np.hypot(*CENTRE), rel=1e-9)
    inside = (np.abs(q[..., 0] - CENTRE[0]) <= 400) & (np.abs(q[..., 1] - CENTRE[1]) <= 500)
    assert s["covered"]["n"] == inside.sum()
    assert s["covered"]["max"] == pytest.approx(np.hypot(*expected[inside].T).max(), rel=1e-9)
    assert s["covered"]["median"] == pytest.approx(np.median(np.hypot(*expected[inside].T)), rel=1e-9)


def test_without_coverage_hulls_the_rotation_is_fitted_at_the_centre():
    a, b = pinhole(800.0), pinhole(801.6)
    d = projection_diff(a, b)
    assert d.covered is None and d.fitted_on.startswith("centre") and "no coverage hull" in d.fitted_on
    assert d.summary()["covered"] is None


def test_two_cameras_are_refused():
    a = pinhole(800.0)
    b = Calibration(a.model, (640, 480), "zhang")
    with pytest.raises(Exception, match="different image sizes"):
        projection_diff(a, b)


@pytest.mark.slow
@pytest.mark.skipif(mrcal_bridge.interpreter() is None, reason="mrcal is not configured (scripts/ensure-mrcal.sh)")
def test_it_agrees_with_mrcal_projection_diff(tmp_path):
    """Two calibrations of OpenCV's own lens from different noise draws, written as
    LENSMODEL_OPENCV5 (exact), compared by mrcal.projection_diff with mrcal's
    defaults without uncertainties (60 samples across, rotation fitted on a central
    disc of min(W, H)/6): the same grid, and the same map to within the difference of
    the two rotation fits (mrcal: a Huber cost of squared angles; here least squares)."""
    a = calibrate(synthetic("radial").train, "zhang")
    b = calibrate(synthetic("radial", seed=1).train, "zhang")
    paths = []
    for name, cal in (("a", a), ("b", b)):
        paths.append(tmp_path / f"{name}.cameramodel")
        paths[-1].write_text(cameramodel(fit_lean(cal, "opencv5")))
    script = ("import json, sys, numpy as np, mrcal\n"
              "m = [mrcal.cameramodel(p) for p in sys.argv[1:3]]\n"
              "difflen, diff, q0, Rt = mrcal.projection_diff(m, use_uncertainties=False, gridn_width=60)\n"
              "print(json.dumps({'difflen': np.nan_to_num(difflen, nan=-1).tolist(), 'q0': q0.tolist()}))\n")
    run = subprocess.run([mrcal_bridge.interpreter(), "-c", script, *map(str, paths)], capture_output=True,
                         text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    theirs = json.loads(run.stdout)
    d = projection_diff(a, b, fit_region="centre")
    q0 = np.array(theirs["q0"])
    assert np.array_equal(q0[0, :, 0], d.u) and np.array_equal(q0[:, 0, 1], d.v)
    mrcal_len = np.array(theirs["difflen"])
    assert np.abs(mrcal_len - d.magnitude).max() < 0.05  # measured 0.021 px, on differences of up to 0.9 px
    assert d.summary()["image"]["p95"] == pytest.approx(np.percentile(mrcal_len, 95), rel=0.05)  # measured 2.4 %


@pytest.mark.slow
def test_freecal_diff_prints_the_summary_and_writes_the_map(tmp_path, capsys):
    a = calibrate(synthetic("radial").train, "zhang")
    b = calibrate(synthetic("radial", seed=1).train, "zhang")
    a.save(tmp_path / "a.json")
    b.save(tmp_path / "b.json")
    png = tmp_path / "maps" / "diff.png"
    assert main(["diff", str(tmp_path / "a.json"), str(tmp_path / "b.json"), "--map", str(png)]) == 0
    out = capsys.readouterr().out
    assert "fitted over the region both calibrations cover" in out and "covered" in out and "median [px]" in out
    image = cv2.imread(str(png))
    assert image is not None and min(image.shape[:2]) > 300
    assert main(["diff", str(tmp_path / "a.json"), str(tmp_path / "b.json"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["image"]["median"] == pytest.approx(projection_diff(a, b).summary()["image"]["median"])
    assert len(doc["magnitude"]) == len(doc["v"]) and len(doc["magnitude"][0]) == len(doc["u"])
    assert main(["diff", str(tmp_path / "a.json"), str(tmp_path / "b.json"), "--map", str(tmp_path)]) == 2
    assert "--map" in capsys.readouterr().err

