"""The mrcal side by side (benchmarks/mrcal_bridge.py): corners reach mrcal's
grid layout intact, and, when mrcal's interpreter is configured, mrcal's
OPENCV8 fit of OpenCV's own lens lands on the noise floor."""
import numpy as np
import pytest

from benchmarks import mrcal_bridge
from benchmarks.bench_compare import thin
from calib_core import synth
from calib_core.detection import babelcalib

from ..conftest import shared_data


def test_corners_land_in_their_board_cells():
    train = synth.generate("radial", n_views=3).train
    grid, spacing = mrcal_bridge.to_grid(train)
    _, origin, (w, h) = mrcal_bridge.lattice(train)  # the grid spans only the corners seen
    assert spacing == synth.SQUARE and grid.shape == (3, h, w, 3) and w <= 22 and h <= 22
    assert int((grid[..., 2] > 0).sum()) == train.n_points  # the rest are missing (weight −1)
    col0, row0 = (origin / spacing).astype(int)
    for k, v in enumerate(train.views):
        row, col = np.divmod(v.ids, synth.TRAIN_BOARD[0])  # id = row · cols + col
        assert np.array_equal(grid[k, row - row0, col - col0, :2], v.image_points)


def test_babelcalib_board_spacing_is_found_from_its_corners():
    folder = shared_data("babelcalib-ov-plane-fisheye")
    spacing, _, (w, h) = mrcal_bridge.lattice(babelcalib.load(folder / "train", folder / "ov_plane.dsc"))
    assert spacing == pytest.approx(7.5) and w <= 22 and h <= 22


@pytest.mark.skipif(mrcal_bridge.interpreter() is None, reason="mrcal is not configured (scripts/ensure-mrcal.sh)")
def test_mrcal_opencv8_fits_the_radial_lens_to_the_noise():
    s = synth.generate("radial", n_views=6)
    out = mrcal_bridge.run(s.train, thin(s.holdout, 16), mrcal_bridge.interpreter())
    r = out["opencv8"]
    assert "error" not in r, r.get("error")
    assert r["train_rmse_axis"] == pytest.approx(0.3, abs=0.03)  # σ = 0.3 per axis
    assert r["test_rmse"] < 0.1  # the exact model: only the noise's effect on the fit
