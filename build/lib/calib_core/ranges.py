"""Every numeric setting's range, checked and worded one way.

Bounds keep a client's settings from asking the solver for the impossible (a
1 000 000 x 1 000 000 knot grid is a 14.6 TiB matrix); the message names the
setting and its range, e.g. ``intervals: expected a whole number from 1 to 50,
got 1000000``.
"""
from __future__ import annotations

import math
from typing import Any

from .errors import SettingsError

MAX_ITERATIONS = 10_000   # of any solver: the defaults take 500 at most, and converge in far fewer


def whole(name: str, value: Any, low: int, high: int, *, alternative: str = "") -> int:
    """``value`` if it is an integer from ``low`` to ``high``, else SettingsError saying the range
    (and ``alternative``, another value the setting takes, e.g. "'auto'")."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SettingsError(f"{name}: expected {_or(alternative)}a whole number from {low} to {high}, "
                            f"got {shown(value)}")
    return value


def number(name: str, value: Any, low: float, high: float, *, above_low: bool = False,
           below_high: bool = False, alternative: str = "") -> float:
    """``value`` if it is a finite number in the range (ends included unless ``above_low`` /
    ``below_high``), else SettingsError saying the range."""
    ok = (isinstance(value, (int, float)) and not isinstance(value, bool)
          and not (isinstance(value, float) and math.isnan(value))  # ints are exact, however long
          and (low < value if above_low else low <= value) and (value < high if below_high else value <= high))
    if not ok:
        raise SettingsError(f"{name}: expected {_or(alternative)}a number "
                            f"{describe(low, high, above_low, below_high)}, got {shown(value)}")
    return float(value)


def iterations_and_tolerance(max_iterations: Any, ftol: Any) -> None:
    """The two settings every solver takes."""
    whole("max_iterations", max_iterations, 1, MAX_ITERATIONS)
    number("ftol", ftol, 0, 1, above_low=True, below_high=True)


def values(name: str, items: Any, low: float, high: float, *, most: int = 20, above_low: bool = False) -> list[float]:
    """A non-empty list of at most ``most`` numbers, each in the range (a grid searched value by value)."""
    if isinstance(items, (int, float)) and not isinstance(items, bool):
        items = [items]
    if not isinstance(items, (list, tuple)) or not 1 <= len(items) <= most:
        raise SettingsError(f"{name}: expected a list of 1 to {most} numbers, each "
                            f"{describe(low, high, above_low)}, got {shown(items)}")
    return [number(name, v, low, high, above_low=above_low) for v in items]


def shown(value: Any, most: int = 60) -> str:
    """``value`` as a message quotes it: a long list is cut, not echoed whole."""
    text = repr(value)
    return text if len(text) <= most else text[:most] + "..."


def _or(alternative: str) -> str:
    return f"{alternative} or " if alternative else ""


def describe(low: float, high: float, above_low: bool = False, below_high: bool = False) -> str:
    return (f"{'above' if above_low else 'at least'} {low:g} and "
            f"{'below' if below_high else 'at most'} {high:g}")
