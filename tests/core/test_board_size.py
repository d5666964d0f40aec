"""The board's size from the photos: a grid grown without a size spans the board's inner corners,
so a size given wrong (squares counted, another board) is caught and the right one suggested."""
from __future__ import annotations

import numpy as np
import pytest

from calib_core.board import BoardSpec
from calib_core.detection.board_size import probe_file, suggest_size
from calib_core.observations import View

from ..conftest import shared_data
from ..rendered_boards import whole_board_photos


def views_on(board: BoardSpec, n: int, cols: int, rows: int) -> list[View]:
    """``n`` views whose corners span a cols × rows grid on ``board`` (ids as the detector places them)."""
    ids = np.array([r * board.cols + c for r in range(rows) for c in range(cols)])
    return [View(f"v{k}", board.object_points(ids), np.zeros((len(ids), 2)), ids) for k in range(n)]


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    return whole_board_photos(tmp_path_factory.mktemp("rendered"), n=4)


@pytest.mark.slow
def test_rendered_photos_show_their_board_and_sizes_given_wrong_are_corrected(rendered):
    assert [probe_file(p)[:2] for p in rendered] == [(9, 6)] * 4
    right = BoardSpec.parse("chessboard:9x6:50mm")
    assert suggest_size(right, views_on(right, 4, 9, 6), 4, rendered) is None
    squares = BoardSpec.parse("chessboard:10x7:50mm")     # squares counted: found, but never whole
    s = suggest_size(squares, views_on(squares, 4, 9, 6), 4, rendered)
    assert (s.cols, s.rows, s.n_photos, s.n_images) == (9, 6, 4, 4)
    assert s.board(squares).to_spec() == "chessboard:9x6:50mm"
    assert "9 × 6 inner corners" in s.message(squares) and "--board" not in s.message(squares)
    small = BoardSpec.parse("chessboard:6x4:50mm")        # another board's size: a part of this one found
    assert (suggest_size(small, views_on(small, 4, 6, 4), 4, rendered).cols, 6) == (9, 6)
    assert suggest_size(small, [], 4, rendered).rows == 6   # or nothing found at all


def test_a_photo_of_many_pixels_is_probed_on_a_reduced_copy_and_still_shows_its_board(tmp_path):
    """A 13 MP photo is probed as detection reads it, on a copy of about 3 MP: the lattice's size is the
    same (and a blank 49 MP photo, probed at full size, held a service worker for minutes)."""
    import cv2

    sq, margin = 380, 300
    h, w = 7 * sq + 2 * margin, 10 * sq + 2 * margin
    y, x = np.mgrid[0:h, 0:w]
    i, j = (x - margin) // sq, (y - margin) // sq
    inside = (x >= margin) & (y >= margin) & (i <= 9) & (j <= 6)
    img = np.where(inside & ((i + j) % 2 == 0), 30, 225).astype(np.uint8)
    assert h * w > 12e6
    cv2.imwrite(str(tmp_path / "big.png"), cv2.GaussianBlur(img, (0, 0), 2.0))
    assert probe_file(tmp_path / "big.png")[:2] == (9, 6)


def test_too_few_or_mixed_grids_suggest_nothing():
    board = BoardSpec.parse("chessboard:16x10:26mm")
    assert suggest_size(board, views_on(board, 1, 15, 9), 1) is None          # one view tells nothing
    mixed = views_on(board, 2, 15, 9) + views_on(board, 2, 12, 7) + views_on(board, 2, 11, 5)
    assert suggest_size(board, mixed + views_on(board, 2, 9, 4), 8) is None   # partial views, no mode
    assert suggest_size(BoardSpec.parse("charuco:5x7:40mm:20mm:DICT_6X6_250"), [], 5) is None


@pytest.mark.slow
def test_gopro_photos_show_a_15_by_9_board():
    photos = sorted(shared_data("gopro-hero3-wide-15x9").glob("*.JPG"))[:3]
    assert [probe_file(p)[:2] for p in photos] == [(15, 9)] * 3
    given = BoardSpec.parse("chessboard:9x6:26mm")
    s = suggest_size(given, [], len(photos), photos)
    assert (s.cols, s.rows, s.n_photos) == (15, 9, 3)
