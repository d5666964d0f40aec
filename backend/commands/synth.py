"""freecal synth --kind radial|fisheye|asymmetric|freeform|decentred|fisheye200 --sigma 0.3 --seed 0 [--images] -o DIR"""
from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

from calib_core import synth
from calib_core.errors import DataError
from calib_core.observations import write_json


def register(sub) -> None:
    p = sub.add_parser("synth", help="the paper's synthetic data with ground truth",
                       description="Write DIR/train.json (noisy), DIR/holdout.json (noise-free, whole image) "
                                   "and DIR/truth.json; with --images also photo-like PNGs of the training "
                                   "views (DIR/images/) and their exact corners (DIR/images_truth.json).")
    p.add_argument("--kind", choices=synth.ALL_KINDS, default="radial",
                   help="the synthetic lens (fisheye200: a circular fisheye of 200 degrees)")
    p.add_argument("--sigma", type=float, default=0.3, help="corner noise per axis, pixels")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--views", type=int, default=10, help="training views")
    p.add_argument("--images", action="store_true",
                   help="also render the training views as 8-bit PNGs (board chessboard:22x22:50mm)")
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
    if args.images:
        write_images(out, args.kind, s.truth, args.seed)
    return 0


def write_images(out: Path, kind: str, truth: dict, seed: int) -> None:
    """DIR/images/<view>.png for every training pose and DIR/images_truth.json."""
    from calib_core.synth import render

    poses = [(v["name"], np.array(v["rvec"] + v["tvec"], dtype=np.float64)) for v in truth["train_views"]]
    folder = out / "images"
    folder.mkdir(parents=True, exist_ok=True)
    print(f"rendering {len(poses)} images ...", file=sys.stderr, flush=True)
    images, corners = render.render_set(kind, poses, seed)
    for name, img in images:
        if not cv2.imwrite(str(folder / name), img):
            raise DataError(f"could not write {folder / name}: check the folder is writable")
    corners.save(out / "images_truth.json")
    c, r = synth.TRAIN_BOARD
    print(f"{len(images)} images ({synth.IMAGE_SIZE[0]}x{synth.IMAGE_SIZE[1]}, blur {render.BLUR_SIGMA} px, "
          f"noise {render.NOISE_SIGMA} grey levels) in {folder}/, exact corners in {out / 'images_truth.json'}; "
          f"board chessboard:{c}x{r}:{synth.SQUARE:g}mm")
