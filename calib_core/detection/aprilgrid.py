"""Kalibr's AprilGrid: AprilTags 36h11 with black squares at their corners.

Layout, as Kalibr builds it (``GridCalibrationTargetAprilgrid.cpp``,
``kalibr_create_target_pdf``): ``X × Y`` tags of edge ``s`` (the black
border included, two bits wide), ``g = spacing · s`` apart; tag ``t`` sits at
column ``t % X``, row ``t // X``, counted from the **bottom-left** of the
printed page, with its lower-left corner at ``(col, row) · (1 + spacing) · s``.
Its four corners are points of a ``2X × 2Y`` lattice, numbered row-major
from the bottom-left: point ``r · 2X + c`` at
``x = (c // 2)(1 + spacing) s + (c % 2) s``, ``y`` likewise with ``r``
(page frame: x right, y **up**, z out of the page, as Kalibr's).

Kalibr draws each tag turned by 180° from the AprilTag image OpenCV
generates for that id (checked bit by bit), so OpenCV's marker corners
0, 1, 2, 3 (its top-left, top-right, bottom-right, bottom-left) are, on
the page, the tag's bottom-right, bottom-left, top-left and top-right:
``CORNER_OFFSETS`` below.
"""
from __future__ import annotations

import numpy as np

BORDER_BITS = 2   # Kalibr's tags have a two-bit black border (OpenCV's default is one)


def corner_ids(tag_ids: np.ndarray, tag_cols: int) -> np.ndarray:
    """Kalibr's point indices (T, 4) of OpenCV's four corners of tags ``tag_ids`` (T,),
    counted from the board's first tag."""
    tag_ids = np.asarray(tag_ids, dtype=np.int64).reshape(-1)
    cols = 2 * tag_cols
    base = (tag_ids // tag_cols) * 2 * cols + (tag_ids % tag_cols) * 2     # the tag's lower-left point
    return base[:, None] + np.array([1, 0, cols, cols + 1])[None, :]
