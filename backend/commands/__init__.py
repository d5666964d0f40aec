"""Sub-commands of ``freecal``; each module has ``register(subparsers)``."""
from . import calibrate, compare, demo, detect, evaluate, serve, synth, worker

COMMANDS = [demo, synth, detect, calibrate, evaluate, compare, serve, worker]
