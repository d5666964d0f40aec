"""A lens of 200°: corners past 90° off the axis projected on their own side, rendered
by freecal synth --images, found by the detector, and calibrated."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from backend.cli import main as cli
from benchmarks.bench_detect import refinable_truth
from calib_core import calibrate, synth
from calib_core.board import BoardSpec
from calib_core.detection.corner_error import same_id_errors
from calib_core.detection.detect import detect_images
from calib_core.detection.detect_image import detect_file, detect_gray
from calib_core.evaluation.evaluate import evaluate
from calib_core.observations import Observations
from calib_core.synth import render
from calib_core.synth.truth import TruthModel


def test_points_behind_the_camera_plane_keep_their_side_of_the_image():
    theta = np.radians([0.0, 45.0, 89.0, 91.0, 99.0])
    pc = np.column_stack([np.sin(theta), np.zeros_like(theta), np.cos(theta)])
    uv = synth.true_project("fisheye200", pc)
    assert np.all(np.diff(uv[:, 0]) > 0)                  # farther off the axis, farther out, past 90° too
    np.testing.assert_allclose(synth.true_rays("fisheye200", uv), pc, atol=1e-12)
    assert synth.in_view("fisheye200", pc).all()
    assert not synth.in_view("fisheye200", np.array([[np.sin(1.8), 0.0, np.cos(1.8)]]))[0]   # 103°: no light
    rays, covered = render.unit_rays("fisheye200")
    assert not covered[0, 0] and covered[640, 512]         # an image circle inside the frame
    assert rays[covered][:, 2].min() < np.cos(np.radians(99.0))
    truth = TruthModel("fisheye200")                      # the truth as a camera model, through angles
    xn = np.column_stack([theta, np.zeros_like(theta)])   # equidistant coordinates
    np.testing.assert_allclose(truth.pixel_of(xn), uv, atol=1e-9)


def test_the_200_degree_protocol_calibrates_with_the_fisheye_model():
    s = synth.generate("fisheye200", 0.3, 0)
    pc = np.concatenate([v.object_points for v in s.train.views])
    assert len(s.train.views) == 10 and s.train.n_points > 3000
    poses = {v["name"]: np.array(v["rvec"] + v["tvec"]) for v in s.truth["train_views"]}
    cam = np.concatenate([Rotation.from_rotvec(poses[v.name][:3]).apply(v.object_points) + poses[v.name][3:]
                          for v in s.train.views])
    assert len(pc) == len(cam) and (cam[:, 2] < 0).sum() > 100    # corners past 90° off the axis
    cal = calibrate(s.train, "fisheye")
    fx, fy, cx, cy = synth.INTRINSICS
    np.testing.assert_allclose(cal.model.intrinsics[:4], [fx, fy, cx, cy], rtol=2e-3)
    assert evaluate(cal, s.holdout)["rmse"] < 0.05


@pytest.mark.slow
def test_rendered_200_degree_views_are_found_to_the_image_circle(tmp_path):
    """freecal synth --kind fisheye200 --images: of the corners whose refinement window lies
    inside the image and the image circle, >= 95 % found, median error <= 0.1 px, no wrong id."""
    assert cli(["synth", "--kind", "fisheye200", "--views", "4", "--images", "-o", str(tmp_path)]) == 0
    truth = json.loads((tmp_path / "truth.json").read_text())
    det = detect_images(tmp_path / "images", BoardSpec.parse("chessboard:22x22:50mm")).observations
    assert det is not None and len(det.views) == 4
    refinable = Observations(synth.IMAGE_SIZE, [
        refinable_truth("fisheye200", np.array(v["rvec"] + v["tvec"]), v["name"] + ".png")
        for v in truth["train_views"]])
    e = same_id_errors(det, refinable, synth.TRAIN_BOARD[0])
    assert e["n"] >= 0.95 * refinable.n_points
    assert np.median(e["distances"]) <= 0.1
    square = 1.5   # px: the smallest squares at the image circle; a wrong id is a whole square off
    assert e["distances"].max() < square
    exact = Observations.load(tmp_path / "images_truth.json")
    assert cv2.imread(str(tmp_path / "images" / "train_00.png")).shape[:2] == (1280, 1024)
    assert max(len(v) for v in exact.views) > 300


@pytest.mark.slow
def test_a_view_inside_an_image_circle_loses_nothing_without_the_classic_detector(tmp_path):
    """A fisheye's image circle sends its photos straight to the sector-based seeds: the
    classic detector, which cannot follow the bent lines, would only have cost its time."""
    s = synth.generate("fisheye200", 0.0, 0, 1)
    view = s.truth["train_views"][0]
    (name, image), = render.render_set("fisheye200", [(view["name"], np.array(view["rvec"] + view["tvec"]))])[0]
    cv2.imwrite(str(tmp_path / name), image)
    board = BoardSpec.parse("chessboard:22x22:50mm")
    found = detect_file(tmp_path / name, board)
    assert found.image_circle is not None and found.status == "used" and found.n_corners > 100
    with_classic = detect_gray(cv2.imread(str(tmp_path / name), cv2.IMREAD_GRAYSCALE), board, classic_first=True)
    np.testing.assert_array_equal(found.ids, with_classic.ids)
    np.testing.assert_array_equal(found.points, with_classic.points)
