"""Photo-like rendered views of a chessboard seen whole (calib_core.synth.render), written as PNG
files: a set whose board size is known exactly, for the board-size and curation tests."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from calib_core import synth
from calib_core.synth import render


def whole_board_photos(folder: Path, n: int = 8, board: tuple[int, int] = (9, 6), square: float = 50.0,
                       kind: str = "radial") -> list[Path]:
    """``n`` PNGs of a ``board`` (inner corners) chessboard, whole in view, tilted every way."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    centre = np.array([(board[0] - 1) * square / 2, (board[1] - 1) * square / 2, 0.0])
    paths = []
    for k in range(n):
        phi = 2 * np.pi * k / n
        tilt = np.radians(25.0) * np.array([np.cos(phi), np.sin(phi)]) if k else np.zeros(2)
        pose = synth.pose_looking_at(centre, 800.0 + 40 * (k % 3), tilt, 0.2 * (k % 4) - 0.3)
        path = folder / f"render_{k:02d}.png"
        cv2.imwrite(str(path), render.render_view(kind, pose, board, square, rng=rng))
        paths.append(path)
    return paths
