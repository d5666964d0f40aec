"""Where a fisheye's image circle ends: the unlit frame around it.

A corner whose refinement window reaches into the unlit region is not a
corner of the board: its dark quadrants merge with the void and cornerSubPix
snaps onto the circle's rim. ``distance_to_unlit`` gives, per pixel, how far
the nearest unlit pixel is, so that test is one lookup per corner.
"""
from __future__ import annotations

import cv2
import numpy as np

BLUR_SIGMA = 2.0
BLUR_REACH = 8      # OpenCV's kernel radius for BLUR_SIGMA: round(8 σ + 1) | 1 taps
UNLIT = 12          # grey level (after a light blur) below which a pixel got no light
MIN_SHARE = 0.002   # unlit regions smaller than this share of the frame are shadows, not the void


def distance_to_unlit(gray: np.ndarray) -> np.ndarray:
    """(H, W) float32 distance (px) from each pixel to the unlit region that touches the
    frame's border (a lens's image circle ends there); very large where there is none."""
    h, w = gray.shape
    if _border_lit(gray):
        return np.full((h, w), 1e9, np.float32)
    dark = (cv2.GaussianBlur(gray, (0, 0), BLUR_SIGMA) < UNLIT).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(dark, connectivity=8)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    void = np.isin(labels, [k for k in border if k > 0 and stats[k, cv2.CC_STAT_AREA] >= MIN_SHARE * h * w])
    if not void.any():
        return np.full((h, w), 1e9, np.float32)
    return cv2.distanceTransform((~void).astype(np.uint8), cv2.DIST_L2, 5)


def _border_lit(gray: np.ndarray) -> bool:
    """True when no pixel within the blur's reach of the frame's border is unlit: then
    no blurred border pixel is, and no unlit region touches the border (the common,
    rectilinear case, decided without blurring the whole image)."""
    r = BLUR_REACH + 1
    strips = (gray[:r], gray[-r:], gray[:, :r], gray[:, -r:])
    return min(int(s.min()) for s in strips) >= UNLIT
