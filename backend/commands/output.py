"""Printing shared by the sub-commands: tables, progress, JSON."""
from __future__ import annotations

import json
import sys
import time
from collections.abc import Sequence
from typing import Any


def table(headers: Sequence[str], rows: Sequence[Sequence[Any]], file=None) -> None:
    """A plain aligned text table; floats with 4 decimals."""
    def fmt(v):
        if isinstance(v, float):
            return "—" if v != v else f"{v:.4f}"
        return str(v)

    cells = [[fmt(v) for v in r] for r in rows]
    widths = [max(len(h), *(len(r[i]) for r in cells)) if cells else len(h) for i, h in enumerate(headers)]
    out = file or sys.stdout
    print("  ".join(h.rjust(w) for h, w in zip(headers, widths, strict=True)), file=out)
    print("  ".join("-" * w for w in widths), file=out)
    for r in cells:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths, strict=True)), file=out)


def print_json(doc: Any) -> None:
    json.dump(doc, sys.stdout, indent=1)
    sys.stdout.write("\n")


class StageProgress:
    """progress(stage, fraction) → one line per stage on stderr, with elapsed time."""

    def __init__(self, quiet: bool = False):
        self.quiet = quiet
        self.stage = None
        self.t0 = time.perf_counter()

    def __call__(self, stage: str, fraction: float) -> None:
        if self.quiet or stage == self.stage:
            return
        self.stage = stage
        print(f"[{time.perf_counter() - self.t0:6.2f} s] {stage} ({100 * fraction:.0f} %)", file=sys.stderr, flush=True)


def require_service(command: str) -> None:
    """``freecal serve`` and ``worker`` need the web stack, an optional part of the install."""
    import importlib.util

    from calib_core.errors import SettingsError

    missing = [m for m in ("fastapi", "uvicorn", "huey", "viser") if importlib.util.find_spec(m) is None]
    if missing:
        raise SettingsError(f"freecal {command} needs the service's packages ({', '.join(missing)} missing): "
                            "pip install 'freecal[service]'")
