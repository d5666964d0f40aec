"""freecal rig LEFT.json RIGHT.json ... -o RIG.json: several cameras calibrated together."""
from __future__ import annotations

from pathlib import Path

from calib_core.errors import SettingsError
from calib_core.json_fields import CAMERA_NAME_RULE, is_camera_name
from calib_core.pipeline import OUTLIER_SIGMA
from calib_core.rig import calibrate_rig, evaluate_rig

from .calibrate import set_settings
from .inputs import load_observations
from .output import claim_stdout, json_text, print_json, table
from .outputs import Outputs
from .progress import StageProgress


def register(sub) -> None:
    p = sub.add_parser("rig", help="calibrate several cameras fixed together (a stereo pair, a rig)",
                       description="Calibrate each camera from its own observations, then the cameras' poses "
                                   "relative to the reference camera, the board's pose at every frame and (unless "
                                   "--hold-models) the cameras' models, from all the corners together. Views of different cameras are matched by frame: a view's "
                                   "\"frame\", else the last number in its name (left07.jpg and right07.jpg are "
                                   "frame 07). Writes freecal.rig/1 (docs/formats.md, section 4).")
    p.add_argument("observations", nargs="+", metavar="CAMERA.json",
                   help="one freecal.observations/1 file per camera (freecal detect ... -o CAMERA.json)")
    p.add_argument("--names", metavar="A,B,...",
                   help="the cameras' names, in the order of the files (default: the files' names without .json)")
    p.add_argument("--reference", metavar="NAME", help="the camera the others are placed from (default: the first)")
    p.add_argument("--method", default="auto", metavar="METHOD",
                   help="each camera's calibration method, as for freecal calibrate (default auto)")
    p.add_argument("--hold-models", action="store_true",
                   help="keep each camera's model as calibrated alone (OpenCV's stereoCalibrate with "
                        "CALIB_FIX_INTRINSIC); by default the rig's fit refines them with the poses")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a method setting, as for calibrate")
    p.add_argument("--outlier-sigma", type=float, default=OUTLIER_SIGMA,
                   help="reject residuals beyond this many robust sigmas in each camera's calibration (0: keep all)")
    p.add_argument("--holdout", nargs="+", metavar="CAMERA_TEST.json",
                   help="other views of the same cameras, one file per camera in the same order: the rig's errors on "
                        "them, each frame's board pose refit from every camera that saw it (models and relative poses "
                        "held)")
    p.add_argument("-o", "--output", metavar="RIG.json", help="write the freecal.rig/1 JSON here (- : standard output)")
    p.add_argument("--json", action="store_true", help="print the rig JSON on standard output instead of the summary")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress lines")
    p.set_defaults(run=run)


def camera_names(args) -> list[str]:
    if len(args.observations) < 2:
        raise SettingsError("a rig needs two or more cameras: give one observations file per camera")
    if args.names is None:
        names = [Path(p).stem for p in args.observations]
        if len(set(names)) != len(names):
            raise SettingsError(f"two files have the same name {names}: name the cameras with --names A,B,...")
        bad = next((n for n in names if not is_camera_name(n)), None)
        if bad is not None:  # a name ends up in the exports' YAML and ROS topics: the service's rule
            raise SettingsError(f"{bad[:70]!r} (a file's name) is not a camera name: name the cameras with "
                                f"--names A,B,... ({CAMERA_NAME_RULE})")
        return names
    names = [n.strip() for n in args.names.split(",")]
    if len(names) != len(args.observations) or not all(names) or len(set(names)) != len(names):
        raise SettingsError(f"--names {args.names}: expected {len(args.observations)} distinct names, one per file")
    bad = next((n for n in names if not is_camera_name(n)), None)
    if bad is not None:
        raise SettingsError(f"--names: {bad[:70]!r} is not a camera name: {CAMERA_NAME_RULE}")
    return names


def run(args) -> int:
    outputs = Outputs()
    rig_file = outputs.file(args.output, "-o", "rig.json")
    names = camera_names(args)
    if args.holdout is not None and len(args.holdout) != len(names):
        raise SettingsError(f"--holdout: expected {len(names)} files, one per camera in the order of the cameras, "
                            f"got {len(args.holdout)}")
    if args.reference is not None and args.reference not in names:
        raise SettingsError(f"--reference {args.reference}: not one of the cameras {names}")
    settings = set_settings(args.set)
    if args.json:
        claim_stdout("--json")
    cameras = {name: load_observations(path) for name, path in zip(names, args.observations, strict=True)}
    holdout = None if args.holdout is None else {
        name: load_observations(path) for name, path in zip(names, args.holdout, strict=True)}
    for (name, test), path in zip((holdout or {}).items(), args.holdout or [], strict=True):
        if tuple(test.image_size) != tuple(cameras[name].image_size):  # said before the calibration, not after
            raise SettingsError(f"--holdout {path}: its images are {test.image_size[0]}x{test.image_size[1]}, those of "
                                f"camera {name!r} {cameras[name].image_size[0]}x{cameras[name].image_size[1]}: give "
                                "each camera's held-out views in the order of the cameras")
    with StageProgress(args.quiet) as progress:
        rig = calibrate_rig(cameras, args.method, args.reference, progress, refine_models=not args.hold_models,
                            outlier_sigma=args.outlier_sigma, **settings)
    with outputs.writing():
        if rig_file is not None:
            rig_file.write(json_text(rig.to_json()))
    if args.json:
        print_json(rig.to_json())
        return 0
    print_rig(rig)
    if holdout is not None:
        print_holdout(evaluate_rig(rig, holdout))
    if rig_file is not None and not rig_file.to_stdout:
        print(f"\nwrote {rig_file}")
    return 0


def print_rig(rig) -> None:
    rows = []
    for cam in rig.cameras:
        d = rig.diagnostics["cameras"][cam.name]
        fx, fy, cx, cy, _ = cam.calibration.model.intrinsics
        chosen = cam.calibration.settings.get("chosen", cam.calibration.method)
        rows.append((cam.name, chosen, f"{fx:.1f} / {fy:.1f}", f"{cx:.1f}, {cy:.1f}", d["n_frames"],
                     d["rmse_alone"], d["rmse_in_rig"], _vector(cam.rvec, 5), _vector(cam.tvec, 3)))
    table(["camera", "model", "fx / fy", "cx, cy", "frames", "rmse alone [px]", "rmse in rig [px]",
           "rvec to reference [rad]", "tvec to reference"], rows)
    for cam in rig.cameras:
        choice = cam.calibration.diagnostics.model_choice
        if choice is not None:  # the score tables: freecal calibrate on that camera's observations prints them
            print(f"camera {cam.name}: {choice.summary}")
    m, sv = rig.metrics, rig.diagnostics["solver"]
    held = "refined with the poses" if sv["models_refined"] else "held as calibrated alone"
    print(f"rig: {m.n_points} corners in {len(rig.frames)} frames, rmse {m.rmse:.4f} px "
          f"(per axis {m.rmse_axis:.4f}), the cameras' models {held}; solver {sv['status']} after "
          f"{sv['iterations']} iterations")
    for w in rig.diagnostics.get("warnings", []):
        print(f"warning: {w}")


def print_holdout(result: dict) -> None:
    print(f"\nhold-out: {result['n_points']} corners in {result['n_frames']} frames ({result['n_shared_frames']} seen by "
          "more than one camera), each frame's board pose refit, models and relative poses held")
    rows = [(name, c["n_points"], c["rmse"], c["rmse_axis"]) for name, c in result["cameras"].items()]
    rows.append(("overall", result["n_points"], result["rmse"], result["rmse_axis"]))
    table(["camera", "points", "rmse [px]", "rmse_axis [px]"], rows)


def _vector(v, decimals: int) -> str:
    return "[" + ", ".join(f"{x:.{decimals}f}" for x in v) + "]"
