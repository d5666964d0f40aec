"""Detection: reports for bad input, grid placement, coverage, CLI (no real data needed)."""
from __future__ import annotations

import concurrent.futures as cf
import json

import cv2
import numpy as np
import pytest

from backend.cli import main as cli
from calib_core.board import BoardSpec
from calib_core.detection import detect, detect_image
from calib_core.detection.detect import detect_images
from calib_core.detection.grid import expand, gap_strides, lattice_score, place_grid, right_handed
from calib_core.errors import DataError
from calib_core.evaluation.coverage import coverage, empty_regions

BOARD = BoardSpec.parse("chessboard:6x5:10mm")


def board_image(cols=6, rows=5, sq=40, margin=60, shape=None) -> np.ndarray:
    """A fronto-parallel chessboard (cols × rows inner corners): the cell right-below corner 0 is white."""
    h, w = shape or (2 * margin + (rows + 1) * sq, 2 * margin + (cols + 1) * sq)
    y, x = np.mgrid[0:h, 0:w]
    i, j = np.floor((x - margin) / sq).astype(int), np.floor((y - margin) / sq).astype(int)
    inside = (i >= 0) & (i <= cols) & (j >= 0) & (j <= rows)
    img = np.where(inside & ((i + j) % 2 == 0), 255, 20).astype(np.uint8)
    img[~inside] = 235
    return cv2.GaussianBlur(img, (0, 0), 1.0)


@pytest.fixture()
def images(tmp_path):
    cv2.imwrite(str(tmp_path / "a_good.png"), board_image())
    cv2.imwrite(str(tmp_path / "b_blank.png"), np.full((360, 400), 128, np.uint8))
    (tmp_path / "c_broken.jpg").write_bytes(b"not an image at all")
    cv2.imwrite(str(tmp_path / "d_small.png"), board_image(margin=40))
    cv2.imwrite(str(tmp_path / "e_good.png"), cv2.flip(board_image(), -1))
    return tmp_path


def test_the_set_takes_the_size_of_its_boards_not_of_photos_without_one(tmp_path):
    """Three blank frames of another size (screenshots, frames without the board) and two
    board photos: the boards' size is the set's, and the blank frames say they show no board."""
    cv2.imwrite(str(tmp_path / "a_good.png"), board_image())
    cv2.imwrite(str(tmp_path / "b_good.png"), cv2.flip(board_image(), -1))
    for k in range(3):
        cv2.imwrite(str(tmp_path / f"c_blank{k}.png"), np.full((480, 640), 128, np.uint8))
    det = detect_images(tmp_path, BOARD, workers=1)
    assert det.observations is not None and det.observations.image_size == (400, 360)
    assert [v.name for v in det.observations.views] == ["a_good.png", "b_good.png"]
    assert {r.reason for r in det.reports if r.name.startswith("c_")} == {"board not found"}


def test_every_image_gets_a_plain_report(images):
    calls = []
    det = detect_images(images, BOARD, progress=lambda d, t: calls.append((d, t)), workers=2)
    rep = {r.name: r for r in det.reports}
    assert list(rep) == ["a_good.png", "b_blank.png", "c_broken.jpg", "d_small.png", "e_good.png"]
    assert rep["a_good.png"].status == "used" and rep["a_good.png"].n_corners == 30
    assert rep["b_blank.png"].reason == "board not found"
    assert rep["c_broken.jpg"].reason == "could not decode the file as an image"
    assert rep["d_small.png"].status == "rejected" and "resolution differs from the set" in rep["d_small.png"].reason
    assert sorted(calls) == [(k, 5) for k in range(1, 6)]
    assert det.observations.image_size == (400, 360)
    v = det.observations.view("a_good.png")
    assert sorted(v.ids.tolist()) == list(range(30))
    # Sub-pixel: the true corner of id r*6+c is at margin + (c+1)*sq - 0.5 (pixel-centre convention).
    truth = np.stack([60 + (v.ids % 6 + 1) * 40 - 0.5, 60 + (v.ids // 6 + 1) * 40 - 0.5], 1)
    err = np.linalg.norm(v.image_points - truth, axis=1)
    assert np.median(err) < 0.05
    # The upside-down copy: the square colours (not the image axes) decide which corner is id 0.
    np.testing.assert_allclose(det.observations.view("e_good.png").image_points[0],
                               [399 - v.image_points[0][0], 359 - v.image_points[0][1]], atol=0.1)


def test_serial_and_pool_agree(images, monkeypatch):
    a = detect_images(images, BOARD, workers=1)
    monkeypatch.setattr(detect, "POOL_PAYS_AFTER", 0.0)  # these few images would not start a pool
    b = detect_images(images, BOARD, workers=2)
    assert [r.to_json() for r in a.reports] == [r.to_json() for r in b.reports]


def test_a_set_quicker_than_a_pools_start_is_detected_on_threads(images, monkeypatch):
    def no_pool(*args, **kwargs):
        raise AssertionError("a pool was started for a set this process detects faster alone")

    threads = []
    real_threads = detect.cf.ThreadPoolExecutor

    def counted(*args, **kwargs):
        threads.append(args[0] if args else kwargs["max_workers"])
        return real_threads(*args, **kwargs)

    serial = detect_images(images, BOARD, workers=1)
    monkeypatch.setattr(detect.cf, "ProcessPoolExecutor", no_pool)
    monkeypatch.setattr(detect.cf, "ThreadPoolExecutor", counted)
    det = detect_images(images, BOARD, workers=2)
    assert threads == [2]
    assert [r.to_json() for r in det.reports] == [r.to_json() for r in serial.reports]


def test_a_dead_pool_leaves_its_images_to_the_threads(images, monkeypatch):
    def broken(*args, **kwargs):
        raise cf.process.BrokenProcessPool("a worker died")

    serial = detect_images(images, BOARD, workers=1)
    monkeypatch.setattr(detect, "POOL_PAYS_AFTER", 0.0)
    monkeypatch.setattr(detect.cf, "ProcessPoolExecutor", broken)
    det = detect_images(images, BOARD, workers=2, progress=lambda d, t: None)
    assert [r.to_json() for r in det.reports] == [r.to_json() for r in serial.reports]


def test_each_thread_has_its_own_marker_detector():
    from calib_core.detection.markers import detector

    mine = detector("DICT_6X6_250")
    assert detector("DICT_6X6_250") is mine
    with cf.ThreadPoolExecutor(1) as pool:
        other = pool.submit(detector, "DICT_6X6_250").result()
    assert other is not mine


def test_wrong_board_spec_is_explained(tmp_path):
    cv2.imwrite(str(tmp_path / "x.png"), board_image())
    cv2.imwrite(str(tmp_path / "y.png"), np.full((360, 400), 90, np.uint8))
    det = detect_images([tmp_path / "y.png"], BoardSpec.parse("chessboard:4x3:10mm"), workers=1)
    assert det.observations is None
    assert "chessboard of 4 × 3 inner corners was found in none of the 1 photos" in det.warnings[0]
    # A board smaller than the spec is a partial view of it: kept, as ids of the 9x6 board.
    det = detect_images([tmp_path / "x.png"], BoardSpec.parse("chessboard:9x6:10mm"), workers=1)
    assert det.reports[0].status == "used" and det.reports[0].n_corners == 30
    assert det.observations.views[0].ids.max() < 54


def test_missing_paths_are_clear_errors(tmp_path):
    with pytest.raises(DataError, match="no such file"):
        detect_images([tmp_path / "nope.png"], BOARD)
    with pytest.raises(DataError, match="no images in this folder"):
        detect_images([tmp_path], BOARD)


def test_right_handed_flips_mirrored_grids():
    c, r = np.meshgrid(np.arange(4.0), np.arange(3.0))
    grid = np.stack([c * 10, r * 10], -1)
    np.testing.assert_array_equal(right_handed(grid), grid)
    np.testing.assert_array_equal(right_handed(grid[:, ::-1]), grid)


def test_partial_grid_parity_and_oversize():
    img = board_image()
    c, r = np.meshgrid(np.arange(1, 4), np.arange(0, 3))  # a 3x3 patch starting at column 1
    grid = np.stack([60 + (c + 1) * 40 - 0.5, 60 + (r + 1) * 40 - 0.5], -1).astype(float)
    ids, pts = place_grid(grid, 6, 5, img)
    assert ids[0] % 2 == 1  # the dark cell under the patch's first corner needs an odd offset
    assert place_grid(np.zeros((6, 7, 2)), 6, 5, img) is None


def test_coverage_names_empty_regions():
    pts = np.array([[10.0, 10.0], [990.0, 10.0], [500.0, 400.0]])
    cov = coverage(pts, (1000, 750))
    assert cov["grid"] == [8, 6]
    assert sum(map(sum, cov["counts"])) == 3
    assert "top-left corner" not in cov["empty_regions"] and "bottom-left corner" in cov["empty_regions"]
    full = np.ones((6, 8), int)
    assert empty_regions(full) == []
    full[2:, -1] = 0
    assert empty_regions(full) == ["bottom-right corner", "right edge"]


def test_cli_detect_writes_observations(images, tmp_path, capsys):
    out = tmp_path / "obs.json"
    assert cli(["detect", str(images / "a_good.png"), str(images / "e_good.png"), "--board", "chessboard:6x5:10mm",
                "-o", str(out)]) == 0
    text = capsys.readouterr()
    assert "2/2 images used, 60 corners" in text.out and "detecting: 2/2 images" in text.err
    doc = json.loads(out.read_text())
    assert doc["format"] == "freecal.observations/1" and len(doc["views"]) == 2
    assert cli(["detect", str(images), "--board", "chessboard:9:10mm"]) == 2
    assert "expected a grid like 9x6" in capsys.readouterr().err


def test_images_too_small_or_undecodable_are_said_in_words_on_the_cli_alone(images, tmp_path, capfd, monkeypatch):
    """A 1 x 1 or 2 px high image crashed OpenCV's thresholds (its assertion text on stderr, numpy warnings
    from the image circle, a reason blaming the file); a 32-bit TIFF made OpenCV print its own warning."""
    cv2.imwrite(str(images / "f_dot.png"), np.zeros((1, 1), np.uint8))
    cv2.imwrite(str(images / "g_strip.png"), np.zeros((2, 500), np.uint8))
    cv2.imwrite(str(images / "h_float.tiff"), board_image().astype(np.float32) / 255)
    monkeypatch.setattr(detect, "POOL_PAYS_AFTER", 0.0)  # and from worker processes too
    assert cli(["detect", str(images), "--board", "chessboard:6x5:10mm", "--workers", "2", "-q",
                "-o", str(tmp_path / "obs.json")]) == 0
    out, err = capfd.readouterr()
    rows = {line.split()[0]: line for line in out.splitlines() if line.strip()}
    assert "too small to show a board: 1 x 1 px" in rows["f_dot.png"]
    assert "too small to show a board: 500 x 2 px" in rows["g_strip.png"]
    assert "could not decode the file as an image" in rows["h_float.tiff"]
    for raw in ("OpenCV", "WARN", "Traceback", "Warning"):
        assert raw not in err, err


def test_grids_that_skip_or_shear_board_lines_are_read_as_such():
    img = board_image()
    c, r = np.meshgrid(np.arange(6), np.arange(5))
    full = np.stack([60 + (c + 1) * 40 - 0.5, 60 + (r + 1) * 40 - 0.5], -1).astype(float)  # (5, 6, 2)
    assert [s.tolist() for s in gap_strides(full, img)] == [[1] * 4, [1] * 5]
    assert lattice_score(full, img) > 0.95
    skip = full[::2]                                   # rows 0, 2, 4: every other board line
    sr, sc = gap_strides(skip, img)
    assert sr.tolist() == [2, 2] and sc.tolist() == [1] * 5
    grown, real = expand(skip, sr, sc)
    np.testing.assert_allclose(grown, full)
    assert real.sum() == skip.shape[0] * skip.shape[1]
    ids, _ = place_grid(skip, 6, 5, img)
    assert sorted((ids // 6).tolist()) == [0] * 6 + [2] * 6 + [4] * 6  # board rows 0, 2, 4: the gaps kept
    # Two skipped lines: a gap of three squares reads one colour at its quarter points like a
    # single square; read as one, a whole row would take a wrong id.
    three = full[[0, 1, 4]]
    sr, sc = gap_strides(three, img)
    assert sr.tolist() == [1, 3] and sc.tolist() == [1] * 5
    ids, _ = place_grid(three, 6, 5, img)
    assert sorted((ids // 6).tolist()) == [0] * 6 + [1] * 6 + [4] * 6
    assert place_grid(full[[0, 1, 4]][:, [0, 3]], 4, 4, img) is None   # 5 rows once expanded: not this board
    # Four or five squares in one gap (a steep view's far end, which LARGER can step over):
    # read at quarter points as one square, the columns beyond would take wrong ids; they
    # are cut off instead, like unreadable gaps.
    assert gap_strides(full[:, [0, 1, 5]], img)[1].tolist() == [1, 0]     # a gap of four squares
    assert gap_strides(full[:, [0, 5]], img)[1].tolist() == [0]           # five
    ids, _ = place_grid(full[:, [0, 1, 5]], 6, 5, img)
    assert len(ids) == 10 and set((ids % 6).tolist()) <= {0, 1}
    sheared = full[:3, :3].copy()
    sheared[1:] = full[1:3, 1:4]                       # rows shifted by one column: a diagonal axis
    assert lattice_score(sheared, img) < 0.8


def tilted_board(cols: int, rows: int, invert: bool, sq: int = 80) -> tuple[np.ndarray, np.ndarray]:
    """A 1280 × 960 photo of a chessboard on a one-square paper margin (white-on-black and
    a black margin when ``invert``), 800 mm away, turned 35° about the vertical and rolled
    10°; and its true corners (N, 2)."""
    y, x = np.mgrid[0:(rows + 3) * sq, 0:(cols + 3) * sq]
    i, j = x // sq - 1, y // sq - 1
    on_squares = (i >= 0) & (i <= cols) & (j >= 0) & (j <= rows)
    light, dark = (20.0, 235.0) if invert else (235.0, 20.0)
    tex = np.where(on_squares, np.where((i + j) % 2 == 0, light, dark), dark if invert else light)
    t, q = np.radians(35.0), np.radians(-10.0)
    turn = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    rot = np.array([[np.cos(q), -np.sin(q), 0], [np.sin(q), np.cos(q), 0], [0, 0, 1]]) @ turn
    mm = 25.0 / sq   # texels to mm
    k = np.array([[1000.0, 0, 639.5], [0, 1000.0, 479.5], [0, 0, 1]])
    centre = np.array([tex.shape[1], tex.shape[0], 0.0]) / 2
    hom = k @ np.column_stack([rot[:, 0] * mm, rot[:, 1] * mm, rot @ (-centre * mm) + [0, 0, 800.0]])
    img = cv2.warpPerspective(tex.astype(np.float32), hom, (1280, 960), flags=cv2.INTER_AREA, borderValue=128)
    img = cv2.GaussianBlur(img, (0, 0), 0.8) + np.random.default_rng(0).normal(0, 2, img.shape)
    corners = np.array([[(c + 2) * sq - 0.5, (r + 2) * sq - 0.5] for r in range(rows) for c in range(cols)])
    truth = cv2.perspectiveTransform(corners.reshape(-1, 1, 2), hom).reshape(-1, 2)
    return np.clip(img, 0, 255).astype(np.uint8), truth


@pytest.mark.slow
@pytest.mark.parametrize("invert", [False, True])
def test_a_seed_grown_past_the_boards_edge_leaves_the_board_to_the_whole_pattern(invert):
    # Without the classic detector (a target's boards, a fisheye's image circle), a seed grew
    # over the board's edge onto the outer squares' corners against the margin: a grid one
    # row or column larger than the board, and a whole, sharp board rejected as "does not fit".
    img, truth = tilted_board(9, 6, invert)
    res = detect_image.detect_gray(img, BoardSpec.parse("chessboard:9x6:25mm"), classic_first=False)
    assert res.status == "used" and res.n_corners == 54
    assert np.linalg.norm(res.points[:, None] - truth[None], axis=2).min(axis=1).max() < 0.2
