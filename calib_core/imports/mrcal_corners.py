"""mrcal's corner files (``corners.vnl``, what ``mrgingham`` and ``mrcal-calibrate-cameras
--corners-cache`` read and write) as observations.

The format (mrcal's ``compute_chessboard_corners``): a vnlog, ``#`` lines are comments or
the header (``# filename x y level``); each data row is ``filename x y`` and an optional
fourth column, a decimation ``level`` (the default) or a ``weight``. An image whose board
was found has exactly W × H rows, the board's corners row by row (W, the width, varies
fastest: our ``id = row * cols + col``); an image without one has a single row
``filename - -``. A corner is missing where x or y is ``-`` or negative, or its level is
``-`` or negative (a weight: ``-`` or not positive). The file does not say the board's
square size nor the images' size: they come from whoever reads it (the page's board
fields; a photo of the set).
"""
from __future__ import annotations

import re

import numpy as np

from ..board import BoardSpec
from ..errors import FormatError
from ..observations import Observations, View

MAX_NAME = 255   # characters of an image name


def read_corners_vnl(text: str, board: BoardSpec, image_size: tuple[int, int],
                     what: str = "corners.vnl") -> tuple[Observations, list[tuple[str, str]]]:
    """(the observations of every image whose board was found, [(image, why it gave no view)])."""
    if board.type != "chessboard":
        raise FormatError(f"{what} holds chessboard corners (mrgingham's): choose a chessboard as the board")
    lines = np.array(text.splitlines(), dtype=str)
    stripped = np.char.strip(lines)
    data = lines[(stripped != "") & ~np.char.startswith(stripped, "#")]
    if not len(data):
        raise FormatError(f"{what} holds no corners (only comments or nothing): is it mrcal's corners.vnl?")
    header = next((h for h in stripped if re.match(r"#\s*filename\s+x\s+y\b", h)), "")
    weights = header.split()[-1] == "weight" if header else False
    parts = np.char.split(data)
    widths = np.fromiter(map(len, parts), int, len(parts))
    if np.any((widths < 3) | (widths > 4)):
        bad = data[np.flatnonzero((widths < 3) | (widths > 4))[0]]
        raise FormatError(f"{what}: every row must be 'filename x y' or 'filename x y level' (mrcal's corners "
                          f"file); this one is not: {str(bad)[:80]!r}")
    # a row without the fourth column counts as seen at full resolution (weight 1), as mrcal reads it
    pad = "1" if weights else "0"
    padded = np.char.add(data, np.where(widths == 3, f" {pad}", ""))
    table = np.array(" ".join(padded).split(), dtype=str).reshape(len(data), 4)
    names = table[:, 0]
    # rows of one image are consecutive: a new image starts where the name changes
    starts = np.flatnonzero(np.r_[True, names[1:] != names[:-1]])
    counts = np.diff(np.r_[starts, len(names)])
    if len(set(names[starts])) != len(starts):
        raise FormatError(f"{what}: the rows of one image must be together (an image appears twice, apart)")
    cols, rows = board.corner_grid
    per_board = cols * rows
    xy = _numbers(table[:, 1:3])
    ok = np.all(np.isfinite(xy), axis=1) & np.all(xy >= 0, axis=1)
    level = _numbers(table[:, 3:4])[:, 0]
    ok &= (level > 0) if weights else (level >= 0)
    views, skipped = [], []
    for start, count in zip(starts, counts, strict=True):   # per image, not per point
        name = str(names[start])
        if len(name) > MAX_NAME:
            raise FormatError(f"{what}: an image name of {len(name)} characters (at most {MAX_NAME})")
        if count == 1 and not ok[start]:
            skipped.append((name, "the other tool found no board in it"))
            continue
        if count != per_board:
            raise FormatError(f"{what}: {name} has {count} corners, but a {cols} × {rows} board has {per_board}: "
                              "set the board's size (inner corners) to the one the corners were found on")
        sel = np.arange(start, start + count)[ok[start:start + count]]
        if not len(sel):
            skipped.append((name, "every corner of it is marked missing"))
            continue
        ids = (sel - start).astype(np.int64)
        views.append(View(name, board.object_points(ids), xy[sel], ids))
    if not views:
        raise FormatError(f"{what}: no image in it has corners (the other tool found no board in any)")
    return Observations(image_size, views, board.to_json()), skipped


def _numbers(cells: np.ndarray) -> np.ndarray:
    """Float array of the cells, NaN where a cell is '-'; FormatError naming a cell that is no number."""
    missing = cells == "-"
    try:
        return np.where(missing, np.nan, np.where(missing, "0", cells).astype(float))
    except ValueError:
        bad = next(c for c in cells.ravel() if c != "-" and not _is_number(c))
        raise FormatError(f"corners.vnl: {str(bad)!r} is no number (x, y and the level are numbers, or '-' "
                          "where a corner is missing)") from None


def _is_number(cell: str) -> bool:
    try:
        float(cell)
    except ValueError:
        return False
    return True
