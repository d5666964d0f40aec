"""Read BabelCalib's corner files: a board description (``.dsc``) and
per-image reference corners (``.orpc``), into ``Observations``.

``.dsc``: a header ``board_id, squares_rows, squares_cols, feature_size_mm``,
a line ``tag_family, tag_border``, then one line per inner corner
``tag_id, col, row, X_cm, Y_cm, Z_cm``. ``.orpc``: five header lines
(filename, width, height, num_corners, encoding), then
``board_id, point_index, flag, x, y`` with 0-based pixels (OpenCV's
convention) and ``point_index`` into the ``.dsc`` corner list.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import FormatError
from ..observations import Observations, View


def read_board(path: str | Path) -> np.ndarray:
    """Board corners (M, 3) in millimetres, in ``.dsc`` order."""
    lines = [ln for ln in Path(path).read_text().splitlines() if ln.strip()]
    try:
        rows = np.array([[float(x) for x in ln.split(",")] for ln in lines[2:]])
        return rows[:, 3:6] * 10.0  # cm → mm, as BabelCalib does
    except (ValueError, IndexError):
        raise FormatError(f"{path}: not a BabelCalib board description (.dsc)") from None


def read_corners(path: str | Path) -> tuple[tuple[int, int], np.ndarray, np.ndarray]:
    """((width, height), corner ids (N,), pixels (N, 2)) of one ``.orpc`` file."""
    lines = Path(path).read_text().splitlines()
    header = dict(ln.split(":", 1) for ln in lines[:5] if ":" in ln)
    try:
        size = (int(header["width"]), int(header["height"]))
        body = np.array([[float(x) for x in ln.split(",")] for ln in lines[5:] if ln.strip()]).reshape(-1, 5)
    except (KeyError, ValueError):
        raise FormatError(f"{path}: not a BabelCalib corner file (.orpc)") from None
    return size, body[:, 1].astype(np.int64), body[:, 3:5]


def load(folder: str | Path, board: str | Path) -> Observations:
    """Every ``.orpc`` in ``folder`` as one view each (named after its image)."""
    corners = read_board(board)
    views, size = [], None
    for path in sorted(Path(folder).glob("*.orpc")):
        size, ids, pixels = read_corners(path)
        views.append(View(path.with_suffix(".png").name, corners[ids], pixels, ids))
    if not views or size is None:
        raise FormatError(f"{folder}: no .orpc corner files")
    return Observations(size, views, {"type": "babelcalib", "file": Path(board).name, "units": "mm"})
