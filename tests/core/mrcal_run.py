"""mrcal itself, in its own venv (``benchmarks.mrcal_bridge.interpreter``):
load a written ``.cameramodel`` with ``mrcal.cameramodel`` and project with
``mrcal.project``, or run one of mrcal's tools. Tests skip when there is none."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

from benchmarks import mrcal_bridge

PROJECT = """
import sys, numpy as np, mrcal
m = mrcal.cameramodel(sys.argv[1])
rays = np.ascontiguousarray(np.load(sys.argv[2]))
lensmodel, intrinsics = m.intrinsics()
region = m.valid_intrinsics_region()
np.savez(sys.argv[3], q=mrcal.project(rays, lensmodel, intrinsics), intrinsics=intrinsics,
         imagersize=m.imagersize(), region=np.zeros((0, 2)) if region is None else region, lensmodel=lensmodel)
"""


def python() -> str:
    path = mrcal_bridge.interpreter()
    if path is None:
        pytest.skip("mrcal is not configured: run scripts/ensure-mrcal.sh (make test does), or set "
                    "FREECAL_MRCAL_PYTHON to the python of mrcal's venv")
    return path


def project(model: Path, rays: np.ndarray, tmp: Path) -> dict[str, np.ndarray]:
    """mrcal's reading of ``model`` and its projection of ``rays`` (N, 3): q, intrinsics,
    imagersize, region (the valid_intrinsics_region; (0, 2) when absent), lensmodel."""
    np.save(tmp / "rays.npy", np.asarray(rays, dtype=np.float64))
    subprocess.run([python(), "-c", PROJECT, str(model), str(tmp / "rays.npy"), str(tmp / "out.npz")],
                   check=True, capture_output=True, text=True, timeout=120)
    with np.load(tmp / "out.npz") as d:
        return {k: d[k] for k in d.files}


def tool(name: str, *args: str, cwd: Path) -> subprocess.CompletedProcess:
    """Run mrcal's command-line tool ``name`` (beside its python)."""
    exe = Path(python()).parent / name
    return subprocess.run([python(), str(exe), *args], cwd=cwd, capture_output=True, text=True, timeout=120)
