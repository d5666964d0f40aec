"""freecal diff A.json B.json [--map DIFF.png] [--json]: how far two calibrations of
one camera disagree on where a direction lands (calib_core/evaluation/diff.py)."""
from __future__ import annotations

from calib_core.evaluation.diff import DEFAULT_GRID, FIT_REGIONS, projection_diff

from .inputs import load_calibration, one_stdin
from .output import claim_stdout, print_json, table
from .outputs import Outputs

REGION_WORDS = {"covered": "over the region both calibrations cover", "centre": "over the image centre",
                "none": "not fitted (the camera frames taken as the same)"}


def register(sub) -> None:
    p = sub.add_parser("diff", help="the projection difference between two calibrations of one camera",
                       description="Unproject a grid of pixels with A, turn the rays by the rotation between the "
                                   "two calibrations' camera frames, project with B: the difference in pixels over "
                                   "the image (as mrcal-show-projection-diff), as a summary and a map.")
    p.add_argument("a", metavar="A.json", help="freecal.calibration/1 JSON (- : standard input)")
    p.add_argument("b", metavar="B.json", help="freecal.calibration/1 JSON of the same camera (- : standard input)")
    p.add_argument("--map", metavar="DIFF.png", help="write the difference over the image as a PNG (- : standard output)")
    p.add_argument("--grid", type=int, default=DEFAULT_GRID, help=f"pixels sampled across the image [{DEFAULT_GRID}]")
    p.add_argument("--fit-region", choices=FIT_REGIONS, default="covered",
                   help="where the rotation between the camera frames is fitted: covered (where both calibrations "
                        "had corners; the default), centre (a disc of min(W,H)/6, mrcal's default), none")
    p.add_argument("--json", action="store_true", help="print the summary (and the map's values) as JSON")
    p.set_defaults(run=run)


def run(args) -> int:
    outputs = Outputs()
    figure = outputs.file(args.map, "--map", "diff.png")
    one_stdin(args.a, args.b)
    if args.json:
        claim_stdout("--json")
    a, b = load_calibration(args.a), load_calibration(args.b)
    result = projection_diff(a, b, args.grid, args.fit_region)
    doc = result.to_json()
    if figure is not None:
        from calib_core.report.figures import projection_diff_map

        png = projection_diff_map(doc)
        with outputs.writing():
            figure.write(png)
    if args.json:
        print_json(doc)
        return 0
    s = result.summary()
    nu, nv = s["grid"]
    print(f"projection difference from A ({a.method}, {a.model.kind}) to B ({b.method}, {b.model.kind}) over a "
          f"{nu} x {nv} grid of the {s['image_size'][0]} x {s['image_size'][1]} image")
    fitted = s["fitted_on"].split(" ", 1)
    words = REGION_WORDS[fitted[0]] + (f" {fitted[1]}" if len(fitted) > 1 else "")
    print(f"rotation between the camera frames: {s['rotation_deg']:.4f} degrees, fitted {words}"
          if fitted[0] != "none" else f"rotation between the camera frames {words}")
    rows = [(name, r["n"], _or_nan(r["median"]), _or_nan(r["p95"]), _or_nan(r["max"]))
            for name, r in (("image", s["image"]), ("covered", s["covered"])) if r is not None]
    table(["region", "pixels", "median [px]", "p95 [px]", "max [px]"], rows)
    if s["covered"] is None:
        print("(no covered region: a calibration records no coverage hull)")
    if figure is not None and not figure.to_stdout:
        print(f"wrote {figure}")
    return 0


def _or_nan(x):
    return float("nan") if x is None else x
