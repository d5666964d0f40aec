"""From photos to corners: detect a board in many images, on all cores.

``detect_images`` is the public entry (the CLI and the web service call it).
Each image is detected in a worker process (``detect_image.detect_file``);
if a process pool cannot be had (sandbox, frozen app, a crashed worker) the
rest run in this process. Every image gets a report, used or rejected, with
the reason in plain words.
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..board import BoardSpec
from ..errors import DataError
from ..evaluation.coverage import coverage, coverage_warning
from ..observations import Observations, View
from .detect_image import ImageResult, detect_file

# What the command line and the service read (the service checks each one's header: backend/app/image_header.py)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".pgm", ".ppm", ".pbm", ".pnm")


@dataclass
class ImageReport:
    name: str
    status: str  # "used" | "rejected"
    n_corners: int
    reason: str
    sharpness: float | None  # chessboard edge width in px (lower is sharper; < 3 is sharp), None if unknown
    width: int | None
    height: int | None

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class Detection:
    observations: Observations | None  # None when no image was usable
    reports: list[ImageReport]
    coverage: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    model_added: int | None = None  # corners the re-detection through ``calibration`` added (None: none given)


def image_paths(items: Iterable[str | Path]) -> list[Path]:
    """Files given, and the images inside directories given (sorted), in order.

    Raises DataError naming what is missing, or when nothing is left.
    """
    out: list[Path] = []
    for item in items:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in IMAGE_SUFFIXES)
            if not found:
                raise DataError(f"{p}: no images in this folder (looked for {', '.join(sorted(IMAGE_SUFFIXES))})")
            out += found
        elif p.is_file():
            out.append(p)
        else:
            raise DataError(f"{p}: no such file or folder")
    if not out:
        raise DataError("no images given: pass image files or a folder of images")
    return out


def detect_images(paths, board: BoardSpec, progress: Callable[[int, int], None] | None = None,
                  workers: int | None = None, calibration=None) -> Detection:
    """Detect ``board`` in every image of ``paths`` (files or folders).

    progress(done, total) is called after each image. A bad image never
    raises: it becomes a rejected report. With ``calibration`` (a first
    ``Calibration`` of this camera), every board corner is also predicted through
    its model from each view's pose and confirmed (``model_guided.py``);
    ``Detection.model_added`` says how many corners that added.
    """
    files = image_paths([paths] if isinstance(paths, (str, Path)) else paths)
    names = _unique_names(files)
    model = None if calibration is None else calibration.model
    results = _run_all(files, names, board, progress, workers, model)
    _reject_odd_sizes(results)
    det = _assemble(results, board)
    if calibration is not None:
        det.model_added = sum(r.model_added or 0 for r in results if r.status == "used")
        if det.observations is not None and tuple(det.observations.image_size) != tuple(calibration.image_size):
            det.warnings.append(f"the calibration is of {calibration.image_size[0]}x{calibration.image_size[1]} "
                                f"images, these are {det.observations.image_size[0]}x"
                                f"{det.observations.image_size[1]}: its predictions are off and add few corners")
    return det


def _unique_names(files: list[Path]) -> list[str]:
    """File names, with parent folders prefixed where two would clash (names must be unique)."""
    counts = Counter(f.name for f in files)
    names = [f.name if counts[f.name] == 1 else f"{f.parent.name}/{f.name}" for f in files]
    seen: Counter = Counter()
    out = []
    for n in names:
        seen[n] += 1
        out.append(n if seen[n] == 1 else f"{n}#{seen[n]}")
    return out


def _run_all(files, names, board, progress, workers, model=None) -> list[ImageResult]:
    total = len(files)
    n = workers if workers is not None else (os.cpu_count() or 1)
    n = max(1, min(n, total))
    results: list[ImageResult | None] = [None] * total
    done = 0
    if n > 1:
        try:
            with cf.ProcessPoolExecutor(n, mp_context=_context(), initializer=_init_worker) as pool:
                futures = {pool.submit(detect_file, str(f), board, nm, model): k
                           for k, (f, nm) in enumerate(zip(files, names, strict=True))}
                for fut in cf.as_completed(futures):
                    k = futures[fut]
                    try:
                        results[k] = fut.result()
                    except Exception:  # a dead worker: this image is retried in-process below
                        continue
                    done += 1
                    if progress:
                        progress(done, total)
        except (OSError, PermissionError, NotImplementedError, cf.process.BrokenProcessPool, RuntimeError):
            pass  # no pool here (sandbox, no /dev/shm...): fall back to this process
    for k, (f, nm) in enumerate(zip(files, names, strict=True)):
        if results[k] is None:
            results[k] = detect_file(f, board, nm, model)
            done += 1
            if progress:
                progress(done, total)
    return results  # type: ignore[return-value]


def _context():
    """forkserver where there is one, preloaded with the detector; else spawn.

    Never fork: once this process has run any parallel OpenCV call (an imwrite, a blur),
    a forked child inherits OpenCV's thread pool without its threads, and its first
    ``cv2.setNumThreads`` waits forever on the pool's condition variable (seen: the
    test suite hung). The fork server is a fresh interpreter that imported OpenCV but
    never ran it, so workers start in milliseconds and clean.
    """
    methods = mp.get_all_start_methods()
    if "forkserver" in methods:
        ctx = mp.get_context("forkserver")
        ctx.set_forkserver_preload(["calib_core.detection.detect_image"])
        return ctx
    return mp.get_context("spawn")


def _init_worker() -> None:
    import cv2

    from ..lifetime import die_with_parent

    die_with_parent()  # a detection killed outright (time limit, its worker gone) takes its pool with it
    cv2.setNumThreads(1)  # one image per core: OpenCV's own threads would only oversubscribe


def _reject_odd_sizes(results: list[ImageResult]) -> None:
    """All views share one camera: images of another size than the most common are rejected."""
    sizes = Counter((r.width, r.height) for r in results if r.width is not None)
    if not sizes:
        return
    (w, h), _ = sizes.most_common(1)[0]
    for r in results:
        if r.width is not None and (r.width, r.height) != (w, h):
            r.status = "rejected"
            r.reason = f"resolution differs from the set: {r.width}x{r.height}, the others are {w}x{h}"
            r.ids = r.points = None


def _image_size(result: ImageResult) -> tuple[int, int]:
    """(width, height) of an image that was read."""
    if result.width is None or result.height is None:
        raise ValueError(f"{result.name}: {result.status} image has no size")
    return result.width, result.height


def _view(result: ImageResult, board: BoardSpec) -> View:
    """A used image's corners as a view of ``board``."""
    if result.ids is None or result.points is None:
        raise ValueError(f"{result.name}: {result.status} image has no corners")
    return View(result.name, board.object_points(result.ids), result.points, result.ids)


def none_found(board: BoardSpec, n_images: int) -> str:
    """Why a detection found nothing, in words that fit the page and the command line alike."""
    if board.type == "chessboard":
        what = f"the chessboard of {board.cols} × {board.rows} inner corners"
        hint = "check the board's size (inner corners, where four squares meet, not squares) and the photos' focus"
    else:
        what = f"the ChArUco board of {board.cols} × {board.rows} squares ({board.dictionary})"
        hint = "check the board's size (squares), its marker dictionary and the photos' focus"
    return f"{what} was found in none of the {n_images} photos: {hint}"


def _assemble(results: list[ImageResult], board: BoardSpec) -> Detection:
    reports = [ImageReport(r.name, r.status, r.n_corners, r.reason, r.sharpness, r.width, r.height) for r in results]
    used = [r for r in results if r.status == "used"]
    warnings: list[str] = []
    if not used:
        warnings.append(none_found(board, len(results)))
        return Detection(None, reports, {}, warnings)
    size = _image_size(used[0])
    views = [_view(r, board) for r in used]
    obs = Observations(size, views, board.to_json())
    cov = coverage(np.concatenate([v.image_points for v in views]), size)
    msg = coverage_warning(cov)
    if msg:
        warnings.append(msg)
    rejected = len(results) - len(used)
    if rejected:
        warnings.append(f"{rejected} of {len(results)} images rejected (see the report for why)")
    return Detection(obs, reports, cov, warnings)
