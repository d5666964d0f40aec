"""Coverage inside a fisheye's image circle: the circle found in the photos, only the
cells inside it counted, and advice that never names the unlit frame around it."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from calib_core.board import BoardSpec
from calib_core.detection.detect import detect_images
from calib_core.detection.image_circle import common_circle, find_image_circle
from calib_core.evaluation.coverage import (
    RIM_DIRECTIONS,
    RIM_SUFFIX,
    cells_inside,
    coverage,
    coverage_warning,
)
from calib_core.observations import Observations
from calib_core.report.tables import coverage_of
from tests.conftest import shared_data
from tests.core.test_detect import board_image

SIZE = (1280, 800)
CIRCLE = (648.0, 404.0, 480.0)      # BabelCalib ov_plane's: cut by the frame's top and bottom, black corners
RIM_NAMES = {d + RIM_SUFFIX for d in RIM_DIRECTIONS}


def fisheye_frame(content: np.ndarray, circle=CIRCLE, black: int = 16) -> np.ndarray:
    """``content`` (H, W) seen through a lens whose light ends at ``circle``: video black outside."""
    h, w = content.shape
    yy, xx = np.mgrid[:h, :w]
    cx, cy, r = circle
    out = np.where((xx - cx) ** 2 + (yy - cy) ** 2 <= r * r, content, black).astype(np.uint8)
    return cv2.GaussianBlur(out, (0, 0), 1.5)   # a soft rim, as a lens gives


def points_in_disc(circle, n: int = 4000, within: float = 0.97, seed: int = 0) -> np.ndarray:
    cx, cy, r = circle
    rng = np.random.default_rng(seed)
    rad, ang = within * r * np.sqrt(rng.random(n)), 2 * np.pi * rng.random(n)
    pts = np.column_stack([cx + rad * np.cos(ang), cy + rad * np.sin(ang)])
    return pts[(pts[:, 0] >= 0) & (pts[:, 0] < SIZE[0]) & (pts[:, 1] >= 0) & (pts[:, 1] < SIZE[1])]


def test_the_circle_is_found_however_dark_the_scene_inside_it():
    rng = np.random.default_rng(1)
    scene = rng.integers(60, 230, SIZE[::-1]).astype(np.uint8)
    scene[:, :300] = 20            # a dark stretch of the scene that reaches the rim on the left
    cx, cy, r = find_image_circle(fisheye_frame(scene))
    assert abs(cx - CIRCLE[0]) < 4 and abs(cy - CIRCLE[1]) < 4 and abs(r - CIRCLE[2]) < 6


def test_an_image_lit_to_its_border_has_no_circle():
    rng = np.random.default_rng(2)
    photo = rng.integers(30, 230, (600, 800)).astype(np.uint8)
    assert find_image_circle(photo) is None
    vignetted = photo.copy()
    vignetted[:40, :40] = 0        # a dark corner is not an image circle
    assert find_image_circle(vignetted) is None


@pytest.mark.parametrize("shape", [(5, 7), (20, 30), (1, 1)])
def test_frames_of_a_few_pixels_have_no_circle_and_no_error(shape):
    assert find_image_circle(np.zeros(shape, np.uint8)) is None
    small = np.zeros(shape, np.uint8)
    small[shape[0] // 2, shape[1] // 2] = 255
    find_image_circle(small)   # whatever it says, it says it without an exception


def test_real_fisheye_photos_give_their_circle_and_gopro_photos_none():
    fisheye = sorted((shared_data("babelcalib-ov-plane-fisheye") / "train").glob("*.png"))[:3]
    circles = [find_image_circle(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)) for p in fisheye]
    cx, cy, r = common_circle(circles)
    assert abs(cx - 648) < 8 and abs(cy - 404) < 8 and abs(r - 480) < 8
    gopro = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))[:2]
    assert [find_image_circle(cv2.imread(str(p), cv2.IMREAD_GRAYSCALE)) for p in gopro] == [None, None]


def test_a_set_has_a_circle_only_when_most_of_its_photos_show_it():
    assert common_circle([CIRCLE, None, (650.0, 400.0, 478.0)]) == pytest.approx((649.0, 402.0, 479.0))
    assert common_circle([CIRCLE, None, None]) is None
    assert common_circle([]) is None


def test_a_full_circle_of_corners_leaves_no_advice_though_the_frame_corners_are_black():
    pts = points_in_disc(CIRCLE)
    plain = coverage(pts, SIZE)
    assert "top-left corner" in plain["empty_regions"]          # what the advice said before: the unlit corners
    cov = coverage(pts, SIZE, circle=CIRCLE)
    assert cov["empty_regions"] == [] and coverage_warning(cov) is None
    inside = np.asarray(cov["inside"])
    assert not inside[0, 0] and not inside[-1, -1] and inside[2, 4]
    assert cov["fraction_covered"] == 1.0 and cov["image_circle"] == {"cx": 648.0, "cy": 404.0, "radius": 480.0}


def test_advice_names_only_stretches_of_the_circle_and_where_the_gap_is():
    pts = points_in_disc(CIRCLE)
    gap = (pts[:, 0] < CIRCLE[0] - 150) & (pts[:, 1] < CIRCLE[1] - 100)   # nothing at the upper left
    cov = coverage(pts[~gap], SIZE, circle=CIRCLE)
    assert "top-left" + RIM_SUFFIX in cov["empty_regions"]
    assert set(cov["empty_regions"]) <= RIM_NAMES and "right" + RIM_SUFFIX not in cov["empty_regions"]
    text = coverage_warning(cov)
    assert text.startswith("no corners near the edge of the image circle at the top-left")
    assert "corner of" not in text and "of the image:" not in text


def test_a_cell_counts_when_at_least_half_of_it_is_inside_the_circle():
    inside = cells_inside((400.0, 400.0, 400.0), (2, 2), (800, 800))
    assert inside.all()                                       # each quarter is π/4 ≈ 79 % inside
    assert not cells_inside((100.0, 100.0, 50.0), (2, 2), (800, 800)).any()


def test_ordinary_images_keep_their_coverage_unchanged():
    pts = np.array([[10.0, 10.0], [990.0, 10.0], [500.0, 400.0]])
    cov = coverage(pts, (1000, 750))
    assert set(cov) == {"grid", "counts", "fraction_covered", "empty_regions"}
    assert coverage_warning(cov).endswith("of the image: the lens is least known there; "
                                          "add views with the board in those regions")


def test_detection_records_the_circle_and_advises_inside_it(tmp_path):
    """Photos of a board in a fisheye's lit disc: the set's circle goes into the observations
    (so the report draws it) and the advice names no corner of the frame."""
    board = BoardSpec.parse("chessboard:6x5:10mm")
    img = board_image(shape=(480, 640), margin=200)
    circle = (320.0, 240.0, 230.0)
    for k in range(2):
        cv2.imwrite(str(tmp_path / f"fish_{k}.png"), fisheye_frame(np.roll(img, 20 * k, axis=1), circle))
    det = detect_images(tmp_path, board, workers=1)
    assert det.observations is not None and len(det.observations.views) == 2
    # the rim is where any light is (a few px past the soft edge): close enough for cells of 80 px
    assert det.image_circle == pytest.approx(circle, abs=5)
    assert det.observations.image_circle == pytest.approx(circle, abs=5)
    assert det.coverage["empty_regions"] and set(det.coverage["empty_regions"]) <= RIM_NAMES
    assert not any("corner of the image" in w or "corner, " in w for w in det.warnings)
    again = coverage_of(Observations.from_json(det.observations.to_json()))   # the report's, from the file
    assert again["image_circle"] == det.coverage["image_circle"] and again["inside"] == det.coverage["inside"]
