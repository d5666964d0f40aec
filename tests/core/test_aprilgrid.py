"""Kalibr's AprilGrid as a board type: Kalibr's layout and numbering, found in rendered views."""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from calib_core import synth
from calib_core.board import BoardSpec
from calib_core.detection.aprilgrid import corner_ids
from calib_core.detection.detect_image import detect_gray
from calib_core.errors import SettingsError
from calib_core.synth import render_target

# Kalibr's codes for tags 0-3 (kalibr_create_target_pdf, t36h11), bit 6i+j of row i, column j, set = white
KALIBR_36H11 = (0xd5d628584, 0xd97f18b49, 0xdd280910e, 0xe479e9c98)


def test_the_spec_reads_like_kalibrs_yaml():
    b = BoardSpec.parse("aprilgrid:6x6:88mm:0.3")      # tagCols, tagRows, tagSize, tagSpacing
    assert (b.cols, b.rows, b.square_size, b.tag_spacing, b.dictionary) == (6, 6, 88.0, 0.3, "DICT_APRILTAG_36h11")
    assert b.n_corners == 144 and b.n_markers == 36
    assert BoardSpec.from_json(b.to_json()) == b and BoardSpec.parse(b.to_spec()) == b
    assert b.to_json()["type"] == "aprilgrid" and b.to_json()["tag_size"] == 88.0


@pytest.mark.parametrize("spec, words", [
    ("aprilgrid:6x6:88mm", "TAGSXxTAGSY:TAG:SPACING"), ("aprilgrid:6x6:88mm:1.5", "at most 1"),
    ("aprilgrid:6x6:88mm:0.3:DICT_6X6_250", "AprilTags"), ("aprilgrid:30x30:88mm:0.3", "holds"),
])
def test_bad_aprilgrid_specs_say_what_to_do(spec, words):
    with pytest.raises(SettingsError, match=words):
        BoardSpec.parse(spec)


def test_points_are_numbered_and_placed_as_kalibr_does():
    """GridCalibrationTargetAprilgrid::createGridPoints: a 2X x 2Y lattice, row-major from
    the bottom-left, x = (c // 2)(1 + spacing) s + (c % 2) s, y likewise."""
    b = BoardSpec.parse("aprilgrid:6x6:88mm:0.3")
    s, step = 88.0, 1.3 * 88.0
    np.testing.assert_allclose(b.object_points([0, 1, 2, 12, 13, 143]),
                               [[0, 0, 0], [s, 0, 0], [step, 0, 0], [0, s, 0], [s, s, 0], [5 * step + s, 5 * step + s, 0]])
    # tag 7 (row 1, col 1): its lower-left point is 2*12*1 + 2 = 26; OpenCV's corners 0-3 (the
    # marker's top-left ...) sit at the printed tag's bottom-right, bottom-left, top-left, top-right
    np.testing.assert_array_equal(corner_ids(np.array([0, 7]), 6), [[1, 0, 12, 13], [27, 26, 38, 39]])


def test_opencvs_apriltag_dictionary_is_kalibrs_codes_printed_turned_round():
    """Why the corner order above: Kalibr prints each tag as OpenCV's marker turned by 180°."""
    d = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    for tag, code in enumerate(KALIBR_36H11):
        bits = (cv2.aruco.generateImageMarker(d, tag, 10, borderBits=2)[2:8, 2:8] > 127).astype(int)
        kalibr = np.rot90([[(code >> (6 * i + j)) & 1 for j in range(6)] for i in range(6)], 2)
        np.testing.assert_array_equal(np.rot90(bits, 2), kalibr)


@pytest.mark.parametrize("kind", ["radial", "fisheye"])
def test_a_rendered_aprilgrid_is_found_with_kalibrs_ids(kind):
    spec = BoardSpec.parse("aprilgrid:6x6:40mm:0.3")
    pts = spec.object_points(np.arange(spec.n_corners))
    rng = np.random.default_rng(0)
    found = 0
    for _ in range(3):
        # Kalibr's board faces +z of its frame (x right, y up the page): turned to face the camera
        r = Rotation.from_rotvec(np.radians(rng.uniform(-35, 35, 3)) * [1, 1, 0.5]) * Rotation.from_rotvec([np.pi, 0, 0])
        t = np.array([*rng.uniform(-60, 60, 2), rng.uniform(220, 300)]) - r.apply(pts.mean(axis=0))
        img = render_target.render_boards(kind, [(spec, np.concatenate([r.as_rotvec(), t]))], rng)
        res = detect_gray(img, spec)
        assert res.status == "used" and res.ids is not None and res.points is not None
        truth = synth.true_project(kind, r.apply(pts) + t)
        e = np.linalg.norm(res.points - truth[res.ids], axis=1)
        assert e.max() < 0.5 and np.median(e) < 0.05   # a wrong id would be a whole tag (~40 px) off
        found += len(res.ids)
    assert found >= 0.7 * 3 * spec.n_corners


@pytest.mark.parametrize("tilt_deg", [60, 65])
def test_a_steep_aprilgrid_keeps_the_corners_of_the_tags_opencv_reads(tilt_deg):
    """Seen 60-65° off face-on, a refinement window sized from a tag's mean side reached past its
    two-bit border into the bits, and cornerSubPix settled there: 60 of 76 and 34 of 56 corners of
    the decoded tags were kept. Sized from the shortest side: 69 and 46, within 0.6 px."""
    from calib_core.detection import markers

    spec = BoardSpec.parse("aprilgrid:6x6:40mm:0.3")
    pts = spec.object_points(np.arange(spec.n_corners))
    r = Rotation.from_rotvec([0, np.radians(tilt_deg), 0]) * Rotation.from_rotvec([np.pi, 0, 0])
    t = np.array([0, 0, 230.0]) - r.apply(pts.mean(axis=0))
    img = render_target.render_boards("radial", [(spec, np.concatenate([r.as_rotvec(), t]))], np.random.default_rng(1))
    _, tags = markers.Markers(img).of(spec.dictionary, 0, spec.n_markers, 2)
    res = detect_gray(img, spec)
    assert res.ids is not None and res.points is not None and len(res.ids) >= 0.8 * 4 * len(tags)
    e = np.linalg.norm(res.points - synth.true_project("radial", r.apply(pts) + t)[res.ids], axis=1)
    assert e.max() < 0.6


def test_an_aprilgrid_taken_for_a_charuco_board_and_back_is_named_as_such():
    """Kalibr's tags have a two-bit border, ChArUco's markers one: the reasons said only "no DICT_5X5_100
    markers decoded" and "no DICT_APRILTAG_36h11 markers decoded" (the image holding 36 and 24 of them)."""
    r = Rotation.from_rotvec([np.pi, 0, 0])
    grid = BoardSpec.parse("aprilgrid:6x6:40mm:0.3")
    t = np.array([0, 0, 260.0]) - r.apply(grid.object_points(np.arange(grid.n_corners)).mean(axis=0))
    img = render_target.render_boards("radial", [(grid, np.concatenate([r.as_rotvec(), t]))], np.random.default_rng(0))
    res = detect_gray(img, BoardSpec.parse("charuco:5x7:40mm:30mm:DICT_5X5_100"))
    assert res.status == "rejected" and "tags of an AprilGrid (DICT_APRILTAG_36h11" in res.reason and "board's type" in res.reason
    charuco = BoardSpec.parse("charuco:6x8:40mm:30mm:DICT_APRILTAG_36h11")
    t = np.array([0, 0, 330.0]) - charuco.object_points(np.arange(charuco.n_corners)).mean(axis=0)
    img = render_target.render_boards("radial", [(charuco, np.concatenate([np.zeros(3), t]))], np.random.default_rng(0))
    res = detect_gray(img, BoardSpec.parse("aprilgrid:6x6:40mm:0.3"))
    assert res.status == "rejected" and "one-bit black border: a ChArUco board's markers" in res.reason


def test_a_grid_of_another_width_is_named_as_such():
    """Tags read on a grid of another width sit where that grid has other ids: no corner is
    named (it would be a wrong object point), and the reason says what to check. A grid with
    fewer rows of the same width is the same grid's first rows: its ids are right."""
    spec = BoardSpec.parse("aprilgrid:6x6:40mm:0.3")
    pts = spec.object_points(np.arange(spec.n_corners))
    r = Rotation.from_rotvec(np.radians([10, -15, 5])) * Rotation.from_rotvec([np.pi, 0, 0])
    t = np.array([0.0, 0.0, 300.0]) - r.apply(pts.mean(axis=0))
    img = render_target.render_boards("radial", [(spec, np.concatenate([r.as_rotvec(), t]))])
    assert detect_gray(img, spec).n_corners == spec.n_corners
    for size in ("5x6", "7x7", "4x9"):
        res = detect_gray(img, BoardSpec.parse(f"aprilgrid:{size}:40mm:0.3"))
        assert res.status == "rejected" and "not where a" in res.reason and "tags across" in res.reason
    first_rows = detect_gray(img, BoardSpec.parse("aprilgrid:6x5:40mm:0.3"))
    assert first_rows.status == "used" and first_rows.ids is not None and first_rows.points is not None
    truth = synth.true_project("radial", r.apply(pts) + t)
    assert np.linalg.norm(first_rows.points - truth[first_rows.ids], axis=1).max() < 0.5


@pytest.mark.parametrize("kind", ["radial", "fisheye"])
def test_a_grid_given_another_spacing_is_named_as_such(kind):
    """Tags printed 0.3 of a tag apart, read with a spec of 0.2 or 0.4: each tag's corners are
    right, but every object point between tags would be off by a tenth of a tag (a calibration
    at pixels, not tenths). The reason names the gap the image shows."""
    spec = BoardSpec.parse("aprilgrid:6x6:40mm:0.3")
    pts = spec.object_points(np.arange(spec.n_corners))
    r = Rotation.from_rotvec(np.radians([10, -15, 5])) * Rotation.from_rotvec([np.pi, 0, 0])
    t = np.array([0.0, 0.0, 300.0]) - r.apply(pts.mean(axis=0))
    img = render_target.render_boards(kind, [(spec, np.concatenate([r.as_rotvec(), t]))])
    assert detect_gray(img, spec).status == "used"
    for spacing in ("0.2", "0.4", "0.27"):
        res = detect_gray(img, BoardSpec.parse(f"aprilgrid:6x6:40mm:{spacing}"))
        assert res.status == "rejected" and res.ids is None
        assert f"its tags are 0.30 of a tag apart, the board's spec says {float(spacing):g}" in res.reason
