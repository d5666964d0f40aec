"""Sub-commands of ``freecal``; each module has ``register(subparsers)``."""
from . import calibrate, demo, evaluate, synth

COMMANDS = [demo, synth, calibrate, evaluate]
