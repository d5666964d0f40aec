"""What every method returns, and how settings are read from keyword arguments."""
from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic

import numpy as np

from ..errors import SettingsError
from ..fit_report import ChoiceReport, Restart
from ..fitting.solve import Data, ModelT_co, SolveResult, SolveSettings

Progress = Callable[[str, float], None]


def no_progress(stage: str, fraction: float) -> None:
    pass


def scaled(progress: Progress, lo: float, hi: float) -> Progress:
    """``progress`` for one part of a longer run: fractions mapped onto [lo, hi]."""
    return lambda stage, fraction: progress(stage, lo + (hi - lo) * fraction)


def named(progress: Progress, label: str) -> Progress:
    """``progress`` for the work of one candidate model or method among several:
    its stages carry its name ("Kannala-Brandt model: initialise"), so that five
    "initialise" in a row say which model each one starts. A nested run's "done"
    (``calibrate`` ends with it) becomes "finished": the run around it goes on."""
    return lambda stage, fraction: progress(f"{label}: {'finished' if stage == 'done' else stage}", fraction)


@dataclass
class Fit(Generic[ModelT_co]):
    """A fitted model and poses, the points it could not use, and what to record."""

    result: SolveResult[ModelT_co]
    excluded: np.ndarray  # (N,) bool: points the model cannot represent (not fitted)
    excluded_reason: str = ""
    settings: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)  # the method's own records (Diagnostics.extra)
    # Refit on a subset of the points (after outlier rejection), for methods
    # whose model is not all refined by LM (residual fields); None: plain LM.
    refit: Callable[[Data, SolveResult[ModelT_co]], SolveResult[ModelT_co]] | None = None
    # How plain LM refits this model (None: the method's max_iterations and
    # ftol, damped steps). A field's refit wants its final fit's Gauss-Newton
    # trials: damped steps crawl along its flat valley (BabelCalib's outlier
    # refits: 13 iterations against 3).
    solve_settings: SolveSettings | None = None
    model_choice: ChoiceReport | None = None  # method auto's choice among candidates
    restart: Restart | None = None  # a field fit restarted from a parametric camera


def settings_from(cls, values: dict[str, Any]):
    """Build a settings dataclass from keyword arguments, naming unknown keys."""
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(values) - names)
    if unknown:
        raise SettingsError(f"unknown setting(s) {unknown}; known: {sorted(names)}")
    obj = cls(**values)
    obj.validate()
    return obj
