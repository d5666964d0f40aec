"""A behaviour fingerprint: every method on every synthetic lens, and detection on
rendered views, printed to 9 digits, so that two checkouts can be diffed.

    python -m benchmarks fingerprint [--methods zhang,...] [--views 8] > after.txt

A restructure (moving modules, typing, splitting files) must leave this output
byte for byte the same; run it on the commit before and after and ``diff`` the
two files. About two minutes on one core.
"""
from __future__ import annotations

import argparse
import hashlib
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from calib_core import synth
from calib_core.board import BoardSpec
from calib_core.detection.detect import detect_images, image_paths
from calib_core.errors import CalibError
from calib_core.evaluation.evaluate import evaluate
from calib_core.pipeline import calibrate
from calib_core.synth import render

METHODS = ("zhang", "rational", "fisheye", "bspline", "auto")


def methods(kinds, names, views: int) -> None:
    for kind in kinds:
        s = synth.generate(kind, 0.3, 1, n_views=views)
        for name in names:
            try:
                cal = calibrate(s.train, name)
            except CalibError as exc:
                print(f"{kind:10s} {name:9s} refused: {exc}")
                continue
            held = evaluate(cal, s.holdout)["rmse"]
            print(f"{kind:10s} {name:9s} {cal.settings.get('chosen', '-'):16s} train {cal.metrics.rmse:.9f} "
                  f"hold-out {held:.9f} intrinsics {' '.join(f'{v:.6f}' for v in cal.model.intrinsics)}")


def detection(kind: str) -> None:
    """Corners found in rendered views (``freecal synth --images``' renderer), and a digest of their positions."""
    truth = synth.generate(kind).truth
    poses = [(v["name"], np.array(v["rvec"] + v["tvec"], dtype=np.float64)) for v in truth["train_views"]]
    images, _ = render.render_set(kind, poses, 0)
    c, r = synth.TRAIN_BOARD
    with tempfile.TemporaryDirectory() as tmp:
        for name, img in images:
            cv2.imwrite(str(Path(tmp) / name), img)
        obs = detect_images(image_paths([tmp]), BoardSpec.parse(f"chessboard:{c}x{r}:{synth.SQUARE:g}mm"),
                            workers=1).observations
    if obs is None:
        print(f"detection {kind}: no board found")
        return
    digest = hashlib.sha256()
    for view in obs.views:
        digest.update(np.round(view.image_points, 6).tobytes())
    print(f"detection {kind}: {sum(len(v.image_points) for v in obs.views)} corners in {len(obs.views)} views, "
          f"positions sha256 {digest.hexdigest()[:16]}")


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks fingerprint", description=__doc__.split("\n\n")[0])
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--detect", default="fisheye", help="lens of the rendered views to detect (none: skip)")
    a = ap.parse_args(argv)
    methods(synth.KINDS, [m for m in a.methods.split(",") if m], a.views)
    if a.detect != "none":
        detection(a.detect)
    sys.stdout.flush()
    return 0
