"""freecal detect IMAGES_OR_DIR... --board SPEC -o OBS.json"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from calib_core.board import BoardSpec
from calib_core.detection.detect import Detection, detect_images
from calib_core.errors import DataError

from .output import table

BOARD_HELP = ("board spec: chessboard:COLSxROWS:SQUARE (inner corners, e.g. chessboard:9x6:25mm) or "
              "charuco:SXxSY:SQUARE:MARKER:DICT[:legacy] (e.g. charuco:5x7:40mm:20mm:DICT_6X6_250)")


def register(sub) -> None:
    p = sub.add_parser("detect", help="find board corners in photos",
                       description="Detect a chessboard or ChArUco board in images (all cores) and write "
                                   "freecal.observations/1 corners.")
    p.add_argument("images", nargs="+", help="image files and/or folders of images")
    p.add_argument("--board", required=True, help=BOARD_HELP)
    p.add_argument("-o", "--output", help="write the freecal.observations/1 JSON here")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    p.add_argument("--refine-with", metavar="CAL.json",
                   help="a first freecal.calibration/1 of this camera: predict every board corner through it "
                        "and keep those confirmed in the image (chessboards)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


class ProgressBar:
    """progress(done, total) → one redrawn line on stderr."""

    def __init__(self, quiet: bool = False, width: int = 30):
        self.quiet, self.width, self.t0 = quiet, width, time.perf_counter()

    def __call__(self, done: int, total: int) -> None:
        if self.quiet:
            return
        filled = int(self.width * done / max(total, 1))
        rate = done / max(time.perf_counter() - self.t0, 1e-9)
        end = "\n" if done >= total else ""
        print(f"\rdetecting [{'#' * filled}{'.' * (self.width - filled)}] {done}/{total} images "
              f"({rate:.1f}/s)", end=end, file=sys.stderr, flush=True)


def detect_with_report(images, board_spec: str, quiet: bool = False, workers: int | None = None,
                       calibration=None) -> Detection:
    """Detect, print the per-image table and warnings; DataError if no image was usable."""
    board = BoardSpec.parse(board_spec)
    det = detect_images(images, board, progress=ProgressBar(quiet), workers=workers, calibration=calibration)
    print_report(det)
    size = board_size_advice(det, board, images, workers)
    if det.observations is None:
        raise DataError((det.warnings[0] if det.warnings else "no image was usable") + (f"; {size}" if size else ""))
    if size:
        print(f"warning: {size}")
    return det


def board_size_advice(det: Detection, board: BoardSpec, images, workers: int | None) -> str | None:
    """The board's size the photos show when it is not --board's, as a --board to try (None when they agree)."""
    from calib_core.detection.board_size import suggest_size
    from calib_core.detection.detect import image_paths

    views = det.observations.views if det.observations is not None else []
    paths = image_paths([images] if isinstance(images, (str, Path)) else images)
    found = suggest_size(board, views, len(det.reports), paths, workers)
    if found is None:
        return None
    return f"{found.message(board)}; try --board {found.board(board).to_spec()}"


def print_report(det: Detection) -> None:
    rows = [(r.name, r.status, r.n_corners, "—" if r.sharpness is None else f"{r.sharpness:.2f}", r.reason or "")
            for r in det.reports]
    table(["image", "status", "corners", "edge width [px]", "reason"], rows)
    used = sum(r.status == "used" for r in det.reports)
    n = sum(r.n_corners for r in det.reports if r.status == "used")
    print(f"\n{used}/{len(det.reports)} images used, {n} corners")
    if det.model_added is not None:
        print(f"re-detection through the calibration added {det.model_added} corners")
    for w in det.warnings:
        print(f"warning: {w}")


def run(args) -> int:
    cal = None
    if args.refine_with:
        from calib_core.calibration import Calibration

        cal = Calibration.load(args.refine_with)
    det = detect_with_report(args.images, args.board, args.quiet, args.workers, cal)
    if args.output:
        det.observations.extra["coverage"] = det.coverage
        det.observations.save(args.output)
        print(f"wrote {args.output}")
    return 0
