"""Board spec strings, the formats.md board object, corner geometry."""
import cv2
import numpy as np
import pytest

from calib_core import synth
from calib_core.board import BoardSpec
from calib_core.errors import FormatError, SettingsError


def test_parse_chessboard_and_units():
    b = BoardSpec.parse("chessboard:9x6:25mm")
    assert (b.type, b.cols, b.rows, b.square_size) == ("chessboard", 9, 6, 25.0)
    assert BoardSpec.parse("chessboard:9x6:2.5cm").square_size == pytest.approx(25.0)
    assert BoardSpec.parse("chessboard:9x6:0.025m").square_size == pytest.approx(25.0)
    assert b.to_json() == {"type": "chessboard", "cols": 9, "rows": 6, "square_size": 25.0, "units": "mm"}


def test_parse_charuco_and_legacy():
    b = BoardSpec.parse("charuco:5x7:40mm:20mm:DICT_6X6_250")
    assert (b.cols, b.rows, b.marker_size, b.dictionary, b.legacy) == (5, 7, 20.0, "DICT_6X6_250", False)
    assert BoardSpec.parse("charuco:5x7:40mm:20mm:DICT_6X6_250:legacy").legacy
    assert b.to_json()["squares_x"] == 5 and b.to_json()["squares_y"] == 7


@pytest.mark.parametrize("spec", ["chessboard:9x6:25mm", "charuco:5x7:40mm:20mm:DICT_6X6_250:legacy"])
def test_json_and_spec_round_trip(spec):
    b = BoardSpec.parse(spec)
    assert BoardSpec.from_json(b.to_json()) == b
    assert BoardSpec.parse(b.to_spec()) == b


@pytest.mark.parametrize("spec, words", [
    ("", "empty"), ("chessboard:9x6", "COLSxROWS:SQUARE"), ("chessboard:9by6:25mm", "grid like 9x6"),
    ("chessboard:9x6:25 inches", "length"), ("circles:4x11:20mm", "unknown board type"),
    ("charuco:5x7:40mm:20mm:DICT_NOPE", "dictionary"), ("charuco:5x7:20mm:40mm:DICT_6X6_250", "smaller than the square"),
    ("chessboard:1x6:25mm", "at least 2x2"), ("charuco:5x7:40mm:20mm:DICT_6X6_250:new", "legacy"),
])
def test_bad_specs_say_what_to_do(spec, words):
    with pytest.raises(SettingsError, match=words):
        BoardSpec.parse(spec)


def test_from_json_rejects_bad_documents():
    with pytest.raises(FormatError, match="board.type"):
        BoardSpec.from_json({"type": "dots"})
    with pytest.raises(FormatError, match="board.cols"):
        BoardSpec.from_json({"type": "chessboard", "cols": "9", "rows": 6, "square_size": 1})


def test_chessboard_object_points_follow_formats_ids():
    b = BoardSpec.parse("chessboard:22x22:50mm")
    ids = np.arange(22 * 22)
    np.testing.assert_array_equal(b.object_points(ids), synth.board_points(22, 22, 50.0))
    np.testing.assert_array_equal(BoardSpec.parse("chessboard:9x6:25mm").object_points([10]), [[25.0, 25.0, 0.0]])
    with pytest.raises(SettingsError):
        b.object_points([22 * 22])


def test_charuco_object_points_match_opencv():
    b = BoardSpec.parse("charuco:5x7:40mm:20mm:DICT_6X6_250")
    np.testing.assert_allclose(b.object_points(np.arange(24)), b.cv_charuco().getChessboardCorners())
    assert b.cv_charuco().getLegacyPattern() is False
    assert isinstance(b.cv_charuco(), cv2.aruco.CharucoBoard)
