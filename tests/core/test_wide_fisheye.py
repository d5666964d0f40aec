"""A lens past 180° (BabelCalib's OV headset fisheye, the authors' reference
corners): calibrate on train/, validate on test/ with a pose-only refit."""
import pytest

from calib_core import calibrate
from calib_core.detection import babelcalib
from calib_core.evaluation.evaluate import evaluate

from ..conftest import shared_data


@pytest.fixture(scope="module")
def sets():
    folder = shared_data("babelcalib-ov-plane-fisheye")
    board = folder / "ov_plane.dsc"
    return babelcalib.load(folder / "train", board), babelcalib.load(folder / "test", board)


def test_reader_matches_the_published_geometry(sets):
    train, test = sets
    assert len(train.views) == 18 and len(test.views) == 7 and train.image_size == (1280, 800)
    pts = train.views[0].object_points
    assert pts[:, 2].max() == 0 and 0 < pts[:, 0].max() <= 22 * 7.5 + 1e-9


@pytest.mark.slow
def test_the_default_beats_kannala_brandt_on_held_out_views(sets):
    train, test = sets
    kb = evaluate(calibrate(train, "fisheye"), test)
    ours_cal = calibrate(train)
    ours = evaluate(ours_cal, test)
    assert ours_cal.diagnostics.excluded_points.outside_model == 0  # nothing lost past 90°
    # mrcal's splined stereographic model, same corners: 0.45 px test rms (per axis).
    assert ours["rmse_axis"] < 0.40 and ours["rmse"] < kb["rmse"]
