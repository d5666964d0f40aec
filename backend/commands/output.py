"""Printing shared by the sub-commands: tables, JSON, and which stream gets what.

Standard output carries either the text a person reads or, with ``--json`` or an
output of ``-``, the data alone (one document), so that it can be piped into
another command; everything else then goes to standard error, which always carries
the progress and the notes.
"""
from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator, Sequence
from typing import Any, TextIO

from calib_core.errors import SettingsError

_data: TextIO | None = None      # the real standard output while a command runs
_claimed_by: str | None = None   # the flag that claimed it for data (--json, -o -)


@contextlib.contextmanager
def stdout_session() -> Iterator[None]:
    """One command run: standard output is the person's until a flag claims it for data."""
    global _data, _claimed_by
    saved = sys.stdout
    _data, _claimed_by = saved, None
    try:
        yield
    finally:
        sys.stdout.flush()
        sys.stdout = saved
        _data, _claimed_by = None, None


def claim_stdout(flag: str) -> None:
    """``flag`` writes data on standard output: from now on the text a person
    reads goes to standard error. Two flags cannot both have it."""
    global _claimed_by
    if _claimed_by is not None and _claimed_by != flag:
        raise SettingsError(f"{_claimed_by} and {flag} both write to standard output: keep one")
    _claimed_by = flag
    sys.stdout = sys.stderr


def data_stream() -> TextIO:
    return _data if _data is not None else sys.stdout


def write_data(data: bytes) -> None:
    """Bytes of a document on the real standard output."""
    stream = data_stream()
    stream.flush()
    if hasattr(stream, "buffer"):
        stream.buffer.write(data)
        stream.buffer.flush()
    else:  # a text stream without bytes (some test captures): the documents are UTF-8 text
        stream.write(data.decode("utf-8"))
    stream.flush()


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


def json_text(doc: Any) -> str:
    """A document as freecal writes and prints JSON: strict (a non-finite number is null), one space of indent."""
    from calib_core.calibration import json_safe
    from calib_core.observations import json_text as strict

    return strict(json_safe(doc))


def print_json(doc: Any) -> None:
    """The machine-readable result of ``--json``, on the real standard output."""
    write_data(json_text(doc).encode("utf-8"))


def require_service(command: str) -> None:
    """``freecal serve`` and ``worker`` need the web stack, an optional part of the install."""
    import importlib.util

    from calib_core.errors import SettingsError

    missing = [m for m in ("fastapi", "uvicorn", "huey", "viser") if importlib.util.find_spec(m) is None]
    if missing:
        raise SettingsError(f"freecal {command} needs the service's packages ({', '.join(missing)} missing): "
                            "pip install 'freecal[service]'")
