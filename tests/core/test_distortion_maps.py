"""The distortion maps (``report/distortion.py``): each view of the lens and the one that reads on it."""
import numpy as np
import pytest

from calib_core import Calibration
from calib_core.models import FisheyeModel, HybridModel, OpenCVModel
from calib_core.models.bspline_basis import BSplineField, clamped_knots
from calib_core.report.distortion import distortion_maps
from calib_core.report.figures import distortion_field as distortion_png
from calib_core.report.tables import distortion_field

W, H = 1000, 750
CENTRE = [(W - 1) / 2, (H - 1) / 2]


def values(m, key):
    return np.array([np.nan if x is None else x for x in m[key]], float)


def test_a_wide_lens_reads_as_angles_and_stays_finite_where_the_pinhole_map_explodes():
    # Kannala-Brandt close to the GoPro's (fx 437 px on 1000 × 750): ~150° across the diagonal
    cal = Calibration(FisheyeModel([437.0, 437.0, *CENTRE, 0.0], [0.04, 0.037, -0.029, 0.007]), (W, H), "fisheye")
    doc = distortion_maps(cal, (21, 15))
    assert doc["wide"] and doc["default"] == "angle" and doc["max_angle_deg"] > 70
    angle, pinhole = doc["maps"]["angle"], doc["maps"]["pinhole"]
    dtheta = values(angle, "dtheta")
    assert np.all(np.isfinite(dtheta)) and angle["unit"] == "°"
    # a few degrees against the equidistant lens, where the pinhole view needs hundreds of pixels
    assert 0.5 < angle["scale"] < 10 and pinhole["scale"] > 200
    assert abs(dtheta[len(dtheta) // 2]) < 1e-6  # the centre pixel is on the axis: θ = r/f = 0
    assert "field" not in doc["maps"]


def test_the_equidistant_lens_is_zero_against_itself():
    cal = Calibration(FisheyeModel([300.0, 300.0, *CENTRE, 0.0], [0.0, 0.0, 0.0, 0.0]), (W, H), "fisheye")
    angle = distortion_maps(cal, (11, 9))["maps"]["angle"]
    assert np.allclose(values(angle, "dtheta"), 0.0, atol=1e-6)
    assert values(angle, "theta").max() > 90  # past the pinhole's reach, still a number


def test_a_field_over_a_core_shows_its_own_part():
    core = OpenCVModel([500.0, 500.0, *CENTRE, 0.0], [-0.2, 0.05, 0.0, 0.0, 0.0])
    knots = clamped_knots(np.linspace(-50, W + 50, 5)), clamped_knots(np.linspace(-50, H + 50, 4))
    field = BSplineField.zeros(*knots)
    field = field.with_control(np.tile([1.5, -0.5], (field.n_u, field.n_v, 1)))  # a constant offset (1.5, −0.5) px
    cal = Calibration(HybridModel(core, field), (W, H), "bspline")
    doc = distortion_field(cal)
    assert doc["default"] == "field"
    own = doc["maps"]["field"]
    assert np.allclose(values(own, "dx"), 1.5, atol=1e-6) and np.allclose(values(own, "dy"), -0.5, atol=1e-6)
    assert own["scale"] == pytest.approx(1.5)
    # the pinhole view is still there, and is what earlier readers find at the top level
    assert np.allclose(values(doc, "dx"), values(doc["maps"]["pinhole"], "dx"), equal_nan=True)
    assert distortion_png(doc)[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_narrow_lens_keeps_the_pinhole_view():
    cal = Calibration(OpenCVModel([900.0, 900.0, *CENTRE, 0.0], [-0.1, 0.02, 0.0, 0.0, 0.0]), (W, H), "zhang")
    doc = distortion_maps(cal, (11, 9))
    assert not doc["wide"] and doc["default"] == "pinhole"
    dx = values(doc["maps"]["pinhole"], "dx")
    uv = np.column_stack([values(doc, "u"), values(doc, "v")])
    assert np.allclose(dx, (uv - cal.undistort_points(uv))[:, 0], atol=1e-6)
