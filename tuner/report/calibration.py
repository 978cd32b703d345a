"""Surface calibration: choose each pedestal's contact numbers so the EROS experiment agrees with the paper.

The EROS paper gives no contact physics, only outcomes: Tables 7-8 (which
step settings stayed up on which pedestal, without and with the
optimisation). We therefore treat the soft layer's support (``layer_timeconst``,
``layer_dmin``) and its in-layer drag as unknowns and pick, per pedestal, the grid
point whose simulated stability matrix agrees with the most of that pedestal's
20 table cells; the heel-strike gain (which the paper does not give either) is
chosen with them, shared by all pedestals. Blade height is the paper's; the
the other numbers stay as in ``tuner.surfaces``. The gait is the baselines' (the
paper's full lift with our 40% double-support phase, ``gaits/eros.py``). Ties go to
the stiffest layer (the smaller time constant, the larger dmin), the more
conservative model. ``gait-tuner calibrate`` runs this and prints the table it
chose from; the values in ``tuner.surfaces`` are its output.
"""

from __future__ import annotations

import functools
import itertools
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

from . import experiments as ex
from ..robots import load_robot
from ..sim.surfaces import SURFACES

__all__ = ["DEFAULT_GRID", "HEEL_GAINS", "Candidate", "evaluate", "calibrate"]

DEFAULT_GRID = {"layer_timeconst": (0.01, 0.015, 0.02, 0.03, 0.04), "layer_dmin": (0.4, 0.5, 0.6, 0.7, 0.8, 0.9),
                "drag": (30.0, 200.0)}
HEEL_GAINS = (0.25, 0.5, 1.0)
#: Pedestals whose layer must keep the toe-sticking behaviour (``tests/test_simulation.py``):
#: a toe-first landing pitches the robot >= 2 deg more than on carpet4 and leaves it
#: pitched >= 4 deg more. The issue tracker makes it a condition of the calibration.
TOE_STICKING = {1: (2.0, 4.0)}


@dataclass(frozen=True)
class Candidate:
    pedestal: int
    surface: str
    values: dict
    heel_gain: float
    without: str        # stable pattern, 'S'/'.', cells in Table 7 order
    with_: str
    agree: int          # cells agreeing with Tables 7 and 8 (of 20)
    toe: tuple = (float("nan"), float("nan"))   # landing test: peak and final pitch [deg]
    toe_ok: bool = True                          # keeps the toe-sticking test (or not required)


@functools.lru_cache(maxsize=None)
def landing_pitch(surface) -> tuple[float, float]:
    """The toe-sticking test's landing (3 deg toe-down, 0.1 m/s forward): peak and final pitch [deg]."""
    import math

    import numpy as np

    import gaits
    from ..sim.rollout import Simulator
    robot = load_robot("kidsize")
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, robot.leg).q_ref[0]
    tr = Simulator(robot, surface).landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
    return float(np.degrees(tr.pitch.max())), float(np.degrees(tr.pitch[-1]))


def _paper_pattern(optimised: bool, pedestal: int) -> str:
    table = ex.PAPER_TABLE8 if optimised else ex.PAPER_TABLE7
    return "".join("S" if table[d][s][pedestal - 1] else "." for d, steps in ex.EROS_STEPS_MM.items()
                   for s in steps)


def evaluate(args: tuple) -> list[Candidate]:
    """One pedestal and grid point, every heel gain (runs in a worker process)."""
    pedestal, values, gains, lift_scale = args
    robot = load_robot("kidsize")
    surface = SURFACES[ex.PEDESTALS[pedestal]].replace(**values)
    toe, toe_ok = (float("nan"), float("nan")), True
    if pedestal in TOE_STICKING:
        toe = landing_pitch(surface)
        ref = landing_pitch(SURFACES["carpet4"])
        more_peak, more_end = TOE_STICKING[pedestal]
        toe_ok = toe[0] > ref[0] + more_peak and toe[1] > ref[1] + more_end
    cells = ex.eros_matrix(robot, {pedestal: surface}, False, lift_scale=lift_scale)
    without = "".join("S" if c.stable else "." for c in cells)
    out = []
    for gain in gains:
        base = ex.eros_params(8, True).replace(heel_gain=gain)
        cells = ex.eros_matrix(robot, {pedestal: surface}, True, base=base, lift_scale=lift_scale)
        with_ = "".join("S" if c.stable else "." for c in cells)
        agree = (sum(a == b for a, b in zip(without, _paper_pattern(False, pedestal)))
                 + sum(a == b for a, b in zip(with_, _paper_pattern(True, pedestal))))
        out.append(Candidate(pedestal, surface.name, dict(values), gain, without, with_, agree, toe, toe_ok))
    return out


def calibrate(grid: dict = DEFAULT_GRID, gains: tuple = HEEL_GAINS, lift_scale: float = 1.0,
              workers: int = 2, progress=None) -> tuple[float, dict[int, Candidate], list[Candidate]]:
    """Best heel gain, the best candidate per pedestal at that gain, and every candidate.

    Only candidates that keep the toe-sticking test (:data:`TOE_STICKING`) are chosen; a
    pedestal with none is left out of the chosen dict (the caller reports it)."""
    keys = list(grid)
    tasks = [(ped, dict(zip(keys, vals)), gains, lift_scale)
             for ped in ex.PEDESTALS for vals in itertools.product(*grid.values())]
    results: list[Candidate] = []
    with ProcessPoolExecutor(max_workers=workers) as pool:
        for batch in pool.map(evaluate, tasks):
            results.extend(batch)
            if progress is not None:
                progress(1)

    def stiffness_key(c: Candidate) -> tuple:
        return (-c.agree, c.values.get("layer_timeconst", 0.0), -c.values.get("layer_dmin", 0.0))

    best_gain, best_total, best = gains[0], -1, {}
    for gain in gains:
        chosen = {}
        for ped in ex.PEDESTALS:
            ok = [c for c in results if c.pedestal == ped and c.heel_gain == gain and c.toe_ok]
            if ok:
                chosen[ped] = min(ok, key=stiffness_key)
        total = sum(c.agree for c in chosen.values())
        if total > best_total:
            best_gain, best_total, best = gain, total, chosen
    return best_gain, best, results
