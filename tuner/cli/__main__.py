"""``python -m tuner.cli``: the command line."""

from .main import run

run()
