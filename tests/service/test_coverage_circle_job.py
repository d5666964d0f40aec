"""The set's detection job (in process, no server): a fisheye's image circle is stored with
the set's coverage and in its observations, and the set's advice names no unlit corner."""
from __future__ import annotations

import cv2
import numpy as np

from backend.base.context import Context
from backend.base.repository import sets
from backend.base.settings import Settings
from backend.queue import detect_job
from calib_core.board import BoardSpec
from tests.core.test_coverage_circle import RIM_NAMES, fisheye_frame
from tests.core.test_detect import board_image


class NoLease:
    """A JobRun that only takes progress: the job runs outside the queue."""

    def progress(self, *args) -> None:
        pass


def test_the_detection_job_stores_the_circle_and_advises_inside_it(tmp_path):
    ctx = Context.open(Settings.from_env({}, data_dir=tmp_path / "data"))
    board = BoardSpec.parse("chessboard:6x5:10mm")
    names = ["fish_0.png", "fish_1.png"]
    sets.create(ctx.db, "s1", "fisheye", "upload", board.to_json(), names)
    folder = ctx.storage.images_dir("s1")
    folder.mkdir(parents=True, exist_ok=True)
    img = board_image(shape=(480, 640), margin=200)
    for k, name in enumerate(names):
        cv2.imwrite(str(folder / name), fisheye_frame(np.roll(img, 20 * k, axis=1), (320.0, 240.0, 230.0)))
    detect_job.run(ctx, {"set_id": "s1", "settings": {"board": board.to_spec()}}, NoLease())
    row = sets.get(ctx.db, "s1")
    cov = row["coverage"]
    assert abs(cov["image_circle"]["radius"] - 230) < 5 and not cov["inside"][0][0]
    assert cov["empty_regions"] and set(cov["empty_regions"]) <= RIM_NAMES
    advice = [w for w in row["warnings"] if w.startswith("no corners")]
    assert len(advice) == 1 and advice[0].startswith("no corners near the edge of the image circle"), row["warnings"]
    obs = (ctx.storage.observations_path("s1")).read_text()
    assert '"image_circle"' in obs
