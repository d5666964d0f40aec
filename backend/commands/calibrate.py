"""freecal calibrate OBS.json [--method auto] -o CAL.json [settings]
freecal calibrate IMAGES_OR_DIR... --board SPEC ... (detects first, then calibrates)"""
from __future__ import annotations

import argparse
from pathlib import Path

from calib_core import Calibration, Observations, calibrate
from calib_core.detection.detect import IMAGE_SUFFIXES
from calib_core.errors import SettingsError
from calib_core.fit_report import ChoiceReport, grid_score
from calib_core.pipeline import OUTLIER_SIGMA

from .detect import BOARD_HELP, TARGET_HELP, detect_with_report
from .inputs import STDIN, load_observations
from .output import claim_stdout, json_text, print_json, table
from .outputs import OutputFolder, Outputs
from .progress import StageProgress


def _pair(text: str) -> tuple[int, int]:
    """'8' or '8x10' → (8, 8) or (8, 10)."""
    try:
        parts = [int(p) for p in text.lower().split("x")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected N or NxM, got {text!r}") from None
    if len(parts) == 1:
        parts *= 2
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"expected N or NxM, got {text!r}")
    return parts[0], parts[1]


def _intervals(text: str):
    return "auto" if text == "auto" else _pair(text)


def _number_or_auto(text: str):
    if text == "auto":
        return text
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got {text!r}") from None


# (flag, settings key, type, help); only the flags given reach the method.
BSPLINE_FLAGS = [
    ("--core", "core", str, "parametric core under the field: none (the paper's model), zhang, rational, fisheye"),
    ("--knots", "knots", str, "knot strategy: kde, kde-paper (the paper's candidates only), uniform"),
    ("--intervals", "intervals", _intervals, "knot intervals per direction: N, NxM or auto (validation over views)"),
    ("--max-intervals", "max_intervals", int, "cap of knot intervals per direction (kde)"),
    ("--min-support", "min_support", int, "minimum corners per knot interval (default max(10, N/50))"),
    ("--bandwidth", "bandwidth", str, "KDE bandwidth rule: scott or silverman"),
    ("--bandwidth-factor", "bandwidth_factor", _number_or_auto,
     "KDE bandwidth multiplier (Table 2: 1.0), or auto (validation over views, with the intervals)"),
    ("--window-ratio", "window_ratio", float, "local-std window ratio rho"),
    ("--weighting", "weighting", str, "sample weights: local_std, uniform, magnitude, gradient"),
    ("--lambda-reg", "lambda_reg", float, "L2 weight on control values"),
    ("--lambda-smooth", "lambda_smooth", _number_or_auto, "bending-energy weight of the field, or auto (validation over views)"),
    ("--time-budget", "time_budget", float, "seconds the search over knot grids and bandwidths may take "
                                            "(default: no limit)"),
    ("--base", "base", str, "base projection of the paper's model (--core none): auto (the default: pinhole, "
                           "or the base nearer a wide lens's initial camera), pinhole, equidistant, stereographic"),
    ("--max-iterations", "max_iterations", int, "Levenberg-Marquardt iteration cap"),
    ("--ftol", "ftol", float, "relative cost decrease that ends the solve"),
]


def register(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate from observations (corners) JSON, or from images",
                       description="Calibrate a camera from freecal.observations/1 corners, or from photos "
                                   "(with --board: detect the board first, then calibrate).")
    p.add_argument("observations", nargs="+", metavar="OBS.json | - | IMAGES",
                   help="freecal.observations/1 JSON file (- : standard input), or image files and/or folders "
                        "(with --board)")
    p.add_argument("--board", help="detect this board in the images first; " + BOARD_HELP)
    p.add_argument("--target", metavar="T.json", help="detect these boards in the images first: " + TARGET_HELP)
    p.add_argument("--workers", type=int, default=None, help="detection worker processes (default: all cores)")
    p.add_argument("--method", default="auto", metavar="METHOD",
                   help="calibration method: auto (the default: the candidate that best predicts views left out "
                        "of its fit), bspline (the paper's field; settings below), zhang, rational, fisheye, mls, tps")
    p.add_argument("-o", "--output", metavar="CAL.json", help="write the freecal.calibration/1 JSON here (- : standard output)")
    p.add_argument("--json", action="store_true",
                   help="print the calibration JSON on standard output instead of the summary (which goes to "
                        "standard error)")
    p.add_argument("--report", metavar="DIR",
                   help="write the report the results page shows into DIR: residual tables (JSON, CSV), heatmap, "
                        "distortion field, knot grid, projection uncertainty, and their figures (PNG)")
    p.add_argument("--outlier-sigma", type=float, default=OUTLIER_SIGMA,
                   help="reject residuals beyond this many robust sigmas (0: keep all)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="any other method setting, e.g. --set lambda_smooth=0.5")
    for flag, key, typ, text in BSPLINE_FLAGS:
        p.add_argument(flag, dest=key, type=typ, default=None, help=text)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def settings_of(args) -> dict:
    given = [flag for flag, key, _, _ in BSPLINE_FLAGS if getattr(args, key) is not None]
    if given and args.method != "bspline":
        raise SettingsError(f"{', '.join(given)} set the B-spline field: add --method bspline (--method {args.method} "
                            + ("chooses the model, knot grid and smoothing itself)" if args.method == "auto" else
                               "takes its settings with --set KEY=VALUE)"))
    flags = {key: flag for flag, key, _, _ in BSPLINE_FLAGS if getattr(args, key) is not None}
    settings = {key: getattr(args, key) for key in flags}
    return {**settings, **set_settings(args.set, flags)}


def set_settings(items: list[str], flags: dict[str, str] | None = None) -> dict:
    """The method settings given as ``--set KEY=VALUE``; a key set by its own flag (``flags``:
    key → flag given; outlier_sigma always has one) is refused rather than one silently winning."""
    flags = {"outlier_sigma": "--outlier-sigma", **(flags or {})}
    settings = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise SettingsError(f"--set {item!r}: expected KEY=VALUE")
        if key.strip() in flags:
            raise SettingsError(f"--set {item!r}: {key.strip()} has its own flag: give it as "
                                f"{flags[key.strip()]} {value.strip()} instead")
        if key.strip() in NOT_SETTINGS:
            raise SettingsError(f"--set {item!r}: {key.strip()} is not a method setting; see the command's own "
                                "flags (--help)")
        settings[key.strip()] = _value(value.strip())
    return settings


# calibrate()'s and calibrate_rig()'s other parameters: a --set of one would pass it twice
NOT_SETTINGS = {"observations", "method", "progress", "cameras", "reference", "refine_models"}


def _value(text: str):
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def observations_of(args) -> Observations:
    """The observations JSON, or (with --board) the corners detected in the images given."""
    if args.board or args.target:
        det = detect_with_report(args.observations, args.board, args.quiet, args.workers, target_path=args.target)
        print()
        assert det.observations is not None  # detect_with_report raises when no image gave corners
        return det.observations
    if args.observations == [STDIN]:
        return load_observations(STDIN)
    first = Path(args.observations[0])
    if len(args.observations) != 1 or first.is_dir() or first.suffix.lower() in IMAGE_SUFFIXES:
        raise SettingsError("to calibrate from images, say which board they show: --board SPEC "
                            "(e.g. chessboard:9x6:25mm) or --target T.json (several boards on one object); "
                            "otherwise give one observations JSON file")
    return load_observations(args.observations[0])


def run(args) -> int:
    outputs = Outputs()
    cal_file = outputs.file(args.output, "-o", "cal.json")
    report = outputs.folder(args.report, "--report")
    settings = settings_of(args)
    if args.json:
        claim_stdout("--json")
    obs = observations_of(args)
    with StageProgress(args.quiet) as progress:
        cal = calibrate(obs, args.method, progress=progress, outlier_sigma=args.outlier_sigma, **settings)
    from calib_core.report.tables import camera

    cal.diagnostics.camera = camera(cal, obs)  # parameters ± σ, field of view, verdict: as the page shows them
    with outputs.writing():
        if cal_file is not None:
            cal_file.write(json_text(cal.to_json()))
        written = write_report(report, cal, obs) if report is not None else []
    if args.json:
        print_json(cal.to_json())
        return 0
    print_summary(cal)
    print_flags(cal, obs)
    if cal_file is not None and not cal_file.to_stdout:
        print(f"\nwrote {cal_file}")
    if written:
        print(f"wrote the report into {report}: {', '.join(written)}")
    return 0


def write_report(folder: OutputFolder, cal, obs: Observations) -> list[str]:
    """The results page's products, their figures and the page itself (report.html, as
    ``freecal report`` writes it) as files in ``folder`` (inside ``Outputs.writing``:
    they land with the other outputs, or not at all)."""
    import json

    from calib_core.calibration import json_safe
    from calib_core.report import tables

    from .report import write_report_page

    products = tables.report_products(cal, obs)
    for name, content in products.items():
        text = content if isinstance(content, str) else json.dumps(
            json_safe(content), indent=1 if name == "calibration.json" else None)
        folder.file(name).write(text)
    figures = write_report_page(folder.file("report.html"), folder, cal, obs, "calibration", products)
    return sorted([*products, *figures, "report.html"])


def print_summary(cal: Calibration) -> None:
    m, d = cal.metrics, cal.diagnostics
    assert m is not None  # calibrate() measures every fit
    fx, fy, cx, cy, s = cal.model.intrinsics
    print(f"method {cal.method}: fx={fx:.3f} fy={fy:.3f} cx={cx:.3f} cy={cy:.3f} skew={s:.4f} (pixels)")
    if d.model_choice is not None:
        print_choice(d.model_choice)
    if d.restart is not None:
        r = d.restart
        print(f"restarted from a parametric camera: {r.reason}; kept the {r.kept} fit "
              f"({r.first.rmse:.3f} px first, {r.restarted.rmse:.3f} px restarted)")
        if r.warning:
            print(f"warning: {r.warning}")
    choice = d.extra.get("base_choice")
    if choice:  # base auto (the paper's model)
        misfit = ", ".join(f"{b} {v:.3f}" for b, v in choice["misfit"].items())
        print(f"base projection: {choice['base']}, chosen by the initial camera's radial profile, its misfit to "
              f"each base's ({misfit}; the pinhole is left beyond {choice['max_misfit']:g} for a nearer base)")
    if "design" in d.extra:  # the B-spline method's own records
        g = d.extra["design"]
        print(f"knot intervals {g['intervals'][0]} x {g['intervals'][1]}, design rank {g['rank']}/{g['n_controls']}, "
              f"zero columns {g['zero_columns']}")
    curve = d.extra.get("smoothing_curve")
    if curve:
        print("knot grid, bandwidth and smoothing chosen by how well the field predicts views left out of its fit "
              "(lower is better):")
        chosen = [cal.settings.get("intervals_used"), cal.settings.get("bandwidth_factor_used")]
        table(["grid", "bandwidth factor", "lambda_smooth", "validation [px^2]", "effective parameters", "chosen"],
              [_curve_row(c, chosen) for c in curve])
    if d.camera is not None:
        print_camera(d.camera)
    if d.solver is not None:
        print(f"solver: {d.solver.status} after {d.solver.iterations} iterations ({d.solver.message}), "
              f"{d.solver.seconds:.2f} s")
    print()
    rows = [(v.name, v.n_points, v.rmse, v.rmse_axis, len(v.outliers)) for v in cal.views]
    rows.append(("overall", m.n_points, m.rmse, m.rmse_axis, sum(len(v.outliers) for v in cal.views)))
    table(["view", "points", "rmse [px]", "rmse_axis [px]", "outliers"], rows)
    print(f"\ncentre rmse {m.rmse_center:.4f} px, edge rmse {m.rmse_edge:.4f} px")
    if d.excluded_points is not None and d.excluded_points.misplaced:
        print(f"{d.excluded_points.misplaced} corners set aside before the fit as misplaced (beyond the image, or not "
              "where their board neighbours put them: wrong ids?); they are counted among the outliers")
    for dv in cal.dropped_views:
        print(f"dropped {dv['name']}: {dv['reason']}")


def print_camera(cam: dict) -> None:
    """The parameters ± one standard deviation, the field of view and the verdict."""
    print(f"model: {cam['model']}, {cam['chosen']}")
    table(["parameter", "value", "± one standard deviation", "unit", "note"],
          [(p["name"], f"{p['value']:.6g}", "—" if p["std"] is None else f"{p['std']:.2g}", p["unit"], p.get("note", ""))
           for p in cam["parameters"]])
    far = cam.get("no_ray_beyond_px") or {}
    print("field of view: " + ", ".join(_fov_part(k, v, far.get(k)) for k, v in cam["field_of_view_deg"].items()))
    print(f"verdict: {cam['verdict']['text']}")


def _fov_part(line: str, degrees: float | None, no_ray_px: float | None) -> str:
    if degrees is not None:
        return f"{line} {degrees:.1f} deg"
    if no_ray_px is not None:
        return f"{line}: no ray past {no_ray_px:.0f} px from the principal point"
    return f"{line}: past the model's reach"


def print_choice(choice: ChoiceReport) -> None:
    """The model choice in words, and the score table that made it."""
    print(f"model chosen: {choice.summary}")
    print(f"rule: {choice.rule}; {choice.how}")
    table(["candidate", "validation rmse per axis [px]", "± one standard error of its excess", "parameters", "chosen"],
          [(c.label, _or_dash(c.validation_rmse), _or_dash(c.standard_error_rmse), c.n_params or "—",
            "*" if c.chosen else choice.status(c))
           for c in choice.candidates])


def _or_dash(x):
    return "—" if x is None else x


def _curve_row(c: dict, chosen: list) -> tuple:
    grid = "x".join(map(str, c["intervals"]))
    factor = c.get("bandwidth_factor")  # absent from calibrations made before it was chosen
    shown = "—" if factor is None else f"{factor:g}"
    if "skipped" in c:
        return grid, shown, "—", "—", "—", f"skipped ({c['skipped']})"
    return (grid, shown, c["lambda_smooth"], grid_score(c), f"{c['dof']:.0f}",
            "*" if [c["intervals"], factor] == chosen else "")


def print_flags(cal, obs: Observations) -> None:
    """The views that look suspicious (``calib_core.evaluation.view_flags``), with why; silent when none do."""
    from calib_core.evaluation.view_flags import view_flags

    flagged = [r for r in view_flags(cal, obs) if r["flags"]]
    if not flagged:
        return
    print(f"\n{len(flagged)} view(s) look suspicious:")
    for r in flagged:
        print(f"  {r['view']}: " + "; ".join(f["text"] for f in r["flags"]))
