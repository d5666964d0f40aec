"""Every compiled kernel into numba's on-disk cache, once per install.

The kernels (``@njit(cache=True)``: the solver's, the B-spline field's, the
detector's checks) compile on their first call, about 30 s in all on a
2-core machine (the detector's 26, the fitting's 5), which the first photo
set or calibration after an install would otherwise wait for. ``make run``
and the Docker image run ``python -m calib_core.warm_up`` before serving;
with the cache in place it loads the kernels in about a second.

One rendered fisheye view is detected (the image circle, growth through
distortion, the saddle checks) and a small synthetic set calibrated with
every method (``RUNS``), so each kernel meets the argument types real work
gives it.
"""
from __future__ import annotations

import time

import numpy as np

from . import synth
from .board import BoardSpec
from .detection.detect_image import detect_gray
from .methods import METHODS
from .pipeline import calibrate
from .synth import render


def warm_up() -> float:
    """Compile (or load) every kernel; the seconds it took."""
    start = time.perf_counter()
    s = synth.generate("fisheye", 0.0, 0, 3)
    view = s.truth["train_views"][0]
    pose = np.array(view["rvec"] + view["tvec"], dtype=np.float64)
    cols, rows = synth.TRAIN_BOARD
    image = render.render_view("fisheye", pose, image_size=(640, 480))  # a quarter of the pixels, the same kernels
    detect_gray(image, BoardSpec.parse(f"chessboard:{cols}x{rows}:{synth.SQUARE:g}mm"))
    observations = synth.generate("radial", 0.3, 0, 4).train
    for method, settings in RUNS:
        calibrate(observations, method, **settings)
    return time.perf_counter() - start


# Every method once, the fields on a small fixed grid (the same kernels as a search, less work),
# and the field over a parametric core (its own rows kernel).
FIXED_GRID = {"intervals": 4, "lambda_smooth": 1.0}
RUNS = [(method, FIXED_GRID if method == "bspline" else {}) for method in METHODS] + [
    ("bspline", {**FIXED_GRID, "core": "rational"})]


def main() -> int:
    print("freecal: loading the compiled kernels (about 30 s the first time after an install) ...", flush=True)
    print(f"freecal: kernels ready in {warm_up():.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
