"""Sub-commands of ``freecal``; each module has ``register(subparsers)``."""
from . import calibrate, demo, evaluate, serve, synth, worker

COMMANDS = [demo, synth, calibrate, evaluate, serve, worker]
