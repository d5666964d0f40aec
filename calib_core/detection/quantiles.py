"""Percentiles of the small samples the checks read (a grid's cells, a frame's border), compiled:
np.percentile's checks and calls cost more than sorting a few hundred values, and hold the GIL."""
from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def percentiles(values, fractions):  # pragma: no cover (compiled)
    """np.percentile(values, 100 * fractions) (its linear method) of finite float64 values (K,),
    fractions (Q,) as np.percentile makes them (q / 100): the same numbers for a fraction of its
    cost (its checks and calls cost more than the sort). Between the sorted values at floor and
    floor + 1 of (K - 1) * fraction, interpolated as np.percentile does (from the nearer end)."""
    s = np.sort(values)
    out = np.empty(len(fractions))
    for k in range(len(fractions)):
        v = (len(s) - 1) * fractions[k]
        if v >= len(s) - 1:
            out[k] = s[-1]
            continue
        i = int(np.floor(v))
        t = v - np.floor(v)
        a, b = s[i], s[i + 1]
        d = b - a
        out[k] = b - d * (1 - t) if t >= 0.5 else a + d * t
    return out
