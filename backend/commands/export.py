"""freecal export CAL.json --to opencv|ros|mrcal|colmap|nerfstudio|kalibr|MODEL [--model M] -o FILE
[--observations OBS.json] [--error-map MAP.npz] [--uncertainty [FILE]] [--alpha A | --keep K | --focal F] [--json]"""
from __future__ import annotations

import io
import json

import numpy as np

from calib_core.calibration import Calibration
from calib_core.errors import SettingsError
from calib_core.exports import LEAN_MODELS, MODELS, TARGETS, export
from calib_core.exports.lean_fit import FitError, save_error_map
from calib_core.exports.rig import export_rig
from calib_core.exports.text import beyond_note
from calib_core.rig import Rig
from calib_core.rig.rig import FORMAT as RIG_FORMAT

from .inputs import load_observations, one_stdin, read_document
from .output import claim_stdout, print_json
from .outputs import Outputs
from .undistort import ALPHA_HELP, FOCAL_HELP, KEEP, chosen_camera

CONSUMERS = "; ".join(f"{t.name}: {t.label} ({', '.join(dict.fromkeys(t.models.values()))})" for t in TARGETS.values())


def register(sub) -> None:
    p = sub.add_parser("export", help="export a calibration for OpenCV, ROS, mrcal, COLMAP, nerfstudio or Kalibr",
                       description="Write a calibration in another tool's format. A calibration that is not "
                                   "already one of the tool's models is fitted by the closest one, and the fit "
                                   "error (what the export loses) over the covered region and the whole image is "
                                   "printed and stored. " + CONSUMERS)
    p.add_argument("calibration", help="freecal.calibration/1 JSON file, or a freecal.rig/1 rig (--to kalibr: every "
                                       "camera in one camchain; --to opencv: a stereo pair's M1 D1 M2 D2 R T) "
                                       "(- : standard input)")
    p.add_argument("--to", required=True, choices=tuple(TARGETS) + tuple(LEAN_MODELS),
                   help="the tool (" + ", ".join(TARGETS) + "); a model name (opencv8, kb4, ...) means opencv "
                        "with that model")
    p.add_argument("--model", choices=("auto",) + MODELS, default="auto",
                   help="the exported model (auto: the calibration's own if the tool knows it, else the closest "
                        "of the tool's models)")
    p.add_argument("--observations", help="fit only over the convex hull of these corners (freecal.observations/1)")
    p.add_argument("--error-map", help="write the fit error map (.npz: error_px, covered, u, v; - : standard output)")
    p.add_argument("--uncertainty", nargs="?", const="", metavar="FILE",
                   help="write the projection-uncertainty sidecar (JSON; default: OUTPUT.uncertainty.json); "
                        "needs --observations")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--keep", choices=sorted([*KEEP, "covered"]),
                   help="--to ros: the rectified camera P keeps valid pixels (default), all, or the covered region")
    g.add_argument("--alpha", type=float, help="--to ros: the rectified camera P, " + ALPHA_HELP)
    g.add_argument("--focal", type=float, help="--to ros: the rectified camera P, " + FOCAL_HELP)
    p.add_argument("-o", "--output", required=True, help="output file (- : standard output)")
    p.add_argument("--json", action="store_true", help="print what was written and the fit errors as JSON")
    p.set_defaults(run=run)


def run(args) -> int:
    fmt, model = (args.to, args.model) if args.to in TARGETS else ("opencv", args.to)
    if args.to not in TARGETS and args.model not in ("auto", args.to):
        raise SettingsError(f"--to {args.to} already names the model; drop --model {args.model}")
    target = TARGETS[fmt]
    if model != "auto" and model not in target.models:
        choices = " | ".join(f"{m} ({name})" for m, name in target.models.items())
        raise SettingsError(f"--model {model}: {target.label} has no such model; choose --model {choices}, "
                            "or leave --model out for the closest")
    if (args.keep or args.alpha is not None or args.focal is not None) and fmt != "ros":
        raise SettingsError("--keep, --alpha and --focal choose ROS's rectified camera (P); they apply to --to ros only")
    if args.uncertainty is not None and not args.observations:
        raise SettingsError("--uncertainty needs --observations OBS.json (the corners the calibration was fitted to)")
    if args.uncertainty == "" and args.output == "-":
        raise SettingsError("--uncertainty: name the file (--uncertainty FILE) when -o is standard output")
    outputs = Outputs()
    written = outputs.file(args.output, "-o", target.file_name)
    error_map = outputs.file(args.error_map, "--error-map", "error_map.npz")
    sidecar = None if args.uncertainty is None else outputs.file(
        args.uncertainty or f"{args.output}.uncertainty.json", "--uncertainty", "camera.uncertainty.json")
    one_stdin(args.calibration, args.observations)
    if args.json:
        claim_stdout("--json")
    doc = read_document(args.calibration)
    if isinstance(doc, dict) and doc.get("format") == RIG_FORMAT:
        return _export_rig(args, Rig.from_json(doc), fmt, model, outputs, written)
    source = Calibration.from_json(doc)
    obs = load_observations(args.observations) if args.observations else None
    covered = None if obs is None else np.concatenate([np.asarray(v.image_points, dtype=np.float64) for v in obs.views])
    done = export(source, fmt, model, covered,
                  rectify=lambda fit: chosen_camera(fit.calibration, args.keep, args.alpha, args.focal, None, fit.region))
    uncertainty = None
    if sidecar is not None:
        from calib_core.exports.sidecar import uncertainty_sidecar
        from calib_core.report.tables import uncertainty_map

        assert obs is not None  # --uncertainty needs --observations (checked above)
        uncertainty = uncertainty_sidecar(done, source, uncertainty_map(source, obs), str(written))
    with outputs.writing():
        assert written is not None  # -o is required
        written.write(done.text)
        if error_map is not None:
            npz = io.BytesIO()
            save_error_map(npz, done.fit)
            error_map.write(npz.getvalue())
        if sidecar is not None:
            sidecar.write(json.dumps(uncertainty) + "\n")
    fit = done.fit
    files = [str(f) for f in (written, error_map, sidecar) if f is not None]
    if args.json:
        print_json({"format": fmt, "model": fit.name, "consumer_model": done.consumer_model, "exact": fit.exact,
                    "n_beyond_reach": fit.n_beyond, "output": str(written), "error_map": None if error_map is None else str(error_map),
                    "uncertainty": None if sidecar is None else str(sidecar),
                    "fit_error": None if fit.exact else {"covered": fit.covered.to_json(), "image": fit.image.to_json(),
                                                         "n_beyond_reach": fit.n_beyond, "units": "px"},
                    "candidates": [{"model": f.name, "covered_rms_px": f.covered.rms, "image_rms_px": f.image.rms}
                                   for f in done.tried],
                    "rectified_camera": None if done.camera is None else done.camera.to_json()})
        return 0
    if fit.exact:
        print(f"{fmt} / {done.consumer_model} ({fit.name}): exact, the calibration is this model{beyond_note(fit)}")
    else:
        choice = "" if not done.tried else ", the closest of " + ", ".join(
            f"{f.name} (rms {f.covered.rms:.4g} px covered, {f.image.rms:.4g} px image)" for f in done.tried
        ) + "; another with --model"
        print(f"{fmt} / {done.consumer_model} ({fit.name}): fitted to the {fit.fitted_to} calibration{choice}")
        print(f"fit error, covered region: {_error(fit.covered)}")
        print(f"fit error, whole image: {_error(fit.image)}{beyond_note(fit)}")
    if fmt == "mrcal" and fit.region is None:
        print("note: the calibration records no covered region, so the model has no valid_intrinsics_region; "
              "give --observations OBS.json (its corners) to write one")
    if done.camera is not None:
        print(f"rectified camera (P): focal {done.camera.focal:.3f} px, centre ({done.camera.cx:.3f}, "
              f"{done.camera.cy:.3f})" + (f"; note: {done.camera.note}" if done.camera.note else ""))
    print("wrote " + ", ".join(files))
    return 0


def _export_rig(args, rig: Rig, fmt: str, model: str, outputs: Outputs, written) -> int:
    """Every camera of a rig in one file (``calib_core.exports.rig``)."""
    given = [flag for flag, value in (("--observations", args.observations), ("--error-map", args.error_map),
                                      ("--uncertainty", args.uncertainty), ("--keep", args.keep),
                                      ("--alpha", args.alpha), ("--focal", args.focal)) if value is not None]
    if given:
        raise SettingsError(f"{', '.join(given)}: not for a rig; export one camera's calibration for those")
    done = export_rig(rig, fmt, model)
    with outputs.writing():
        written.write(done.text)
    if args.json:
        print_json({"format": fmt, "output": str(written), "cameras": [
            {"camera": cam.name, "model": e.fit.name, "consumer_model": e.consumer_model, "exact": e.fit.exact,
             "fit_error": None if e.fit.exact else {"covered": e.fit.covered.to_json(), "image": e.fit.image.to_json(),
                                                    "units": "px"}}
            for cam, e in zip(rig.cameras, done.cameras, strict=True)]})
        return 0
    for cam, e in zip(rig.cameras, done.cameras, strict=True):
        how = "exact" if e.fit.exact else (f"fitted to its {e.fit.fitted_to} calibration, rms {e.fit.covered.rms:.4g} px "
                                           f"covered, {e.fit.image.rms:.4g} px whole image")
        print(f"{cam.name}: {fmt} / {e.consumer_model} ({e.fit.name}): {how}")
    print(f"wrote {written}")
    return 0


def _error(e: FitError) -> str:
    return f"rms {e.rms:.4f} px, p99 {e.p99:.4f} px, max {e.max:.4f} px over {e.n} samples"
