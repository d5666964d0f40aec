"""Sub-commands of ``freecal``; each module has ``register(subparsers)``."""
from . import calibrate, compare, demo, detect, diff, evaluate, export, report, serve, synth, undistort, worker

COMMANDS = [demo, synth, detect, calibrate, evaluate, compare, diff, report, undistort, export, serve, worker]
