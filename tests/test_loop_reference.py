"""The controller loop walks every joint table exactly as the table-replay loop did (recorded).

``tests/data/reference_traces.npz`` was recorded by ``tests/data/record_reference_traces.py``
with the replay loop of commit df58f72, before the loop drove controllers: per surface, plain
and randomised walks, the IMU stabiliser with noise, latency and a push, walk commands and
EROS. Every recorded field must agree tick for tick within 1e-9, with one difference on
purpose: the replay loop recorded row 0 of a randomised walk *before* it applied the start-pose
error, so its first row showed a pose the robot never had; the controller loop records the
pose the walk starts from, and row 0 of randomised walks is left out of the comparison.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
_spec = importlib.util.spec_from_file_location("record_reference_traces", DATA / "record_reference_traces.py")
ref = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ref)
REFERENCE = np.load(DATA / "reference_traces.npz")
ROBOT = ref.load_robot("kidsize-pd")      # recorded on round one's servos (the pd law)
SIMS: dict = {}


@pytest.mark.parametrize("case", ref.CASES, ids=[c[0] for c in ref.CASES])
def test_table_walks_as_recorded(case):
    trace = ref.walk(case, ROBOT, SIMS)
    name = case[0]
    assert str(REFERENCE[f"{name}/reason"]) == trace.reason
    first = 0 if case[4] is None else 1
    for f in ref.FIELDS:
        want = REFERENCE[f"{name}/{f}"]
        got = np.asarray(getattr(trace, f))
        assert got.shape == want.shape, f
        got, want = got[first:], want[first:]
        assert np.allclose(got, want, rtol=0, atol=1e-9), (f, float(np.nanmax(np.abs(got - want))))
