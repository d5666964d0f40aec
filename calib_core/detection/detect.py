"""From photos to corners: detect a board in many images, on all cores.

``detect_images`` is the public entry (the CLI and the web service call it).
Each image is detected on its own (``detect_image.detect_file``), on threads
of this process, or in worker processes for long sets; if a process pool
cannot be had (sandbox, frozen app, a crashed worker) the rest run on the
threads. Every image gets a report, used or rejected, with the reason in
plain words.
"""
from __future__ import annotations

import concurrent.futures as cf
import logging
import multiprocessing as mp
import os
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..board import BoardSpec
from ..errors import DataError
from ..evaluation.coverage import Circle, circle_json, coverage, coverage_warning
from ..observations import Observations, View
from ..target import Target
from .detect_image import MIN_CORNERS, ImageResult, detect_file
from .image_circle import common_circle
from .targets import detect_target_file

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
    boards: list[dict] | None = None  # with a target: each board's name, corners, whether placed, why not
    image_circle: Circle | None = None  # a fisheye's lit disc (cx, cy, r) px, if it has one

    def to_json(self) -> dict:
        return asdict(self)


@dataclass
class Detection:
    observations: Observations | None  # None when no image was usable
    reports: list[ImageReport]
    coverage: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)
    model_added: int | None = None  # corners the re-detection through ``calibration`` added (None: none given)
    image_circle: Circle | None = None  # the set's (``image_circle.common_circle``), if any


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


# A pool's workers come from a fresh interpreter that imports OpenCV and the
# detector (0.7 s of CPU on these machines) before the first image, where a thread
# starts at once: a set is detected on threads of this process unless it is long
# enough for processes to pay (the Python of growth and checks holds the GIL between
# its compiled kernels; OpenCV's detectors and the kernels release it).
POOL_PAYS_AFTER = 1.5  # seconds of CPU left after the first image (its thread's CPU times the images left)


def detect_images(paths, board: BoardSpec | Target, progress: Callable[[int, int], None] | None = None,
                  workers: int | None = None, calibration=None) -> Detection:
    """Detect ``board`` in every image of ``paths`` (files or folders).

    progress(done, total) is called after each image. A bad image never
    raises: it becomes a rejected report. With ``calibration`` (a first
    ``Calibration`` of this camera), every board corner is also predicted through
    its model from each view's pose and confirmed (``model_guided.py``);
    ``Detection.model_added`` says how many corners that added.

    With a ``Target`` (several boards, ``freecal.target/1``), each image gives
    one view of the object (3-D object points, target ids) and a planar view
    ``IMAGE/BOARD`` per loose or undecided board (``targets.py``).
    """
    if isinstance(board, Target) and calibration is not None:
        raise DataError("re-detection through a calibration works on one board at a time, not on a target")
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
    """Every image's result, in order, on ``workers`` cores (default: all): on threads of this
    process, or on a pool of processes when the set is long enough to pay for starting one
    (see POOL_PAYS_AFTER). Images a pool could not detect are detected on the threads."""
    total = len(files)
    n = workers if workers is not None else (os.cpu_count() or 1)
    n = max(1, min(n, total))
    results: list[ImageResult | None] = [None] * total
    done = 0

    def finished(k: int, result: ImageResult) -> None:
        nonlocal done
        results[k] = result
        done += 1
        if progress:
            progress(done, total)

    jobs = [_job(files[k], board, names[k], model) for k in range(total)]
    if n == 1:
        for k in range(total):
            finished(k, _call(jobs[k]))
        return results  # type: ignore[return-value]
    with cf.ThreadPoolExecutor(n, thread_name_prefix="freecal-detect") as threads:
        # The first image's CPU decides on a pool; the next n - 1 images start beside it rather
        # than wait (a set of a few images took a round of one image's time longer).
        first = threads.submit(_timed_call, jobs[0])
        running = {threads.submit(_call, jobs[k]): k for k in range(1, n)}
        result, cpu = first.result()
        finished(0, result)
        rest = list(range(n, total))
        if rest and cpu * (total - 1) > POOL_PAYS_AFTER:
            _on_processes(jobs, rest, n, finished)
            rest = [k for k in rest if results[k] is None]
        running.update({threads.submit(_call, jobs[k]): k for k in rest})
        for fut in cf.as_completed(running):
            finished(running[fut], fut.result())
    return results  # type: ignore[return-value]


def _call(job: tuple) -> ImageResult:
    fn, *args = job
    return fn(*args)


def _timed_call(job: tuple) -> tuple[ImageResult, float]:
    """``_call(job)`` and the CPU seconds of its thread: CPU, not wall, so that on a busy machine
    the wall clock does not start a pool for a set this process detects faster than the pool's
    start; its thread's, as other images run beside it."""
    start = time.thread_time()
    result = _call(job)
    return result, time.thread_time() - start


def _on_processes(jobs: list[tuple], todo: list[int], n: int, finished: Callable[[int, ImageResult], None]) -> None:
    """Jobs ``todo`` on a pool of n processes; those a dead worker took with it are left undone."""
    try:
        with cf.ProcessPoolExecutor(n, mp_context=_context(), initializer=_init_worker,
                                    initargs=worker_logging()) as pool:
            futures = {pool.submit(*jobs[k]): k for k in todo}
            for fut in cf.as_completed(futures):
                try:
                    finished(futures[fut], fut.result())
                except Exception:  # a dead worker: this image is retried on a thread
                    continue
    except (OSError, PermissionError, NotImplementedError, cf.process.BrokenProcessPool, RuntimeError):
        pass  # no pool here (sandbox, no /dev/shm...): the threads take the rest


def _job(path: Path, board: BoardSpec | Target, name: str, model) -> tuple:
    """(function, its arguments) that detect ``board`` in one image file (in a worker)."""
    if isinstance(board, Target):
        return detect_target_file, str(path), board, name
    return detect_file, str(path), board, name, model


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
        ctx.set_forkserver_preload(["calib_core.detection.detect_image", "calib_core.detection.targets"])
        return ctx
    return mp.get_context("spawn")


def worker_logging() -> tuple[int, bool]:
    """This process's OpenCV log level, and whether freecal's log is silenced here (the CLI's
    ``quiet_library_logs``): what a worker process started from it should do the same."""
    quiet = any(isinstance(h, logging.NullHandler) for h in logging.getLogger("freecal").handlers)
    return cv2.utils.logging.getLogLevel(), quiet


def _init_worker(opencv_log_level: int, quiet: bool) -> None:
    from ..lifetime import die_with_parent

    die_with_parent()  # a detection killed outright (time limit, its worker gone) takes its pool with it
    cv2.setNumThreads(1)  # one image per core: OpenCV's own threads would only oversubscribe
    cv2.utils.logging.setLogLevel(opencv_log_level)
    if quiet:
        logging.getLogger("freecal").addHandler(logging.NullHandler())


def _reject_odd_sizes(results: list[ImageResult]) -> None:
    """All views share one camera: views of another size than the most common among the images
    where a board was found are rejected (not among all images: a folder's photos without the
    board, of another size, would reject every view)."""
    sizes = Counter((r.width, r.height) for r in results if r.status == "used")
    if not sizes:
        return
    (w, h), _ = sizes.most_common(1)[0]
    for r in results:
        if r.status == "used" and (r.width, r.height) != (w, h):
            r.status = "rejected"
            r.reason = f"resolution differs from the set: {r.width}x{r.height}, the others are {w}x{h}"
            r.ids = r.points = r.boards = None


def _image_size(result: ImageResult) -> tuple[int, int]:
    """(width, height) of an image that was read."""
    if result.width is None or result.height is None:
        raise ValueError(f"{result.name}: {result.status} image has no size")
    return result.width, result.height


def _views(result: ImageResult, board: BoardSpec | Target) -> list[View]:
    """A used image's corners as views of ``board``: one, or with a target the object's
    view and a planar view per board kept on its own."""
    if isinstance(board, BoardSpec):
        if result.ids is None or result.points is None:
            raise ValueError(f"{result.name}: {result.status} image has no corners")
        return [View(result.name, board.object_points(result.ids), result.points, result.ids)]
    views = []
    if result.ids is not None and result.points is not None:
        views.append(View(result.name, board.object_points(result.ids), result.points, result.ids))
    for hit in result.boards or []:
        if not hit.placed and hit.ids is not None and hit.points is not None and hit.n_corners >= MIN_CORNERS:
            spec = board.boards[hit.board].spec if hit.board is not None else _size_spec(board, hit.label)
            views.append(View(f"{result.name}/{hit.label}", spec.object_points(hit.ids), hit.points, hit.ids))
    return views


def none_found(board: BoardSpec, n_images: int, undecodable: int = 0) -> str:
    """Why a detection found nothing, in words that fit the page and the command line alike;
    ``undecodable``: photos not searched as they could not be read, named first (a board's size
    is not to blame for those)."""
    if board.type == "chessboard":
        what = f"the chessboard of {board.cols} × {board.rows} inner corners"
        hint = "check the board's size (inner corners, where four squares meet, not squares) and the photos' focus"
    elif board.type == "charuco":
        what = f"the ChArUco board of {board.cols} × {board.rows} squares ({board.dictionary})"
        hint = "check the board's size (squares), its marker dictionary and the photos' focus"
    else:
        what = f"the board ({board.to_spec()})"
        hint = "check the board's spec and the photos' focus"
    unusable = _unusable(n_images, undecodable)
    if unusable and undecodable == n_images:
        return unusable
    if unusable:
        return f"{unusable}; {what} was found in none of the other {n_images - undecodable}: {hint}"
    return f"{what} was found in none of the {n_images} photos: {hint}"


def _unusable(n_images: int, undecodable: int) -> str:
    """"none of the N photos could be used: ..." when some could not be read as images, else ""."""
    return (f"none of the {n_images} photos could be used: {undecodable} could not be read as images "
            "(see each one's reason)") if undecodable else ""


def _size_spec(target: Target, label: str) -> BoardSpec:
    """The spec of the chessboards of an undecided hit's size ("chessboard 9x6 #2")."""
    size = label.split()[1]
    return next(b.spec for b in target.boards if b.spec.type == "chessboard" and f"{b.spec.cols}x{b.spec.rows}" == size)


def _report(r: ImageResult) -> ImageReport:
    boards = None if r.boards is None else [h.to_json() for h in r.boards]
    return ImageReport(r.name, r.status, r.n_corners, r.reason, r.sharpness, r.width, r.height, boards,
                       r.image_circle)


def _assemble(results: list[ImageResult], board: BoardSpec | Target) -> Detection:
    reports = [_report(r) for r in results]
    used = [r for r in results if r.status == "used"]
    warnings: list[str] = []
    if not used:
        # Photos that could not be decoded are why, not the board: say so.
        undecodable = sum(r.width is None for r in results)
        searched = len(results) - undecodable
        unusable = _unusable(len(results), undecodable)
        if isinstance(board, BoardSpec):
            warnings.append(none_found(board, len(results), undecodable))
        elif unusable and not searched:
            warnings.append(unusable)
        else:
            warnings.append(f"{unusable}; " * bool(unusable) + f"no board of the target ({board.describe()}) was "
                            f"found in any of the{' other' * bool(unusable)} {searched} photos: "
                            "check the target file and the photos' focus")
        return Detection(None, reports, {}, warnings)
    size = _image_size(used[0])
    views = [v for r in used for v in _views(r, board)]
    circle = common_circle([r.image_circle for r in results if r.width is not None])
    extra = {} if circle is None else {"image_circle": circle_json(circle)}
    if isinstance(board, BoardSpec):
        obs = Observations(size, views, board.to_json(), extra)
    else:
        obs = Observations(size, views, None, {"target": board.to_json(), **extra})
    cov = coverage(np.concatenate([v.image_points for v in views]), size, circle=circle)
    msg = coverage_warning(cov)
    if msg:
        warnings.append(msg)
    rejected = len(results) - len(used)
    if rejected:
        warnings.append(f"{rejected} of {len(results)} images rejected (see the report for why)")
    return Detection(obs, reports, cov, warnings, image_circle=circle)
