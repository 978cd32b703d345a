"""Record what the walk engine was handed and what it answered, tick by tick (the reference of
``tests/test_engine_reference.py``).

Each case is a randomised match walk in the simulator (pushes, sensor noise and latency, the
stabiliser where the set has one): every ``reset`` and ``step`` of the :class:`gaits.WalkEngine`
is recorded with its whole :class:`gaits.control.Measurement`, its command and the 20 targets it
returned, and the plan's meta at the end. The test replays the inputs into a fresh engine, with no
simulator, and asks for the same targets bit for bit. Run ``python tests/data/record_engine_traces.py``
to write ``engine_traces.npz`` again (only when the engine's behaviour is meant to change).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

#: (name, shipped set, surface, scenario seed, commanded seconds, pushes per second)
CASES = [
    ("carpet4-match", "kidsize-engine-carpet4", "carpet4", 3, 6.0, 1.0),
    ("grass50-match", "kidsize-engine-grass50", "grass50", 4, 6.0, 1.0),
    ("grass30-push-set", "kidsize-engine-push", "grass30", 7, 4.0, 1.5),
]
FIELDS = ("q", "dq", "imu_rpy", "gyro", "accel", "foot_force")


def drive_of(set_name: str):
    from tuner.params_io import resolve_drive
    return resolve_drive(set_name, None)


def record(case) -> dict[str, np.ndarray]:
    import dataclasses

    import gaits
    from tuner.sim import cache
    from tuner.sim.randomisation import EVALUATE, Randomisation, draw
    from tuner.sim.robustness import walk_scenario
    from tuner.sim.match_walks import MatchDistribution, draw_scenario
    name, set_name, surface, seed, seconds, rate = case
    sim = cache.simulator(cache.robot("kidsize-pd"), surface)
    dist = MatchDistribution(duration=seconds, push_rate=rate, push_min=0.5, push_max=1.5)
    stream, pushes = draw_scenario(dist, seed, EVALUATE)
    perturb = draw(Randomisation(), seed, *sim.n_random(), namespace=EVALUATE)
    rows, engines = [], []
    step, reset = gaits.WalkEngine.step, gaits.WalkEngine.reset

    def rec_reset(self, m):
        engines.append(self)
        rows.append(("reset", dataclasses.replace(m), None, None))
        return reset(self, m)

    def rec_step(self, m, command=None):
        kept = dataclasses.replace(m, **{f: None if getattr(m, f) is None else np.array(getattr(m, f))
                                         for f in FIELDS})
        q = step(self, m, command)
        rows.append(("step", kept, None if command is None else np.array(command, dtype=float), np.array(q)))
        return q
    gaits.WalkEngine.step, gaits.WalkEngine.reset = rec_step, rec_reset
    try:
        walk_scenario(sim, drive_of(set_name), stream, pushes, perturb)
    finally:
        gaits.WalkEngine.step, gaits.WalkEngine.reset = step, reset
    assert len(engines) == 1 and rows[0][0] == "reset"
    steps = [r for r in rows if r[0] == "step"]
    out = {"t": np.array([r[1].t for r in steps]), "reset_t": np.array(rows[0][1].t),
           "command": np.array([r[2] for r in steps]), "targets": np.array([r[3] for r in steps]),
           "replans": np.array(engines[0].replans), "steps": np.array(engines[0].steps_taken)}
    for f in FIELDS:
        out[f] = np.array([getattr(r[1], f) for r in steps])
        out[f"reset_{f}"] = np.array(getattr(rows[0][1], f))
    return {f"{name}/{k}": v for k, v in out.items()}


if __name__ == "__main__":
    data = {}
    for case in CASES:
        data.update(record(case))
        print(case[0], len(data[f"{case[0]}/t"]), "ticks,", int(data[f"{case[0]}/replans"]), "re-plans")
    np.savez_compressed(Path(__file__).with_name("engine_traces.npz"), **data)
