"""Calibration objects that are not one plane: a cube of boards calibrates
the lens as its faces would one by one, with every method."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib_core import calibrate, synth
from calib_core.evaluation.evaluate import evaluate
from calib_core.fitting.init_3d import face_views, planar_faces
from calib_core.methods import METHODS
from calib_core.observations import Observations, View
from calib_core.pipeline import to_data
from calib_core.synth import targets
from calib_core.synth.opencv_lenses import views_of, webcam_lens


def cube_set(kind: str, n: int, seed: int = 0, sigma: float = 0.2) -> Observations:
    rng = np.random.default_rng(seed)
    return targets.shoot(kind, targets.cube(), targets.camera_poses(n, rng), sigma, rng)


def test_the_faces_of_a_cube_are_found_in_its_points():
    target = targets.cube()
    pts = target.object_points(np.arange(target.n_corners))
    label, frames = planar_faces(pts)
    board = target.board_index(np.arange(target.n_corners))
    assert len(frames) == len(target.boards)
    # one face per board, every corner on its own board's face
    assert all(len(np.unique(label[board == k])) == 1 for k in range(len(target.boards)))
    assert len(np.unique(label)) == len(target.boards) and (label >= 0).all()


def test_each_face_seen_in_a_view_becomes_a_planar_view_for_the_homographies():
    obs = cube_set("fisheye", 8)
    data, _, _ = to_data(obs)
    faces = face_views(data)
    assert np.all(faces.object_points[:, 2] == 0.0)
    # as many pseudo-views as (view, board) pairs with at least six corners
    target = targets.cube()
    pairs = sum(int(np.sum(np.bincount(target.board_index(v.ids)) >= 6)) for v in obs.views)
    assert faces.n_views == pairs


def test_a_cube_of_boards_through_a_wide_lens_calibrates_to_the_true_lens():
    """Five ChArUco faces seen from all round through the protocol's fisheye:
    the calibration from the 3-D object points finds the true camera, and the
    same corners split into one planar view per face give the same answer."""
    obs = cube_set("fisheye", 16)
    assert any(len(np.unique(np.round(v.object_points[:, 2], 6))) > 2 for v in obs.views)  # truly 3-D views
    cal = calibrate(obs, "fisheye")
    fx, fy, cx, cy = synth.INTRINSICS
    np.testing.assert_allclose(cal.model.intrinsics[:2], [fx, fy], rtol=3e-3)
    np.testing.assert_allclose(cal.model.intrinsics[2:4], [cx, cy], atol=1.5)
    holdout = synth.generate("fisheye").holdout
    error = evaluate(cal, holdout)["rmse"]
    assert error < 0.15
    split = targets.cube().split(obs)
    assert len(split.views) > len(obs.views)  # views showing two or three faces
    per_face = calibrate(split, "fisheye")
    np.testing.assert_allclose(cal.model.intrinsics[:4], per_face.model.intrinsics[:4], rtol=2e-3)
    assert evaluate(per_face, holdout)["rmse"] < 0.15


@pytest.mark.slow
@pytest.mark.parametrize("method", sorted(METHODS))
def test_every_method_calibrates_a_3d_object_as_its_faces_one_by_one(method):
    obs = cube_set("radial", 16)
    split = targets.cube().split(obs)
    solid, faces = calibrate(obs, method), calibrate(split, method)
    assert np.isfinite(solid.metrics.rmse)
    assert solid.metrics.rmse <= 1.5 * faces.metrics.rmse
    np.testing.assert_allclose(solid.model.intrinsics[:2], faces.model.intrinsics[:2], rtol=0.02)


def test_one_board_moved_off_z_0_calibrates_as_the_board_itself():
    """Object points of one planar board given in another frame (tilted, shifted:
    a face of some object): posed by PnP instead of a homography, same camera."""
    obs = views_of(webcam_lens, (640, 480), 8, seed=1, sigma=0.2, distance=500, spread=0.3)
    motion = Rotation.from_rotvec([0.4, -0.3, 1.0])
    moved = Observations(obs.image_size, [View(v.name, motion.apply(v.object_points) + [100.0, -50.0, 300.0],
                                               v.image_points, v.ids) for v in obs.views])
    a, b = calibrate(obs, "zhang"), calibrate(moved, "zhang")
    np.testing.assert_allclose(a.model.intrinsics, b.model.intrinsics, rtol=1e-6, atol=1e-6)
    assert b.metrics.rmse == pytest.approx(a.metrics.rmse, rel=1e-6)


def test_a_view_whose_corners_lie_on_one_line_is_dropped_saying_why():
    """One row of a board cannot fix its pose (no homography, no PnP): such a view
    once made every initial camera fail ("no focal length explains the board views")."""
    obs = views_of(webcam_lens, (640, 480), 8, seed=1, sigma=0.2, distance=500, spread=0.3)
    v = obs.views[0]
    row = v.object_points[:, 1] == v.object_points[0, 1]
    obs.views[0] = v.subset(row)
    assert len(obs.views[0]) >= 6
    cal = calibrate(obs, "zhang")
    assert [d["name"] for d in cal.dropped_views] == [v.name]
    assert "one line" in cal.dropped_views[0]["reason"]
