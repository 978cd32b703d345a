"""The walk engine answers its recorded inputs with the recorded targets, to the last bits.

``tests/data/engine_traces.npz`` was written by ``tests/data/record_engine_traces.py`` with the
engine of commit 4ef20d3, the last one before ``gaits/engine.py`` became the package
``gaits/engine/`` (randomised match walks with pushes on three surfaces: re-plans, touch-downs,
stops). Each case's inputs (every Measurement, every command) go into a fresh engine built as the
simulator builds it, with no simulator: its targets must be the recorded ones within 1e-12 rad (numpy
2.4 moved some by an ulp: bit for bit holds only on one numpy), and its count of re-plans and steps
exactly. Recorded on round one's servos (``kidsize-pd``: the engine reads the servos' speeds).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

import gaits
from gaits.control import Measurement

DATA = Path(__file__).parent / "data"
_spec = importlib.util.spec_from_file_location("record_engine_traces", DATA / "record_engine_traces.py")
ref = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ref)
REFERENCE = np.load(DATA / "engine_traces.npz")


def _engine(set_name: str) -> gaits.WalkEngine:
    from tuner.sim import cache
    robot = cache.robot("kidsize-pd")          # recorded on round one's servos (the pd law)
    ctl = ref.drive_of(set_name).controller(robot, 0.01)
    while not isinstance(ctl, gaits.WalkEngine):       # the stabiliser wraps it: the engine is inside
        ctl = ctl.inner
    return ctl


@pytest.mark.parametrize("case", ref.CASES, ids=[c[0] for c in ref.CASES])
def test_the_engine_replays_its_recorded_walk_bit_for_bit(case):
    name, set_name = case[0], case[1]
    r = {k.split("/", 1)[1]: v for k, v in REFERENCE.items() if k.startswith(name + "/")}
    e = _engine(set_name)
    e.start_pose()
    e.reset(Measurement(float(r["reset_t"]), **{f: r[f"reset_{f}"] for f in ref.FIELDS}))
    for i in range(len(r["t"])):
        m = Measurement(float(r["t"][i]), **{f: r[f][i].copy() for f in ref.FIELDS})
        q = e.step(m, r["command"][i].copy())
        # to the last bits: numpy's releases move a sum's rounding by an ulp (2.5 did), so 1e-12 rad
        assert np.allclose(q, r["targets"][i], rtol=0.0, atol=1e-12), (name, i, float(np.max(np.abs(q - r["targets"][i]))))
    assert (e.replans, e.steps_taken) == (int(r["replans"]), int(r["steps"]))
