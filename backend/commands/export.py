"""freecal export CAL.json --to opencv|ros|mrcal|opencv5|opencv8|opencv14|kb4 [--model M] -o FILE"""
from __future__ import annotations

import io

import numpy as np

from calib_core.errors import SettingsError
from calib_core.exports import LEAN_MODELS, cameramodel, exact_name, fit_lean, lean_yaml, parametric_part, ros_yaml
from calib_core.exports.lean_fit import save_error_map

from .inputs import load_calibration, load_observations, one_stdin
from .output import claim_stdout, print_json
from .outputs import Outputs

FORMATS = ("opencv", "ros", "mrcal")
DEFAULT_MODEL = {"opencv": "opencv8", "ros": "opencv8", "mrcal": "opencv8"}


def register(sub) -> None:
    p = sub.add_parser("export", help="export a calibration for OpenCV, ROS or mrcal (lean-model fit)",
                       description="Write a calibration in another tool's format. A calibration that is not "
                                   "already the chosen lean model is fitted by one over the image, and the fit "
                                   "error (what the export loses) is printed and stored.")
    p.add_argument("calibration", help="freecal.calibration/1 JSON file (- : standard input)")
    p.add_argument("--to", required=True, choices=FORMATS + tuple(LEAN_MODELS),
                   help="opencv (FileStorage YAML), ros (camera_info YAML), mrcal (.cameramodel); "
                        "a model name (opencv8, kb4, ...) means opencv with that model")
    p.add_argument("--model", choices=("auto",) + tuple(LEAN_MODELS), default="auto",
                   help="lean model (auto: the calibration's own if it is one, else opencv8)")
    p.add_argument("--observations", help="fit only over the convex hull of these corners (freecal.observations/1)")
    p.add_argument("--error-map", help="write the fit error map (.npz: error_px, u, v)")
    p.add_argument("-o", "--output", required=True, help="output file (- : standard output)")
    p.add_argument("--json", action="store_true", help="print what was written and the fit error as JSON")
    p.set_defaults(run=run)


def run(args) -> int:
    outputs = Outputs()
    target = outputs.file(args.output, "-o", "camera.yaml")
    error_map = outputs.file(args.error_map, "--error-map", "error_map.npz")
    one_stdin(args.calibration, args.observations)
    if args.json:
        claim_stdout("--json")
    cal = load_calibration(args.calibration)
    cal = parametric_part(cal) or cal  # a hybrid with a held zero field is its core, exactly
    fmt, model = (args.to, args.model) if args.to in FORMATS else ("opencv", args.to)
    if args.to not in FORMATS and args.model != "auto" and args.model != args.to:
        raise SettingsError(f"--to {args.to} already names the model; drop --model {args.model}")
    if model == "auto":
        model = exact_name(cal) or DEFAULT_MODEL[fmt]
    covered = None
    if args.observations:
        obs = load_observations(args.observations)
        covered = np.concatenate([np.asarray(v.image_points, dtype=np.float64) for v in obs.views])
    fit = fit_lean(cal, model, covered=covered)
    if fmt == "opencv":
        text = lean_yaml(fit, cal)
    elif fmt == "ros":
        text = ros_yaml(fit)
    else:
        text = cameramodel(fit)
    with outputs.writing():
        assert target is not None  # -o is required
        target.write(text)
        if error_map is not None:
            npz = io.BytesIO()
            save_error_map(npz, fit)
            error_map.write(npz.getvalue())
    if args.json:
        print_json({"format": fmt, "model": model, "exact": fit.exact, "output": str(target),
                    "error_map": None if error_map is None else str(error_map),
                    "fit_error": None if fit.exact else {"n_samples": fit.n_samples, "rms": fit.rms,
                                                         "p99": fit.p99, "max": fit.max, "units": "px"}})
        return 0
    what = "exact (the calibration is this model)" if fit.exact else (
        f"fit error over {fit.n_samples} image samples: rms {fit.rms:.4f} px, p99 {fit.p99:.4f} px, max {fit.max:.4f} px")
    print(f"{fmt} / {model}: {what}")
    print(f"wrote {target}" + (f" and {error_map}" if error_map is not None else ""))
    return 0
