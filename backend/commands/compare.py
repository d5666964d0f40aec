"""freecal compare OBS.json [--holdout H.json] [--splits 5] [--methods a,b] [--json]"""
from __future__ import annotations

from calib_core.evaluation.compare import compare

from .inputs import load_observations, one_stdin
from .output import claim_stdout, print_json, table
from .progress import StageProgress


def register(sub) -> None:
    p = sub.add_parser("compare", help="every method on the same corners, side by side, and a verdict",
                       description="Calibrate with every method on the same corners; compare fit, "
                                   "cross-validated and hold-out errors; pick the method to trust.")
    p.add_argument("observations", help="freecal.observations/1 JSON file (- : standard input)")
    p.add_argument("--holdout", help="freecal.observations/1 JSON of other views to validate on (pose-only refit; "
                                     "- : standard input)")
    p.add_argument("--splits", type=int, default=5, help="cross-validation folds over the views (0: none)")
    p.add_argument("--methods", help="comma-separated methods (default: zhang,rational,fisheye,mls,tps,bspline)")
    p.add_argument("--json", action="store_true", help="print one JSON object on standard output instead of tables")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def run(args) -> int:
    one_stdin(args.observations, args.holdout)
    if args.json:
        claim_stdout("--json")
    obs = load_observations(args.observations)
    holdout = load_observations(args.holdout) if args.holdout else None
    methods = [m.strip() for m in args.methods.split(",") if m.strip()] if args.methods else None
    with StageProgress(args.quiet, "comparing") as progress:
        result = compare(obs, methods, args.splits, holdout, progress)
    if args.json:
        print_json(result.to_json())
        return 0
    print_tables(result.to_json())
    return 0


def _pm(d: dict) -> str:
    return f"{d['mean']:.4f} ± {d['std']:.4f}"


def print_tables(result: dict) -> None:
    """The comparison as tables, from the document ``--json`` prints (``Comparison.to_json``)."""
    ms = result["methods"]
    ok = [m for m in ms if "error" not in ms[m]]
    print("Fit: per-view and overall rmse [px, per point: sqrt(mean(dx²+dy²))] (paper Tables 4 and 6)")
    names = [v["name"] for v in ms[ok[0]]["views"]] if ok else []
    rows = []
    for vn in names:
        row = [vn]
        for m in ok:
            match = [v["rmse"] for v in ms[m]["views"] if v["name"] == vn]
            row.append(match[0] if match else float("nan"))
        rows.append(row)
    rows.append(["overall"] + [ms[m]["rmse"] for m in ok])
    rows.append(["overall rmse_axis"] + [ms[m]["rmse_axis"] for m in ok])
    table(["view"] + ok, rows)
    if any("cv" in ms[m] for m in ok):
        print(f"\nCross-validation over views, {result['splits']} splits, each view validated once "
              "(model held, pose refit) [rmse px, mean ± std] (paper Table 8)")
        table(["method", "calibration", "validation", "increase"],
              [[m, _pm(ms[m]["cv"]["calibration_rmse"]), _pm(ms[m]["cv"]["validation_rmse"]), _pm(ms[m]["cv"]["increase"])]
               for m in ok if "cv" in ms[m]])
    print("\nCentre vs edge: observed pixel in [0.25, 0.75]² of the image, or not [rmse px] (paper Table 9)")
    table(["method", "centre", "edge"], [[m, ms[m]["rmse_center"], ms[m]["rmse_edge"]] for m in ok])
    if any("holdout_rmse" in ms[m] for m in ok):
        print("\nHold-out views (model held, pose refit) [rmse px]")
        table(["method", "rmse", "rmse_axis", "centre", "edge"],
              [[m, ms[m]["holdout_rmse"], ms[m]["holdout_rmse_axis"], ms[m]["holdout_rmse_center"], ms[m]["holdout_rmse_edge"]]
               for m in ok])
    print_quality(result)
    for m in ms:
        if "error" in ms[m]:
            print(f"\n{m}: could not calibrate: {ms[m]['error']}")
    d = result["verdict_detail"]
    print(f"\nVerdict: {result['verdict']}" + (f" (lowest {d['by']}: {d['value']:.4f} px)" if "by" in d else f" ({d.get('reason')})"))
    s = d.get("spatial_structure")
    if s:
        state = "still show spatial structure" if s["structured"] else "show no spatial structure"
        print(f"Its validation residuals {state}: neighbour correlation rho = {s['rho']:.3f}, "
              f"p = {s['p_value']:.3f} ({s['n_pairs']} neighbour pairs)")


def print_quality(result: dict) -> None:
    """Table 7: the boards' geometry after each method's rectification (calib_core/evaluation/quality.py)."""
    ms = result["methods"]
    rows = [("raw image", result.get("quality_raw", {}))] + [(m, ms[m].get("quality", {})) for m in ms if "error" not in ms[m]]
    rows = [(name, q) for name, q in rows if q and "error" not in q]
    if not rows:
        return
    from calib_core.evaluation.quality import METRICS

    print("\nRectification quality on the boards (paper Table 7; straightness in rectified px, "
          "orthogonality in degrees, smoothness: mean |Hessian| of the distortion field [1/px])")
    table(["method"] + [label for _, label in METRICS], [[name] + [float("nan") if q.get(k) is None else q[k] for k, _ in METRICS]
                                                         for name, q in rows])
