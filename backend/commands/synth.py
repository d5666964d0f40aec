"""freecal synth --kind radial|fisheye|asymmetric|freeform|decentred|fisheye200 --sigma 0.3 --seed 0 [--images] -o DIR"""
from __future__ import annotations

import sys

import cv2
import numpy as np

from calib_core import synth
from calib_core.errors import DataError

from .output import claim_stdout, json_text, print_json
from .outputs import OutputFolder, Outputs


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
    p.add_argument("--json", action="store_true", help="print what was written as JSON")
    p.set_defaults(run=run)


def run(args) -> int:
    outputs = Outputs()
    out = outputs.folder(args.output, "-o")
    assert out is not None  # -o is required
    if args.json:
        claim_stdout("--json")
    s = synth.generate(args.kind, args.sigma, args.seed, args.views)
    written = ["train.json", "holdout.json", "truth.json"]
    with outputs.writing():
        out.file("train.json").write(json_text(s.train.to_json()))
        out.file("holdout.json").write(json_text(s.holdout.to_json()))
        out.file("truth.json").write(json_text(s.truth))
        if args.images:
            written += write_images(out, args.kind, s.truth, args.seed)
    if args.json:
        print_json({"kind": args.kind, "sigma": args.sigma, "seed": args.seed, "folder": str(out),
                    "train": {"views": len(s.train.views), "corners": s.train.n_points},
                    "holdout": {"views": len(s.holdout.views), "corners": s.holdout.n_points},
                    "written": [str(out.target / name) for name in written]})
        return 0
    print(f"{args.kind}: {len(s.train.views)} training views ({s.train.n_points} corners, sigma {args.sigma} px), "
          f"{len(s.holdout.views)} hold-out views ({s.holdout.n_points} corners) in {out}/")
    if args.images:
        c, r = synth.TRAIN_BOARD
        from calib_core.synth import render

        print(f"{len(s.truth['train_views'])} images ({synth.IMAGE_SIZE[0]}x{synth.IMAGE_SIZE[1]}, blur {render.BLUR_SIGMA} px, "
              f"noise {render.NOISE_SIGMA} grey levels) in {out}/images/, exact corners in "
              f"{out.target / 'images_truth.json'}; board chessboard:{c}x{r}:{synth.SQUARE:g}mm")
    return 0


def write_images(out: OutputFolder, kind: str, truth: dict, seed: int) -> list[str]:
    """DIR/images/<view>.png for every training pose and DIR/images_truth.json; the names written."""
    from calib_core.synth import render

    poses = [(v["name"], np.array(v["rvec"] + v["tvec"], dtype=np.float64)) for v in truth["train_views"]]
    print(f"rendering {len(poses)} images ...", file=sys.stderr, flush=True)
    images, corners = render.render_set(kind, poses, seed)
    names = []
    for name, img in images:
        ok, png = cv2.imencode(".png", img)
        if not ok:
            raise DataError(f"could not encode {name} as PNG")
        out.file(f"images/{name}").write(png.tobytes())
        names.append(f"images/{name}")
    out.file("images_truth.json").write(json_text(corners.to_json()))
    return names + ["images_truth.json"]
