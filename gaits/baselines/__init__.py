"""The papers' own parameter sets, shipped as YAML files beside this module.

``list_baselines()`` names them; ``load_baseline(name)`` returns a validated
:class:`gaits.gait_file.GaitFile`. Each file's ``description`` says where every
number comes from and which readings of the paper it rests on.
"""

from __future__ import annotations

from pathlib import Path

from ..gait_file import GaitFile, load_gait_file
from ..params import ParamError

__all__ = ["BASELINE_DIR", "list_baselines", "load_baseline", "baseline_path"]

BASELINE_DIR = Path(__file__).resolve().parent


def list_baselines() -> list[str]:
    """Names of the shipped baseline sets (file names without ``.yaml``)."""
    return sorted(p.stem for p in BASELINE_DIR.glob("*.yaml"))


def baseline_path(name: str) -> Path:
    path = BASELINE_DIR / f"{name}.yaml"
    if not path.is_file():
        raise ParamError(f"unknown baseline {name!r}: expected one of {', '.join(list_baselines())}")
    return path


def load_baseline(name: str) -> GaitFile:
    """Load a shipped baseline set by name, e.g. ``tkux-table2`` or ``eros-x16-with``."""
    return load_gait_file(baseline_path(name))
