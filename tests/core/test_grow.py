"""Growing a detected lattice over the whole visible board (grow.py, saddle.py, model_guided.py)."""
from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest

from calib_core import synth
from calib_core.board import BoardSpec
from calib_core.calibration import Calibration
from calib_core.detection import image_circle
from calib_core.detection.corner_error import best_motion
from calib_core.detection.detect_image import detect_gray
from calib_core.detection.grow import Lattice, grow_board
from calib_core.detection.image_circle import distance_to_unlit
from calib_core.detection.model_guided import model_guided
from calib_core.models.fisheye import FisheyeModel
from calib_core.synth import render

BOARD = BoardSpec.parse("chessboard:22x22:50mm")


@functools.cache
def _view(k: int):
    """Rendered fisheye training view k: image and exact corners (ids, pixels)."""
    s = synth.generate("fisheye", 0.0, 0, 10)
    v = s.truth["train_views"][k]
    pose = np.array(v["rvec"] + v["tvec"])
    img = render.render_view("fisheye", pose, rng=np.random.default_rng(k))
    ids, _, uv = render.true_corners("fisheye", pose)
    return img, ids, uv


def _against_truth(ids, pts, true_ids, true_uv):
    """Per detected corner: the true id it maps to through the view's lattice motion, and the
    distance to that corner's true pixel (partial-board ids are defined up to that motion)."""
    ours = np.stack([ids % 22, ids // 22], 1)
    d = np.linalg.norm(pts[:, None] - true_uv[None], axis=-1)
    near = d.argmin(1)
    m = d[np.arange(len(pts)), near] < 1.0
    rot, t = best_motion(ours[m], np.stack([true_ids[near[m]] % 22, true_ids[near[m]] // 22], 1))
    mapped = ours @ rot.T + t
    mapped_ids = mapped[:, 1] * 22 + mapped[:, 0]
    lookup = {int(i): k for k, i in enumerate(true_ids)}
    k = np.array([lookup.get(int(i), -1) for i in mapped_ids])
    assert (k >= 0).all(), "a corner mapped to no true corner: a wrong id"
    return k, np.linalg.norm(pts - true_uv[k], axis=1)


@pytest.mark.slow
def test_grown_grid_reaches_the_image_edge_with_true_ids():
    """View 3: the board runs off the right edge of the frame, bending hard there."""
    img, true_ids, true_uv = _view(3)
    res = detect_gray(img, BOARD)
    assert res.status == "used"
    k, err = _against_truth(res.ids, res.points, true_ids, true_uv)
    assert len(set(k.tolist())) == len(k)                      # one detected corner per true corner
    assert np.median(err) < 0.1 and err.max() < 1.0, (np.median(err), err.max())
    w = synth.IMAGE_SIZE[0]
    edge = true_uv[:, 0] > w - 60                               # true corners within 60 px of the right edge
    found = np.isin(np.arange(len(true_ids)), k)
    assert edge.sum() >= 10 and found[edge].mean() >= 0.8, (edge.sum(), found[edge].mean())
    assert len(res.ids) >= 0.95 * len(true_ids), (len(res.ids), len(true_ids))


def test_a_calibration_predicts_the_rest_of_the_board_from_a_small_patch():
    img, true_ids, true_uv = _view(3)
    fx, fy, cx, cy = synth.INTRINSICS
    model = FisheyeModel(np.array([fx, fy, cx, cy, 0.0]), [0.05, 0.02, 0.01, 0.005])  # the true lens
    patch = np.isin(true_ids // 22, [10, 11, 12]) & np.isin(true_ids % 22, [10, 11, 12])
    hook = model_guided(img, model, 50.0)
    lat = Lattice.of(true_ids[patch], true_uv[patch], 22, 22)   # the exact corners of a 3 x 3 patch
    assert hook(lat, distance_to_unlit(img)) >= 300             # one pass through the model finds most of the board
    i, j = np.nonzero(lat.known)
    grown = grow_board(img, (i - 22) * 22 + (j - 22), lat.p[i, j], 22, 22, after_growth=hook)
    k, err = _against_truth(grown.ids, grown.points, true_ids, true_uv)
    assert err.max() < 1.0 and np.median(err) < 0.1


@pytest.mark.slow
def test_detect_images_reports_what_the_calibration_added(tmp_path):
    import cv2

    from calib_core.detection.detect import detect_images

    img, _, _ = _view(3)
    cv2.imwrite(str(tmp_path / "v.png"), img)
    cv2.imwrite(str(tmp_path / "blank.png"), np.full((1280, 1024), 128, np.uint8))
    fx, fy, cx, cy = synth.INTRINSICS
    cal = Calibration(FisheyeModel(np.array([fx, fy, cx, cy, 0.0]), [0.05, 0.02, 0.01, 0.005]), synth.IMAGE_SIZE,
                      "fisheye")
    det = detect_images(tmp_path, BOARD, workers=1, calibration=cal)
    assert det.model_added is not None and det.model_added >= 0
    blank = next(r for r in det.reports if r.name == "blank.png")
    assert blank.status == "rejected" and blank.reason == "board not found"   # plain words, no OpenCV text
    plain = detect_images(tmp_path, BOARD, workers=1)
    assert plain.model_added is None
    assert det.observations.n_points >= plain.observations.n_points


def test_corners_one_step_off_fail_the_colour_test():
    """A corner given the id of its neighbour (one column over) has the wrong square colours
    around it: it is dropped, never kept under the wrong id."""
    from calib_core.detection import corner_refine, saddle
    from calib_core.detection.grow import Lattice, lattice_steps

    img, true_ids, true_uv = _view(0)
    lat = Lattice.of(true_ids, true_uv, 22, 22)
    e_col, e_row = lattice_steps(lat.p)
    k = lat.known & np.isfinite(e_col[..., 0]) & np.isfinite(e_row[..., 0])
    even = lat.even()[k]
    half = corner_refine.half_window(corner_refine.nearest_corner(e_col[k], e_row[k]))
    right = saddle.is_corner(img, lat.p[k], e_col[k], e_row[k], even, half)
    wrong = saddle.is_corner(img, lat.p[k], e_col[k], e_row[k], ~even, half)
    assert right.mean() > 0.9
    assert wrong.mean() < 0.01


def test_the_unlit_frame_is_found_however_little_of_it_touches_the_border():
    """The shortcut for frames lit to the border gives what the full search gives."""
    rng = np.random.default_rng(3)
    lit = rng.integers(40, 255, (120, 160), dtype=np.uint8)
    assert np.all(image_circle.distance_to_unlit(lit) >= 1e8)
    circle = lit.copy()
    yy, xx = np.mgrid[:120, :160]
    circle[(xx - 80) ** 2 + (yy - 60) ** 2 > 55 ** 2] = 0  # a fisheye's black frame
    d = image_circle.distance_to_unlit(circle)
    assert d[60, 80] > 40 and d[2, 2] == 0
    for row in (0, image_circle.BLUR_REACH - 2):  # a dark patch at the border, and one just inside the blur's reach
        patch = lit.copy()
        patch[row : row + 12, 70:110] = 0
        slow = (cv2.GaussianBlur(patch, (0, 0), image_circle.BLUR_SIGMA) < image_circle.UNLIT)
        touches = slow[0].any()
        assert (image_circle.distance_to_unlit(patch).min() == 0) == touches


def _blurred_corner(tag_bits: bool, square: float = 24.0) -> np.ndarray:
    """An 80 px checker corner at (40.5, 39.5), blurred; with tag_bits, a bright patch in the
    dark square to its upper right from 0.15 of a square out, as a tag's white bits are."""
    y, x = np.mgrid[0:80, 0:80].astype(float)
    u, v = x - 40.3, 39.6 - y
    img = np.where((u > 0) ^ (v > 0), 200.0, 40.0)
    if tag_bits:
        img[(u > 0.15 * square) & (u < 0.45 * square) & (v > 0.15 * square) & (v < 0.45 * square)] = 200.0
    return cv2.GaussianBlur(img, (0, 0), 1.2).astype(np.uint8)


def test_a_saddle_that_moves_with_the_window_is_not_located():
    """corner_refine.located: a clean corner's saddle is the same for every window; where a
    tag's bright bits lie inside the window it follows the window (here 1.9 px off with a
    half-window of 6), and the corner is not located; nor is a point with no saddle."""
    from calib_core.detection import corner_refine
    start = np.array([[40.0, 40.0]])
    for h in (3, 6, 8):
        p, det, sure = corner_refine.saddle_points(_blurred_corner(False), start, np.array([h]))
        assert sure[0] and det[0] < 0 and np.linalg.norm(p[0] - [40.5, 39.5]) < 0.05
    p, _, sure = corner_refine.saddle_points(_blurred_corner(True), start, np.array([6]))
    assert not sure[0] and np.linalg.norm(p[0] - [40.5, 39.5]) > 1.0
    _, _, sure = corner_refine.saddle_points(np.full((80, 80), 90, np.uint8), start, np.array([6]))
    assert not sure[0]


def test_a_partial_board_seeded_the_other_way_round_grows_over_all_of_it():
    """A view shows 8 x 8 corners of an 11 x 8 board at first: its seed may be placed either way
    round, and was grown within the board's size in the way it was placed. Where the board goes
    on along the other axis (views rendered through lenses drawn at random: 3 of 48 lost 3
    columns), growth now keeps both ways open until the lattice outgrows the shorter side."""
    cols, rows, square = 11, 8, 50.0
    rot = cv2.Rodrigues(np.radians([8.0, -6.0, 3.0]))[0]
    pose = np.r_[cv2.Rodrigues(rot)[0].ravel(), -rot @ [250.0, 175.0, 0.0] + [0.0, 0.0, 700.0]]
    img = render.render_view("radial", pose, (cols, rows), square, rng=np.random.default_rng(0))
    true_ids, _, true_uv = render.true_corners("radial", pose, (cols, rows), square)
    assert len(true_ids) == cols * rows
    r, c = true_ids // cols, true_ids % cols
    seed = c < 8  # the first 8 columns, every row: 8 x 8
    turned = c[seed] * cols + r[seed]  # placed the other way round: true columns as rows
    grown = grow_board(img, turned, true_uv[seed], cols, rows)
    assert len(grown.ids) == cols * rows and grown.added == cols * rows - 64
    d = np.linalg.norm(grown.points[:, None] - true_uv[None], axis=-1)
    near = d.argmin(1)
    assert d[np.arange(len(near)), near].max() < 0.5 and len(set(near.tolist())) == len(near)
    ours = np.stack([grown.ids % cols, grown.ids // cols], 1)
    truth = np.stack([true_ids[near] % cols, true_ids[near] // cols], 1)
    motion, shift = best_motion(ours, truth)  # the ids are right up to a motion of the lattice
    assert np.array_equal(ours @ motion.T + shift, truth)


@pytest.mark.parametrize("parity", [0, 1])
def test_a_lattice_grown_the_other_way_round_is_turned_not_mirrored(parity):
    """A partial view's seed is placed one way round; growth can show it lies the other way
    (8 rows of corners on a 9 x 6 board's 6-row side). Its ids then turn a quarter: a transpose
    mirrored the board (seen: a probe's corner view, every corner left-handed), which no pose
    of a board seen from the front can take back. The square colours stay where they were."""
    rows, cols = 6, 9
    p = np.full((3 * rows, 3 * cols, 2), np.nan)
    r, c = np.mgrid[rows:rows + 8, cols:cols + 5]                  # 8 rows x 5 columns of corners
    p[r, c] = np.stack([30.0 * c + 3.0 * r, 30.0 * r - 2.0 * c], -1)  # image x right, y down: right-handed
    lat = Lattice(p, rows, cols, cols, rows, parity)
    ids, pts = lat.placed()
    assert ids.min() >= 0 and ids.max() < rows * cols and len(ids) == 40
    at = dict(zip(ids.tolist(), pts, strict=True))
    turns = [_turn(at[i + 1] - at[i], at[i + cols] - at[i]) for i in at if i + 1 in at and i + cols in at
             and i % cols != cols - 1]
    assert len(turns) > 20 and all(t > 0 for t in turns)            # board x cross board y: right-handed
    # The colours: each corner's id parity against its square colours (``even``), one relation
    # for every corner and the same as for a lattice placed without a turn (5 x 8, same parity).
    upright = Lattice(np.full_like(p, np.nan), rows, cols, cols, rows, parity)
    r, c = np.mgrid[rows:rows + 5, cols:cols + 8]
    upright.p[r, c] = np.stack([30.0 * c, 30.0 * r], -1)
    assert _colour_relation(lat, ids, pts, cols) == _colour_relation(upright, *upright.placed(), cols)


def _turn(a: np.ndarray, b: np.ndarray) -> float:
    """z of a × b for image vectors (x right, y down): positive when b is a right turn from a."""
    return float(a[0] * b[1] - a[1] * b[0])


def _colour_relation(lat: Lattice, ids: np.ndarray, pts: np.ndarray, cols: int) -> set[bool]:
    """Whether each placed corner's square colours (``Lattice.even``) agree with its id's parity."""
    even = {tuple(pt): e for pt, e in zip(lat.p[lat.known], lat.even()[lat.known], strict=True)}
    return {bool(even[tuple(pt)] == ((i // cols + i % cols) % 2 == 0)) for i, pt in zip(ids, pts, strict=True)}
