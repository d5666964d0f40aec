"""The ``freecal`` command: one sub-command per module in ``backend/commands``.

Errors a user can cause (``CalibError``: bad input, bad settings, an output path
that cannot be written) print one line saying what to do and exit with status 2;
never a traceback.
"""
from __future__ import annotations

import argparse
import logging
import os
import sys

import cv2

from calib_core.errors import CalibError

from .commands import COMMANDS
from .commands.output import stdout_session
from .version import version


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="freecal",
        description="Camera calibration for lenses that defy the textbook models.",
    )
    parser.add_argument("--version", action="version", version=f"freecal {version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in COMMANDS:
        module.register(sub)
    return parser


def quiet_library_logs() -> None:
    """What a command shows is its own words: per-image reasons, one error line. The raw texts
    behind them (OpenCV's warnings, freecal's log of a detector's exception) are for a service's
    log, which ``serve`` and ``worker`` configure; here they would only repeat them in OpenCV's terms."""
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
    log = logging.getLogger("freecal")
    if not any(isinstance(h, logging.NullHandler) for h in log.handlers):
        log.addHandler(logging.NullHandler())  # a handler: Python's last resort no longer prints them


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.command not in ("serve", "worker"):
        quiet_library_logs()
    try:
        with stdout_session():
            return int(args.run(args) or 0)
    except CalibError as exc:
        print(f"freecal {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into head, less...: not an error
        sys.stdout = open(os.devnull, "w")
        return 0
    except KeyboardInterrupt:
        print(f"freecal {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
