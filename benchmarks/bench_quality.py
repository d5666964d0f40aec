"""Table 7 of Wang et al. 2026 (rectification quality) on the paper's
synthetic protocol, for every method, the raw image and the ground truth,
beside the paper's values (measured there on the real YP lens, which is not
public: compare the ranking and the ratios, not the numbers).

    python -m benchmarks quality [--kinds radial,fisheye,asymmetric] [--on train,holdout]
        [--methods zhang,...] [--sigma 0.3] [--seed 0]

``train``: the noisy (σ) training boards, as ``freecal compare`` measures
them (the noise floor: truth's straightness ≈ σ); ``holdout``: noise-free
unseen boards covering the whole image, corners included (model error alone;
truth gives 0). Metrics: ``calib_core/evaluation/quality.py``.
"""
from __future__ import annotations

import argparse
import sys
import time

from calib_core import synth
from calib_core.errors import CalibError
from calib_core.evaluation.quality import METRICS, geometric_quality, raw_quality
from calib_core.pipeline import calibrate
from calib_core.synth.truth import truth_calibration

METHODS = ["zhang", "rational", "fisheye", "mls", "tps", "bspline"]
# Paper Table 7 (real YP lens): straightness px, spacing CV, orthogonality deg, smoothness.
# BabelCalib = KB (our fisheye), McCalib = rational 8 (our rational).
PAPER_T7 = {"raw image": (11.16, 0.111, 5.82, 0.095), "zhang": (3.850, 0.072, 2.94, 0.061),
            "fisheye": (2.650, 0.056, 2.15, 0.049), "rational": (2.420, 0.053, 1.95, 0.045),
            "mls": (1.980, 0.047, 1.60, 0.038), "tps": (1.780, 0.043, 1.42, 0.032),
            "bspline": (1.420, 0.036, 1.12, 0.025)}


def _fmt(v) -> str:
    if v is None or v != v:
        return "—"
    return f"{v:.3g}" if abs(v) < 0.01 else f"{v:.3f}"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks quality", description=__doc__.split("\n\n")[0])
    ap.add_argument("--kinds", default=",".join(synth.PAPER_KINDS), help=f"any of {', '.join(synth.KINDS)}")
    ap.add_argument("--on", default="train,holdout", help="which boards: train (noisy), holdout (noise-free)")
    ap.add_argument("--methods", default=",".join(METHODS))
    ap.add_argument("--sigma", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    methods = [m for m in args.methods.split(",") if m]
    sets = [s for s in args.on.split(",") if s]
    for kind in [k for k in args.kinds.split(",") if k]:
        data = synth.generate(kind, args.sigma, args.seed)
        cals = {"truth": truth_calibration(kind)}
        for m in methods:
            t0 = time.perf_counter()
            try:
                cals[m] = calibrate(data.train, m)
            except CalibError as exc:
                print(f"{kind}/{m}: could not calibrate: {exc}", file=sys.stderr)
                continue
            print(f"[{kind}] {m}: calibrated in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)
        for which in sets:
            obs = data.train if which == "train" else data.holdout
            print(f"\nTable 7, synthetic {kind} lens, {which} boards "
                  f"({f'σ = {args.sigma:g} px' if which == 'train' else 'noise-free'}; {obs.n_points} corners); "
                  "paper (real lens) in brackets")
            rows = [("raw image", raw_quality(obs))]
            rows += [(name, geometric_quality(cal, obs, with_smoothness=True)) for name, cal in cals.items()]
            head = ["method"] + [label for _, label in METRICS]
            cells = []
            for name, q in rows:
                paper = PAPER_T7.get(name)
                cells.append([name] + [_fmt(q.get(k)) + (f" [{paper[i]:g}]" if paper else "")
                                       for i, (k, _) in enumerate(METRICS)])
            widths = [max(len(h), *(len(r[i]) for r in cells)) for i, h in enumerate(head)]
            print("  ".join(h.rjust(w) for h, w in zip(head, widths, strict=True)))
            print("  ".join("-" * w for w in widths))
            for r in cells:
                print("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
