"""a⁻¹ b for the symmetric positive definite systems of the cross-validations, by LAPACK's
Cholesky solver (``dposv``, as ``scipy.linalg.solve(assume_a="pos")`` calls it, without its
condition estimate: these are solved thousands of times a calibration). What to do where
rounding leaves a system indefinite is the caller's: each question has its own answer."""
from __future__ import annotations

import numpy as np
import scipy.linalg


def cholesky_solve(a: np.ndarray, b: np.ndarray, lower: bool = False, overwrite: bool = False) -> np.ndarray | None:
    """a⁻¹ b, reading ``a``'s upper (or ``lower``) triangle only; None where ``a`` is not
    positive definite. ``overwrite``: ``a`` may be factorised in place (no copy where it is
    in LAPACK's column order: a C-ordered array's transpose)."""
    _, x, info = scipy.linalg.lapack.dposv(a, b, lower=int(lower), overwrite_a=int(overwrite))
    if info < 0:
        raise ValueError(f"dposv: illegal argument {-info}")
    return x if info == 0 else None
