"""Targets of several boards (freecal.target/1): the file, every board found and
labelled in rendered images, one 3-D view of the object per image."""
from __future__ import annotations

import copy

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib_core import calibrate, synth
from calib_core.board import BoardSpec
from calib_core.detection.detect_image import detect_gray
from calib_core.detection.targets import detect_target
from calib_core.errors import FormatError
from calib_core.evaluation.evaluate import evaluate
from calib_core.synth import render_target, targets
from calib_core.target import Target


def corner_doc() -> dict:
    return targets.corner().to_json()


def test_a_target_file_round_trips_and_numbers_its_corners_board_after_board():
    t = Target.from_json(corner_doc())
    assert Target.from_json(t.to_json()) == t
    assert [b.offset for b in t.boards] == [0, 64, 128] and t.n_corners == 192
    np.testing.assert_array_equal(t.board_index([0, 63, 64, 191]), [0, 0, 1, 2])
    # board k's corner i is the target's offset_k + i, placed by the board's pose
    b = t.boards[1]
    np.testing.assert_allclose(t.object_points([64 + 10]), b.in_object(b.spec.object_points([10])))
    assert all(abs(p[a]) < 1e-9 for p, a in zip(t.object_points([0, 64, 128]), (2, 0, 1), strict=True))


@pytest.mark.parametrize("change, words", [
    (lambda d: d["boards"][1]["board"].update(first_marker=20), "share markers 20-39"),
    (lambda d: d["boards"][0].pop("tvec"), "both rvec and tvec"),
    (lambda d: d["boards"][0].update(rvec=[0, 0]), "three finite numbers"),
    (lambda d: d["boards"][0]["board"].update(units="m"), "differs from the target's"),
    (lambda d: d["boards"][2].update(name="floor"), "appears twice"),
    (lambda d: d.update(format="freecal.observations/1"), "not a freecal target"),
    (lambda d: d["boards"][0]["board"].update(type="dots"), "boards\\[0\\].board.type"),
])
def test_a_bad_target_file_says_what_is_wrong(change, words):
    doc = copy.deepcopy(corner_doc())
    change(doc)
    with pytest.raises(FormatError, match=words):
        Target.from_json(doc)


def test_a_board_without_a_pose_is_loose():
    doc = corner_doc()
    del doc["boards"][2]["rvec"], doc["boards"][2]["tvec"]
    t = Target.from_json(doc)
    assert [b.fixed for b in t.boards] == [True, True, False]
    assert "rvec" not in t.to_json()["boards"][2]


def _errors(found_ids, found_pts, truth_ids, truth_uv):
    """Distance of each found corner to the true corner of the same id (inf: no such visible corner)."""
    truth = dict(zip(truth_ids.tolist(), truth_uv, strict=True))
    return np.array([np.linalg.norm(p - truth[i]) if i in truth else np.inf
                     for i, p in zip(found_ids.tolist(), found_pts, strict=True)])


@pytest.mark.slow
def test_every_board_of_a_rendered_room_corner_is_found_with_its_own_ids():
    """Three ChArUco boards of one dictionary (ids 0-39, 40-79, 80-119) through the
    protocol's fisheye: each board seen well is found, every corner under its
    target id and where the truth has it."""
    t = targets.corner()
    rng = np.random.default_rng(3)
    for pose in targets.corner_poses(2, rng):
        res = detect_target(render_target.render_target("fisheye", t, pose, rng), t)
        assert res.status == "used" and res.ids is not None and res.points is not None
        e = _errors(res.ids, res.points, *targets.seen("fisheye", t, pose, max_angle_deg=89.0))
        assert e.max() < 0.5 and np.median(e) < 0.05
        clear, _ = targets.seen("fisheye", t, pose, max_angle_deg=60.0)
        board = t.board_index(clear)
        seen_boards = {t.boards[k].name for k in np.unique(board) if np.sum(board == k) >= 15}
        found = {h.label for h in res.boards if h.placed and h.n_corners}
        assert seen_boards <= found
        assert np.isin(clear, res.ids).mean() > 0.85


@pytest.mark.slow
@pytest.mark.parametrize("kind, method, seed", [("radial", "zhang", 0), ("fisheye", "auto", 0), ("fisheye", "auto", 2)])
def test_a_rendered_room_corner_calibrates_the_lens_as_well_as_its_boards_one_by_one(tmp_path, kind, method, seed):
    """Twelve rendered views, detected as one object: the 3-D calibration predicts the
    hold-out views within 10 % of the same corners calibrated as planar views, one per
    board (the same corner count); the radial lens's camera is the true one. Through the
    fisheye, the default's choice must not extrapolate worse for the object than for its boards."""
    from calib_core.detection.detect import detect_images

    t = targets.corner()
    rng = np.random.default_rng(seed)
    for k, pose in enumerate(targets.corner_poses(12, rng)):
        cv2.imwrite(str(tmp_path / f"corner_{k:02d}.png"), render_target.render_target(kind, t, pose, rng))
    obs = detect_images(tmp_path, t).observations
    assert obs is not None and len(obs.views) == 12 and obs.extra["target"]["format"] == "freecal.target/1"
    solid = calibrate(obs, method)
    if kind == "radial":
        fx, fy, cx, cy = synth.INTRINSICS
        np.testing.assert_allclose(solid.model.intrinsics[:4], [fx, fy, cx, cy], rtol=2e-3)
    holdout = synth.generate(kind).holdout
    planar = calibrate(t.split(obs), method)
    assert evaluate(solid, holdout)["rmse"] <= 1.1 * evaluate(planar, holdout)["rmse"]


def _chessboard_corner(sizes) -> Target:
    doc = corner_doc()
    for k, (cols, rows) in enumerate(sizes):
        doc["boards"][k]["board"] = {"type": "chessboard", "cols": cols, "rows": rows, "square_size": 40.0}
    return Target.from_json(doc)


@pytest.mark.slow
def test_chessboards_are_placed_only_where_the_image_tells_which_they_are():
    pose = synth.look_at_pose(np.full(3, 700 / np.sqrt(3)), np.full(3, 130.0), 0.5)  # all three boards, whole
    # a 6x5 and a 5x4 board: one of each size, not square, odd corner sums: placed on the object
    t = _chessboard_corner([(6, 5), (5, 4)])
    res = detect_target(render_target.render_target("radial", t, pose), t)
    placed = {h.label: h.n_corners for h in res.boards if h.placed}
    assert placed["floor"] == 30 and placed["wall x"] == 20 and placed["wall y"] > 40
    e = _errors(res.ids, res.points, *targets.seen("radial", t, pose, max_angle_deg=89.0))
    assert e.max() < 0.5
    # two 6x5 boards: which is which cannot be told, each becomes a planar view of its own
    t = _chessboard_corner([(6, 5), (6, 5)])
    res = detect_target(render_target.render_target("radial", t, pose), t)
    own = [h for h in res.boards if not h.placed and h.n_corners]
    assert sorted(h.label for h in own) == ["chessboard 6x5 #1", "chessboard 6x5 #2"]
    assert all("2 chessboards of this size" in h.reason for h in own)


def _charuco_view(flip: bool = False) -> np.ndarray:
    spec = targets.corner().boards[0].spec
    pose = np.concatenate([Rotation.from_rotvec([0.3, -0.2, 0.1]).as_rotvec(), [-180.0, -180.0, 450.0]])
    img = render_target.render_boards("radial", [(spec, pose)])
    return cv2.flip(img, 1) if flip else img


def test_tags_of_another_dictionary_and_mirrored_boards_are_named_as_such():
    img = _charuco_view()
    right = BoardSpec.parse("charuco:9x9:40mm:30mm:DICT_5X5_250")
    assert detect_gray(img, right).status == "used"
    wrong = detect_gray(img, BoardSpec.parse("charuco:9x9:40mm:30mm:DICT_4X4_250"))
    assert wrong.status == "rejected" and "markers of DICT_5X5_50" in wrong.reason and "dictionary" in wrong.reason
    mirrored = detect_gray(_charuco_view(flip=True), right)
    assert mirrored.status == "rejected" and "mirrored" in mirrored.reason
    other_ids = detect_gray(img, BoardSpec.from_json({**right.to_json(), "first_marker": 100}))
    assert "ids 100-139" in other_ids.reason and "ids 0-39" in other_ids.reason


def test_a_board_out_of_view_is_not_told_to_check_its_dictionary():
    """Two ChArUco boards of different dictionaries, one out of the picture: the markers the image
    shows are the other board's, and the reason for the missing one read "no DICT_6X6_250 markers
    decoded, but 24 markers of DICT_4X4_50: check the board's dictionary"."""
    board = {"type": "charuco", "squares_x": 5, "squares_y": 7, "square_size": 40.0, "marker_size": 30.0}
    t = Target.from_json({"format": "freecal.target/1", "units": "mm", "boards": [
        {"name": "near", "board": {**board, "dictionary": "DICT_4X4_50"}, "rvec": [0.0, 0.0, 0.0], "tvec": [0.0, 0.0, 0.0]},
        {"name": "away", "board": {**board, "dictionary": "DICT_6X6_250"}, "rvec": [0.0, 0.0, 0.0],
         "tvec": [5000.0, 0.0, 0.0]}]})
    pose = np.array([0.0, 0.0, 0.0, -100.0, -140.0, 450.0])  # the near board face-on, the other far aside
    res = detect_target(render_target.render_target("radial", t, pose, np.random.default_rng(0)), t)
    reasons = {h.label: h.reason for h in res.boards}
    assert res.status == "used" and reasons["near"] == ""
    assert reasons["away"].startswith("not in view") and "dictionary" not in reasons["away"].replace("of DICT", "")


def test_a_charuco_corner_beside_one_unreadable_marker_is_found():
    """A marker covered (a finger, glare, too small to decode) leaves each of the four corners
    round it one decoded marker: each is still found, where the truth has it."""
    spec = targets.corner().boards[0].spec
    pose = np.concatenate([Rotation.from_rotvec([0.3, -0.2, 0.1]).as_rotvec(), [-180.0, -180.0, 450.0]])
    turn = Rotation.from_rotvec(pose[:3])
    corners = spec.object_points(np.arange(spec.n_corners))
    truth = synth.true_project("radial", turn.apply(corners) + pose[3:])
    centre = np.asarray(spec.cv_charuco().getObjPoints(), np.float64)[12].mean(axis=0)   # a marker mid-board
    at = synth.true_project("radial", turn.apply(centre[None]) + pose[3:])[0]
    img = render_target.render_boards("radial", [(spec, pose)])
    square_px = np.linalg.norm(truth[1] - truth[0])
    cv2.circle(img, tuple(int(round(v)) for v in at), int(0.25 * square_px), 255, -1)   # its bits, not its corners
    res = detect_gray(img, spec)
    beside = np.flatnonzero(np.linalg.norm(corners[:, :2] - centre[:2], axis=1) < 0.75 * spec.square_size)
    assert len(beside) == 4 and np.isin(beside, res.ids).all()
    assert np.linalg.norm(res.points - truth[res.ids], axis=1).max() < 0.3


def test_a_steep_charuco_board_keeps_the_corners_its_markers_name():
    """Seen 65° off its normal, the far markers are too small to read or lie beside unread
    ones: each corner one decoded marker names is found, where the truth has it."""
    spec = BoardSpec.parse("charuco:9x9:28mm:19mm:DICT_4X4_50")
    corners = spec.object_points(np.arange(spec.n_corners))
    turn = Rotation.from_euler("y", 65, degrees=True)
    shift = np.array([0.0, 0.0, 260.0]) - turn.apply(corners.mean(axis=0))
    res = detect_gray(render_target.render_boards("radial", [(spec, np.concatenate([turn.as_rotvec(), shift]))]), spec)
    assert res.status == "used" and res.ids is not None and res.points is not None
    assert len(res.ids) >= 36   # OpenCV's naming alone: 24
    truth = synth.true_project("radial", turn.apply(corners) + shift)
    assert np.linalg.norm(res.points - truth[res.ids], axis=1).max() < 0.3


def test_a_charuco_board_of_another_size_is_named_as_such():
    """The same markers read on a board of another width sit where that board has other ids:
    no corner is named, and the reason says what to check. (A board with fewer rows of the
    same width is the same board's first rows: its ids and corners are right.)"""
    img = _charuco_view()
    for size in ("7x9", "10x9", "11x11"):
        res = detect_gray(img, BoardSpec.parse(f"charuco:{size}:40mm:30mm:DICT_5X5_250"))
        assert res.status == "rejected" and "not where a" in res.reason and "board's size" in res.reason


def test_the_example_in_the_targets_page_is_a_valid_target():
    import json
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "targets.md").read_text()
    block = re.search(r'```json\n(\{\n  "format": "freecal.target/1".*?)```', text, re.S)
    assert block is not None
    t = Target.from_json(json.loads(block.group(1)))
    corner = targets.corner()
    assert [b.fixed for b in t.boards] == [True, True, False]
    for ours, theirs in zip(t.boards[:2], corner.boards[:2], strict=True):   # the poses are the rendered target's
        np.testing.assert_allclose(ours.pose, theirs.pose, atol=1e-4)
