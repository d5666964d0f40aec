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
        return f"freecal export: {fit.name}, exactly the {fit.fitted_to} calibration{beyond_note(fit)}"
    return (f"freecal export: {fit.name} fitted to the {fit.fitted_to} calibration; fit error over the covered "
            f"region rms {fit.covered.rms:.4g} px, max {fit.covered.max:.4g} px; over the whole image "
            f"rms {fit.image.rms:.4g} px, max {fit.image.max:.4g} px{beyond_note(fit)}")


def beyond_note(fit) -> str:
    """"; N of the image's M samples ..." where the model cannot represent some of the image's rays
    (a lens past the consumer's reach: OpenCV's models stop short of 90° off axis), and where a
    fitted rational model throws a ring of them to infinity; else ""."""
    note = ""
    if fit.n_beyond:
        note += (f"; {fit.n_beyond} of the image's {fit.image.n + fit.n_beyond} samples lie past what this model can "
                 "represent (too far off axis), and are not in it")
    if fit.pole_radius is not None:
        angle = math.degrees(math.atan(fit.pole_radius))
        note += (f"; outside the corners' region its rational denominator vanishes on the rays {angle:.1f}° off axis "
                 f"(r = {fit.pole_radius:.3f}): those project to infinity, and the image's pixels there have no ray "
                 "(choose another model with --model where the whole image matters)")
    return note
