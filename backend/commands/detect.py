"""freecal detect IMAGES_OR_DIR... --board SPEC -o OBS.json | --json"""
from __future__ import annotations

from pathlib import Path

from calib_core.board import BoardSpec
from calib_core.detection.detect import Detection, detect_images
from calib_core.errors import DataError, SettingsError
from calib_core.target import Target

from .inputs import load_calibration
from .output import claim_stdout, json_text, table, write_data
from .outputs import Outputs
from .progress import CountProgress

BOARD_HELP = ("board spec: chessboard:COLSxROWS:SQUARE (inner corners, e.g. chessboard:9x6:25mm), "
              "charuco:SXxSY:SQUARE:MARKER:DICT[:legacy] (e.g. charuco:5x7:40mm:20mm:DICT_6X6_250) or "
              "aprilgrid:TAGSXxTAGSY:TAG:SPACING (Kalibr's, e.g. aprilgrid:6x6:88mm:0.3)")
TARGET_HELP = ("a freecal.target/1 JSON file (docs/targets.md): several boards, each with its pose on one "
               "calibration object; each image then gives one view of the object with 3-D object points")


def register(sub) -> None:
    p = sub.add_parser("detect", help="find board corners in photos",
                       description="Detect a chessboard or ChArUco board in images (all cores) and write "
                                   "freecal.observations/1 corners.")
    p.add_argument("images", nargs="+", help="image files and/or folders of images")
    p.add_argument("--board", help=BOARD_HELP)
    p.add_argument("--target", metavar="T.json", help=TARGET_HELP + " (instead of --board)")
    p.add_argument("-o", "--output", metavar="OBS.json",
                   help="write the freecal.observations/1 JSON here (- : standard output)")
    p.add_argument("--json", action="store_true",
                   help="print only the observations JSON on standard output (the per-image table goes to "
                        "standard error), e.g. to pipe into freecal calibrate -")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: all cores)")
    p.add_argument("--refine-with", metavar="CAL.json",
                   help="a first freecal.calibration/1 of this camera (- : standard input): predict every board "
                        "corner through it and keep those confirmed in the image (chessboards)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def board_of(board_spec: str | None, target_path: str | None = None) -> BoardSpec | Target:
    """The board of --board SPEC, or the boards of --target T.json (exactly one of them)."""
    if (board_spec is None) == (target_path is None):
        raise SettingsError("say what the images show: --board SPEC (one board, e.g. chessboard:9x6:25mm) or "
                            "--target T.json (several boards on one object), not both")
    return BoardSpec.parse(board_spec) if board_spec is not None else Target.load(str(target_path))


def detect_with_report(images, board_spec: str | None, quiet: bool = False, workers: int | None = None,
                       calibration=None, target_path: str | None = None) -> Detection:
    """Detect, print the per-image table and warnings; DataError if no image was usable."""
    board = board_of(board_spec, target_path)
    if isinstance(board, Target) and calibration is not None:
        raise SettingsError("--refine-with works with --board (one board), not with --target")
    with CountProgress(quiet) as progress:
        det = detect_images(images, board, progress=progress, workers=workers, calibration=calibration)
    print_report(det)
    size = None if isinstance(board, Target) else board_size_advice(det, board, images, workers)
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
    if any(r.boards is not None for r in det.reports):  # a target: which boards each image shows
        rows = [(r.name, r.status, r.n_corners, _boards(r.boards or []), r.reason or "") for r in det.reports]
        table(["image", "status", "corners", "boards (corners)", "reason"], rows)
    else:
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


def _boards(boards: list[dict]) -> str:
    """'+x 36, -z 20, chessboard 9x6 #1 54 (own view)': the boards an image shows."""
    found = [f"{b['name']} {b['n_corners']}" + ("" if b["placed"] else " (own view)") for b in boards if b["n_corners"]]
    return ", ".join(found) or "none"


def run(args) -> int:
    outputs = Outputs()
    target = outputs.file(args.output, "-o", "obs.json")
    if args.json:
        claim_stdout("--json")
    cal = load_calibration(args.refine_with) if args.refine_with else None
    det = detect_with_report(args.images, args.board, args.quiet, args.workers, cal, args.target)
    assert det.observations is not None  # detect_with_report raises when no image gave corners
    det.observations.extra["coverage"] = det.coverage
    text = json_text(det.observations.to_json())
    with outputs.writing():
        if target is not None:
            target.write(text)
    if args.json:
        write_data(text.encode("utf-8"))
    elif target is not None and not target.to_stdout:
        print(f"wrote {target}")
    return 0

