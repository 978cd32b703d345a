import os
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def gait_tuner_cmd():
    """The real console script of this environment (falls back to python -m)."""
    exe = Path(sys.executable).with_name("gait-tuner")
    if exe.exists():
        return [str(exe)]
    return [sys.executable, "-m", "tuner.cli"]


@pytest.fixture
def run_env():
    env = dict(os.environ)
    env["MPLBACKEND"] = "Agg"
    return env
