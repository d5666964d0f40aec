"""Rigid poses as (6,) ``[rvec | tvec]`` (OpenCV's convention), composed and inverted."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The pose ``a ∘ b`` (first b, then a), poses as (6,) [rvec | tvec]."""
    ra, rb = Rotation.from_rotvec(a[:3]), Rotation.from_rotvec(b[:3])
    return np.concatenate([(ra * rb).as_rotvec(), ra.apply(b[3:]) + a[3:]])


def inverse(a: np.ndarray) -> np.ndarray:
    r = Rotation.from_rotvec(a[:3]).inv()
    return np.concatenate([r.as_rotvec(), -r.apply(a[3:])])
