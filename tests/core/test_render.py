"""Rendered board images: the lens inversion, and detection against exact corners (#4 done criterion)."""
from __future__ import annotations

import numpy as np
import pytest

from backend.cli import main as cli
from calib_core import synth
from calib_core.board import BoardSpec
from calib_core.detection.corner_error import corner_errors
from calib_core.detection.detect_image import detect_gray
from calib_core.observations import Observations
from calib_core.synth import render


def test_pixel_rays_invert_the_true_lens():
    fx, fy, cx, cy = synth.INTRINSICS
    w, h = synth.IMAGE_SIZE
    rays, covered = render.pixel_rays("fisheye")
    assert rays.shape == (h, w, 2) and covered.shape == (h, w)
    # The fisheye's image circle stops short of the frame's corners; its centre is covered.
    assert not covered[0, 0] and not covered[-1, -1] and covered[h // 2, w // 2] and covered.mean() > 0.9
    v, u = np.mgrid[0:h:7, 0:w:7]
    ok = covered[v, u]
    back = synth.true_project("fisheye", np.concatenate([rays[v, u][ok], np.ones((ok.sum(), 1))], 1))
    np.testing.assert_allclose(back, np.stack([u[ok], v[ok]], 1), atol=1e-7)



@pytest.mark.parametrize("kind", ["freeform", "decentred"])
def test_newton_inverts_the_new_lenses_over_the_whole_image(kind):
    """Every pixel of a grid spanning the image, edges and corners included, has
    a ray, and the lens takes it back to the pixel to 1e-9 (normalised units)."""
    fx, fy, cx, cy = synth.INTRINSICS
    w, h = synth.IMAGE_SIZE
    v, u = np.meshgrid(np.linspace(0, h - 1, 81), np.linspace(0, w - 1, 65), indexing="ij")
    target = np.stack([(u.ravel() - cx) / fx, (v.ravel() - cy) / fy], axis=-1)
    x = render._invert_distortion(kind, target)
    assert np.all(np.isfinite(x))
    np.testing.assert_allclose(synth.true_distort(kind, x), target, rtol=0, atol=1e-9)
    # The lens is far from the identity there: the inversion did some work.
    assert np.abs(x - target).max() * fx > 50
    # The renderer's own per-pixel rays (spline between Newton lattice points, one
    # Newton step per pixel) cover the whole frame.
    rays, covered = render.pixel_rays(kind)
    assert covered.all()
    vv, uu = np.mgrid[0:h:7, 0:w:7]
    back = synth.true_project(kind, np.concatenate([rays[vv, uu].reshape(-1, 2), np.ones((vv.size, 1))], 1))
    np.testing.assert_allclose(back, np.stack([uu.ravel(), vv.ravel()], 1), rtol=0, atol=1e-7)

@pytest.mark.slow
def test_rendered_images_detect_within_a_tenth_of_a_pixel(tmp_path, capsys):
    assert cli(["synth", "--kind", "fisheye", "--views", "2", "--images", "-o", str(tmp_path)]) == 0
    assert sorted(p.name for p in (tmp_path / "images").iterdir()) == ["train_00.png", "train_01.png"]
    truth = Observations.load(tmp_path / "images_truth.json")
    assert truth.board["cols"] == 22 and truth.image_size == synth.IMAGE_SIZE
    assert cli(["detect", str(tmp_path / "images"), "--board", "chessboard:22x22:50mm", "-q",
                "-o", str(tmp_path / "det.json")]) == 0
    assert "2/2 images used" in capsys.readouterr().out
    err = corner_errors(Observations.load(tmp_path / "det.json"), truth, cols=22)
    assert err["views"] == 2 and err["n"] >= 200
    assert err["median"] <= 0.1, err["median"]              # the done criterion
    assert err["p95"] <= 0.25, err["p95"]
    assert err["n_wrong"] <= 0.02 * err["n"]                   # corners off the board's lattice
    assert err["min_lattice_agreement"] >= 0.95  # partial-grid ids: one lattice motion of the truth's (1.0 today)


@pytest.mark.slow
def test_whole_board_views_get_the_true_ids_and_corners():
    """A 9x6 board seen whole: ids are absolute, so each corner is checked against its own truth."""
    board = BoardSpec.parse("chessboard:9x6:50mm")
    rng = np.random.default_rng(1)
    errs = []
    for k, tilt in enumerate(np.radians([[0.0, 0.0], [25.0, -15.0]])):
        pose = synth.pose_looking_at(np.array([200.0, 125.0, 0.0]), 800.0, tilt, 0.3 * k)
        img = render.render_view("radial", pose, (9, 6), 50.0, rng=rng)
        ids, _, uv = render.true_corners("radial", pose, (9, 6), 50.0)
        res = detect_gray(img, board)
        assert res.status == "used" and res.ids.tolist() == ids.tolist() == list(range(54))
        errs.append(np.linalg.norm(res.points - uv, axis=1))
    assert np.median(errs) <= 0.1 and np.max(errs) < 0.3
