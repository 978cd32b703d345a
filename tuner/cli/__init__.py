"""The ``gait-tuner`` command line: a face. ``main.py`` is the root (the verbs, loaded when they
run); each other module holds a group of verbs, each parsing, calling one function of a wing and
printing; ``options.py`` what several verbs share."""

from .main import VERBS, cli, main, run

__all__ = ["VERBS", "cli", "main", "run"]
