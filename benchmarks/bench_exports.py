"""What each export loses: for calibrations (files given, or the synthetic
lenses under a few methods), every target's default choice and its fit
error over the covered region and the whole image, as a Markdown table
(the figures of docs/exports.md).

    python -m benchmarks exports [CAL.json ...] [--targets opencv,ros,...] [--methods bspline,fisheye]
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from calib_core import Calibration, calibrate, synth
from calib_core.exports import TARGETS, export


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks exports", description=__doc__.split("\n\n")[0])
    ap.add_argument("calibrations", nargs="*", help="freecal.calibration/1 files (default: the synthetic lenses)")
    ap.add_argument("--targets", default=",".join(TARGETS))
    ap.add_argument("--methods", default="bspline,fisheye", help="methods for the synthetic lenses")
    args = ap.parse_args(argv)
    cals: list[tuple[str, Calibration]] = [(Path(p).stem, Calibration.load(p)) for p in args.calibrations]
    if not cals:
        for kind in synth.PAPER_KINDS:
            train = synth.generate(kind, 0.3, 0).train
            cals += [(f"synthetic {kind} / {m}", calibrate(train, m)) for m in args.methods.split(",") if m]
    print("| calibration | target | written as | covered rms / max px | whole image rms / max px | s |")
    print("|---|---|---|---|---|---|")
    for name, cal in cals:
        for to in args.targets.split(","):
            t0 = time.perf_counter()
            done = export(cal, to)
            f = done.fit
            how = "exact" if f.exact else "fitted"
            print(f"| {name} | {to} | {done.consumer_model} ({f.name}, {how}) | {f.covered.rms:.3g} / {f.covered.max:.3g} "
                  f"| {f.image.rms:.3g} / {f.image.max:.3g} | {time.perf_counter() - t0:.1f} |", flush=True)
    return 0
