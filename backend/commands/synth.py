"""freecal synth --kind radial|fisheye|asymmetric --sigma 0.3 --seed 0 -o DIR"""
from __future__ import annotations

from pathlib import Path

from calib_core import synth
from calib_core.observations import write_json


def register(sub) -> None:
    p = sub.add_parser("synth", help="the paper's synthetic data with ground truth",
                       description="Write DIR/train.json (noisy), DIR/holdout.json (noise-free, whole image) "
                                   "and DIR/truth.json.")
    p.add_argument("--kind", choices=synth.KINDS, default="radial")
    p.add_argument("--sigma", type=float, default=0.3, help="corner noise per axis, pixels")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--views", type=int, default=10, help="training views")
    p.add_argument("-o", "--output", required=True, help="output directory")
    p.set_defaults(run=run)


def run(args) -> int:
    out = Path(args.output)
    s = synth.generate(args.kind, args.sigma, args.seed, args.views)
    s.train.save(out / "train.json")
    s.holdout.save(out / "holdout.json")
    write_json(out / "truth.json", s.truth)
    print(f"{args.kind}: {len(s.train.views)} training views ({s.train.n_points} corners, sigma {args.sigma} px), "
          f"{len(s.holdout.views)} hold-out views ({s.holdout.n_points} corners) in {out}/")
    return 0
