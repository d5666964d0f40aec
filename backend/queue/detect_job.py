"""A detection job: a set's images → corners (``observations.json``) and a report per image.

Images go to ``calib_core.detection.detect.detect_images`` in batches so each image's
status reaches the database (and the API) as soon as its batch is done.
Coverage and its warning are computed over the merged views with
``calib_core.evaluation.coverage`` (what ``detect_images`` itself reports for one batch).
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from calib_core import Observations
from calib_core.errors import DataError
from calib_core.evaluation.coverage import Circle

from ..base import storage
from ..base.context import Context
from ..base.repository import sets
from .lease import JobRun

BATCHES = 8             # status updates per set; each batch still runs on every core
DETECTED = 0.9          # the share of the progress figure the photos take (the board-size check: the rest)


def run(ctx: Context, job: dict[str, Any], run: JobRun) -> dict[str, Any]:
    from calib_core.board import BoardSpec
    from calib_core.detection.board_size import suggest_size
    from calib_core.detection.detect import detect_images, none_found
    from calib_core.detection.image_circle import common_circle
    from calib_core.evaluation.coverage import circle_json

    set_id = job["set_id"]
    row = sets.get(ctx.db, set_id)
    if row is None:
        raise DataError("the image set was deleted")
    board = BoardSpec.parse(job["settings"]["board"])
    folder = ctx.storage.images_dir(set_id)
    names = [im["name"] for im in row["images"]]
    sets.reset_images(ctx.db, set_id)
    size = max(1, math.ceil(len(names) / BATCHES))
    views, warnings = [], []
    image_size: tuple[int, int] | None = None
    circles: list = []  # each photo read: its image circle, or None
    undecodable = 0  # photos that could not be read as images: no board's size is to blame for them
    run.progress("detect", 0.0, 0.0, DETECTED)
    for start in range(0, len(names), size):
        batch = names[start:start + size]
        done = start

        def progress(k: int, total: int, done=done) -> None:  # detect_images: after each image
            run.progress("detect", (done + k) / len(names), 0.0, DETECTED)

        det = detect_images([folder / n for n in batch], board, progress=progress)
        circles += [r.image_circle for r in det.reports if r.width is not None]
        undecodable += sum(r.width is None for r in det.reports)
        reports = [_report(r) for r in det.reports]
        if det.observations is not None:
            if image_size is None:
                image_size = det.observations.image_size
            # detect_images keeps one size per call; across batches that is ours to check
            if tuple(det.observations.image_size) == image_size:
                views += det.observations.views
            else:
                bad = {v.name for v in det.observations.views}
                for r in reports:
                    if r["name"] in bad:
                        r.update(status="rejected", reason=f"image size {det.observations.image_size} differs "
                                 f"from the set's {list(image_size)}: one camera per set")
        warnings += [w for w in det.warnings if w not in warnings]
        sets.record_reports(ctx.db, set_id, reports)
        run.progress("detect", (start + len(batch)) / len(names), 0.0, DETECTED)
    circle = common_circle(circles)
    coverage, warning = measure_coverage(views, image_size, circle)
    # per batch, superseded by the set's own: coverage, the board found in none, images rejected
    per_batch = ("no corners in the ", "no corners near the edge of the image circle", " was found in none of the ", " images rejected (see the report")
    warnings = [w for w in warnings if not any(b in w for b in per_batch)]
    if warning:
        warnings.append(warning)
    rejected = len(names) - len(views)
    if views and rejected:
        warnings.append(f"{rejected} of {len(names)} photos gave no corners (each says why)")
    run.progress("board size", 0.0, DETECTED, 1.0)
    size_found = suggest_size(board, views, len(names), [folder / n for n in names])
    suggestion = record_suggestion(ctx, set_id, board, size_found, len(names))
    if suggestion and views:
        warnings.append(suggestion["message"])
    sets.record_detection(ctx.db, set_id, None if image_size is None else list(image_size), coverage,
                          warnings, len(views))
    if not views or image_size is None:
        raise DataError(none_found(board, len(names), undecodable) + (f"; {suggestion['message']}" if suggestion else ""))
    obs = Observations(image_size, views, board.to_json(),
                       {} if circle is None else {"image_circle": circle_json(circle)})
    storage.write_json(ctx.storage.observations_path(set_id), obs.to_json())
    return {"artefacts": ["observations.json"], "summary": {"n_views": len(views), "n_images": len(names)}}


def record_suggestion(ctx: Context, set_id: str, board: Any, found: Any, n_images: int) -> dict[str, Any] | None:
    """Store (or clear) the board size the photos suggest, as the set shows it (``SetPublic.board_suggestion``)."""
    path = ctx.storage.board_suggestion_path(set_id)
    if found is None:
        path.unlink(missing_ok=True)
        return None
    doc = {"spec": found.board(board).to_spec(), "cols": found.cols, "rows": found.rows,
           "n_photos": found.n_photos, "n_images": n_images,
           "message": f"{found.message(board)}: detect again with {found.cols} × {found.rows}"}
    storage.write_json(path, doc)
    return doc


def _report(r: Any) -> dict[str, Any]:
    keys = ("name", "status", "n_corners", "reason", "sharpness", "width", "height")
    d = r if isinstance(r, dict) else {k: getattr(r, k, None) for k in keys}
    return {k: d.get(k) for k in keys}


def measure_coverage(views: list, image_size: tuple[int, int] | None,
                     circle: Circle | None = None) -> tuple[dict[str, Any] | None, str | None]:
    """The set's coverage (only inside the lens's image ``circle``, if the photos have one) and its advice."""
    from calib_core.evaluation.coverage import coverage, coverage_warning

    if not views or image_size is None:
        return None, None
    cov = coverage(np.concatenate([v.image_points for v in views]), image_size, circle=circle)
    return cov, coverage_warning(cov)
