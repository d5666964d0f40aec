"""Numbers as the consumers' readers parse them back, bit for bit."""
from __future__ import annotations

import math

import numpy as np


def number(x: float) -> str:
    """A float as YAML 1.1 (PyYAML, Kalibr's reader) and JSON read it back as a float,
    exactly: Python's shortest round-trip form with a '.' in the mantissa and a
    signed exponent (PyYAML reads ``1e-05`` as a string, ``500`` as an int)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot write {x!r} as a YAML number")
    s = repr(x)
    if "e" in s:
        mantissa, exponent = s.split("e")
        if "." not in mantissa:
            mantissa += ".0"
        if exponent[0] not in "+-":
            exponent = "+" + exponent
        return f"{mantissa}e{exponent}"
    return s if "." in s else s + ".0"


def numbers(values) -> str:
    """``[a, b, ...]`` of floats, each as ``number`` writes it."""
    return "[" + ", ".join(number(v) for v in np.asarray(values, dtype=np.float64).ravel()) + "]"


def fit_note(fit) -> str:
    """One line (no comment marker) saying what the export is: exact, or fitted with its errors."""
    if fit.exact:
        return f"freecal export: {fit.name}, exactly the {fit.fitted_to} calibration"
    return (f"freecal export: {fit.name} fitted to the {fit.fitted_to} calibration; fit error over the covered "
            f"region rms {fit.covered.rms:.4g} px, max {fit.covered.max:.4g} px; over the whole image "
            f"rms {fit.image.rms:.4g} px, max {fit.image.max:.4g} px")
