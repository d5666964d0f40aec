"""Degenerate view sets fail with the reason and what to shoot (calib_core.fitting.view_set), on the
synthetic lenses: copies of one view, one pose re-shot with noise, every board face-on, every
board with the same tilt; a good set of each lens still calibrates."""
from __future__ import annotations

import numpy as np
import pytest

from calib_core import calibrate, synth
from calib_core.errors import DataError, DegenerateViews
from calib_core.fitting.view_set import check_views
from calib_core.observations import Observations, View

KINDS = ("radial", "fisheye", "asymmetric", "decentred")
QUICK = {"knots": "uniform", "intervals": [4, 4], "max_iterations": 10, "lambda_smooth": 0.1}
COLS, ROWS = synth.TRAIN_BOARD
CENTRE = np.array([(COLS - 1) * synth.SQUARE / 2, (ROWS - 1) * synth.SQUARE / 2, 0.0])


def shot(kind: str, poses, sigma: float = 0.3, seed: int = 0) -> Observations:
    views, _ = synth.shoot(kind, np.array(poses), synth.board_points(COLS, ROWS), sigma,
                            np.random.default_rng(seed), "view_")
    board = {"type": "chessboard", "cols": COLS, "rows": ROWS, "square_size": synth.SQUARE, "units": "mm"}
    return Observations(synth.IMAGE_SIZE, views, board)


def placed(rng, tilt_deg=(0.0, 0.0), roll: bool = True) -> np.ndarray:
    """A pose looking at a random point of the board from a random distance, with the given tilt."""
    return synth.pose_looking_at(CENTRE + [*rng.uniform(-150, 150, 2), 0.0], rng.uniform(160, 260),
                                  np.radians(tilt_deg), rng.uniform(-0.5, 0.5) if roll else 0.0)


def refused(obs: Observations, *words: str, method: str = "bspline", **settings) -> str:
    with pytest.raises(DegenerateViews) as err:
        calibrate(obs, method, **settings)
    message = str(err.value)
    assert isinstance(err.value, DataError)  # the service answers it as the data's fault, the CLI in one line
    for w in (*words, "tilted by 20-45°"):
        assert w in message, message
    return message


@pytest.mark.parametrize("kind", KINDS)
def test_copies_of_one_photo_are_one_pose(kind):
    one = synth.generate(kind, 0.3, 0).train.views[3]
    copies = Observations(synth.IMAGE_SIZE, [View(f"copy_{k:02d}", one.object_points, one.image_points, one.ids)
                                             for k in range(13)], {})
    message = refused(copies, "only 1 distinct pose", "'copy_00' and 'copy_01'", "copies of one photo")
    assert "13 views" in message


@pytest.mark.parametrize("kind", KINDS)
def test_one_pose_shot_again_and_again_is_one_pose(kind):
    pose = placed(np.random.default_rng(1), (25.0, 10.0))
    again = Observations(synth.IMAGE_SIZE, [View(f"view_{s}", v.object_points, v.image_points, v.ids)
                                            for s in range(8) for v in shot(kind, [pose], 0.3, s).views], {})
    refused(again, "only 1 distinct pose", "did not move")


def test_two_poses_are_not_enough_but_three_are_checked_further():
    good = synth.generate("radial", 0.3, 0).train.views
    two = Observations(synth.IMAGE_SIZE, [good[1], good[2]] * 3, {})
    two.views = [View(f"v{k}", v.object_points, v.image_points, v.ids) for k, v in enumerate(two.views)]
    with pytest.raises(DegenerateViews, match="only 2 distinct pose"):
        check_views(two)
    check_views(Observations(synth.IMAGE_SIZE, good[:3], {}))  # three poses, tilted: fine


@pytest.mark.slow
@pytest.mark.parametrize("kind", KINDS)
def test_every_board_face_on_is_refused(kind):
    """Before the solver when the corners show it (depth ratios); with this wide lens's distortion bending
    the homographies, on the fitted poses (all parallel) otherwise."""
    rng = np.random.default_rng(2)
    refused(shot(kind, [placed(rng) for _ in range(10)]), "the focal length cannot be told from the distance")


@pytest.mark.parametrize("kind", KINDS)
def test_every_board_with_the_same_tilt_is_refused(kind):
    """Parallel planes (one tilt, moved around the frame): each view is tilted, yet the focal length is
    unobservable; fitted, these gave fx from 18 to 512 px for a 305 px lens."""
    rng = np.random.default_rng(3)
    obs = shot(kind, [placed(rng, (25.0, 7.5), roll=False) for _ in range(10)])
    check_views(obs)  # each view on its own looks fine
    for method, settings in (("zhang", {}), ("bspline", QUICK)):
        refused(obs, "tilted the same way in all 10 views", "the focal length cannot be told from the distance",
                method=method, **settings)


@pytest.mark.parametrize("kind", KINDS)
def test_a_good_set_still_calibrates(kind):
    obs = synth.generate(kind, 0.3, 0).train
    check_views(obs)
    cal = calibrate(obs, "bspline", **QUICK)
    assert len(cal.views) == len(obs.views)


def test_too_few_usable_views_names_each_dropped_view_and_why():
    obs = synth.generate("radial", 0.3, 0).train
    ys, counts = np.unique(obs.views[0].object_points[:, 1], return_counts=True)
    row = obs.views[0].object_points[:, 1] == ys[np.argmax(counts)]  # the longest row the view shows
    views = [View("one_row", obs.views[0].object_points[row], obs.views[0].image_points[row]),
             View("four_corners", obs.views[1].object_points[:4], obs.views[1].image_points[:4]), obs.views[2]]
    with pytest.raises(DataError) as err:
        calibrate(Observations(obs.image_size, views, obs.board), "zhang")
    message = str(err.value)
    for words in ("only 1 usable view(s) of 3", "'one_row': its corners all lie on one line",
                  "'four_corners': too few corners (4, need at least 6)"):
        assert words in message, message
