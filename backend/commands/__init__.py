"""Sub-commands of ``freecal``; each module has ``register(subparsers)``."""
from . import calibrate, compare, demo, detect, diff, evaluate, export, report, rig, serve, synth, undistort, worker

COMMANDS = [demo, synth, detect, calibrate, evaluate, compare, diff, report, rig, undistort, export, serve, worker]
