"""Shared fixtures: synthetic sets are cached per session (they are deterministic)."""
from __future__ import annotations

import functools
import os
from pathlib import Path

import pytest
from hypothesis import settings

from calib_core import synth

# The property tests draw new random examples on every run, so rare bugs
# surface over time (a knot at the domain's end was found so); CI replays one
# fixed draw, so that a merge is judged on the code, not on the luck of a draw.
settings.register_profile("ci", derandomize=True)
if os.environ.get("CI"):
    settings.load_profile("ci")

ROOT = Path(__file__).resolve().parents[1]
SHARED_DATA = ROOT.parent / "shared" / "data"


@functools.cache
def synthetic(kind: str, sigma: float = 0.3, seed: int = 0) -> synth.SynthSet:
    return synth.generate(kind, sigma, seed)


def shared_data(name: str) -> Path:
    """A folder of ../shared/data, or skip the test saying why."""
    path = SHARED_DATA / name
    if not path.is_dir():
        pytest.skip(f"real image set {name!r} not found at {path} (the shared data folder sits beside the checkout)")
    return path


@pytest.fixture(scope="module")
def stereo_pair_files(tmp_path_factory) -> list[Path]:
    """Two simulated cameras' corners (frames 000-007, matched by the digits of the view names), saved as
    left.json and right.json."""
    from .core.test_rig import simulated_rig

    root = tmp_path_factory.mktemp("pair")
    paths = []
    for name, obs in zip(("left", "right"), simulated_rig([range(0, 8), range(0, 8)], seed=3).values(), strict=True):
        obs.save(root / f"{name}.json")
        paths.append(root / f"{name}.json")
    return paths

