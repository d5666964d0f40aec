"""Real photo sets of ../shared/data, detected and calibrated once per session
(skipped when the data is absent): the calibrations the exports were checked on."""
from __future__ import annotations

import functools

from calib_core import Calibration, calibrate
from calib_core.board import BoardSpec
from calib_core.detection.detect import detect_images
from calib_core.observations import Observations

from ..conftest import shared_data

SETS = {  # name → (folder, board, images)
    "gopro": ("gopro-hero3-wide-15x9", "chessboard:15x9:26mm", "*.JPG"),
}


@functools.cache
def observations(name: str) -> Observations:
    folder, board, pattern = SETS[name]
    det = detect_images(sorted(shared_data(folder).glob(pattern)), BoardSpec.parse(board))
    assert det.observations is not None
    return det.observations


@functools.cache
def calibration(name: str, method: str) -> Calibration:
    return calibrate(observations(name), method)
