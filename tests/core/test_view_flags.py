"""Curation flags: in a synthetic set where one view was shot wrong (a bent board, a board that
moved half-way, corners misdetected) exactly that view is flagged, for that reason; a clean set
and a real one (OpenCV's stereo left camera) are not flagged for rmse or structure."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib_core import calibrate, synth
from calib_core.evaluation.view_flags import structure, view_flags
from calib_core.synth.lenses import true_project

KIND = "radial"
BAD = 4   # the view that goes wrong


def _shot(truth_view: dict, board: np.ndarray) -> np.ndarray:
    """Pixels of board points (N, 3) seen from the truth's pose of one view, through the true lens."""
    pc = Rotation.from_rotvec(truth_view["rvec"]).apply(board) + np.asarray(truth_view["tvec"])
    return true_project(KIND, pc)


def bent(obs, truth):
    """The board sags like a sheet bowed along its rows (2 mm at the middle); its corners are still
    given flat."""
    v = obs.views[BAD]
    x = v.object_points[:, 0]
    half = np.ptp(x) / 2
    sag = 2.0 * (1 - ((x - x.min() - half) / half) ** 2)
    board = v.object_points + np.column_stack([0 * x, 0 * x, sag])
    rng = np.random.default_rng(1)
    v.image_points = _shot(truth["train_views"][BAD], board) + rng.normal(0, 0.3, (len(v), 2))


def moved(obs, truth):
    """The board moved during the exposure (rolling shutter): its lower half seen 0.4 degrees further
    turned about the board's middle row than its upper half."""
    v = obs.views[BAD]
    y = v.object_points[:, 1]
    mid = np.array([0.0, np.median(y), 0.0])
    low = y > mid[1]
    board = v.object_points.copy()
    board[low] = Rotation.from_rotvec([np.radians(0.4), 0, 0]).apply(board[low] - mid) + mid
    rng = np.random.default_rng(2)
    v.image_points = _shot(truth["train_views"][BAD], board) + rng.normal(0, 0.3, (len(v), 2))


def misdetected(obs, truth):
    """A fifth of the view's corners snapped 6 px off (glare, the wrong saddle)."""
    v = obs.views[BAD]
    rng = np.random.default_rng(3)
    k = rng.choice(len(v), len(v) // 5, replace=False)
    angle = rng.uniform(0, 2 * np.pi, len(k))
    v.image_points[k] += 6.0 * np.column_stack([np.cos(angle), np.sin(angle)])


@pytest.mark.slow
@pytest.mark.parametrize("spoil, code", [(bent, "structure"), (moved, "rmse"), (misdetected, "outliers")])
def test_the_one_spoiled_view_is_flagged_for_its_reason(spoil, code):
    s = synth.generate(KIND, 0.3, 0, n_views=12)
    spoil(s.train, s.truth)
    name = s.train.views[BAD].name
    rows = view_flags(calibrate(s.train, "rational"), s.train)
    flagged = {r["view"]: [f["code"] for f in r["flags"]] for r in rows if r["flags"]}
    assert set(flagged) == {name}, flagged
    assert code in flagged[name], flagged
    row = next(r for r in rows if r["view"] == name)
    assert all(len(f["text"]) > 20 for f in row["flags"])  # said in words


@pytest.mark.slow
def test_a_clean_set_has_no_flags():
    s = synth.generate(KIND, 0.3, 0, n_views=12)
    rows = view_flags(calibrate(s.train, "rational"), s.train)
    assert len(rows) == len(s.train.views)
    assert not [r for r in rows if r["flags"]]
    for r in rows:
        assert r["n_kept"] <= r["n_detected"] == len(s.train.view(r["view"]))
        assert 0 < r["rmse"] < 0.6 and r["max_error"] >= r["rmse"]


def test_structure_tells_a_pattern_from_noise():
    rng = np.random.default_rng(0)
    j, i = np.mgrid[0:9, 0:15]
    board = np.column_stack([i.ravel() * 26.0, j.ravel() * 26.0, np.zeros(i.size)])
    noise = rng.normal(0, 0.3, (len(board), 2))
    share, p = structure(board, noise)
    assert share < 0.2 and p > 1e-3           # noise: about 6 of 135 points' worth
    x = (board[:, 0] - board[:, 0].mean()) / 200
    bow = noise + np.column_stack([x ** 2, 0 * x]) * 3
    share, p = structure(board, bow)
    assert share > 0.5 and p < 1e-12
    assert structure(board[:10], noise[:10]) == (None, None)   # too few corners to tell
