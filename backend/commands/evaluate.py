"""freecal evaluate CAL.json OBS.json: the hold-out protocol (pose-only refit)."""
from __future__ import annotations

from calib_core.evaluation.evaluate import evaluate

from .inputs import load_calibration, load_observations, one_stdin
from .output import claim_stdout, print_json, table


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="hold-out errors of a calibration on other views",
                       description="Hold the model fixed, refit each view's pose, report the errors.")
    p.add_argument("calibration", help="freecal.calibration/1 JSON (- : standard input)")
    p.add_argument("observations", help="freecal.observations/1 JSON of the views to evaluate (- : standard input)")
    p.add_argument("--json", action="store_true", help="print the result as JSON on standard output")
    p.set_defaults(run=run)


def run(args) -> int:
    one_stdin(args.calibration, args.observations)
    if args.json:
        claim_stdout("--json")
    result = evaluate(load_calibration(args.calibration), load_observations(args.observations))
    if args.json:
        print_json(result)
        return 0
    rows = [(v["name"], v["n_points"], v["rmse"], v["rmse_axis"], v["max_error"]) for v in result["views"]]
    rows.append(("overall", result["n_points"], result["rmse"], result["rmse_axis"], result["max_error"]))
    table(["view", "points", "rmse [px]", "rmse_axis [px]", "max [px]"], rows)
    print(f"\ncentre rmse {result['rmse_center']:.4f} px, edge rmse {result['rmse_edge']:.4f} px")
    return 0
