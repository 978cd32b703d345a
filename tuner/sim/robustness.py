"""Robustness of a gait: many randomised rollouts with evaluation seeds, and a push sweep.

``evaluate`` walks a parameter set ``rollouts`` times on one robot and surface, each rollout
with its own perturbation drawn from the :data:`tuner.randomisation.EVALUATE` namespace
(seeds ``(seed, i)``, never used in tuning), then ``push_rollouts`` times per push size with
the same randomisation plus one push. Reported (definitions in ``DEFINITIONS``):

* ``survival``: fraction of the randomised rollouts that did not fall;
* time to fall: the fall times of those that fell (quartiles);
* pitch RMS and speed: 10th, 50th and 90th percentiles over the rollouts that stayed up;
* a joint table's walks: the covered fraction of its planned forward distance (percentiles over
  the rollouts that stayed up), and how many of those ``stalled``: stayed up having covered less
  than ``metrics.MIN_PROGRESS`` of it (a robot held in place by its ground stands, it does not walk;
  survival counts it, this says so);
* per push size, the survival fraction; ``largest_push_ns``: the largest size survived in
  at least 90% of its rollouts (and of every smaller size).
Workers are forked processes, each with its own simulator; the numbers do not depend on how
many there are.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import numpy as np

import gaits
from gaits.control import WithoutReadings
from .cache import simulator
from .metrics import MIN_PROGRESS, planned_forward_distance, steady_tracking, summarize
from ..process_pool import map_in_order
from .randomisation import DEFAULT_PUSHES, EVALUATE, Randomisation, draw
from .record import recording, recording_stem
from ..robots import load_robot
from .rollout import Simulator
from .surfaces import load_surface

__all__ = ["evaluate", "scenario_walks", "walk_scenario", "RobustnessReport", "DEFINITIONS", "DEFAULT_PUSHES", "PUSH_SURVIVAL"]

PUSH_SURVIVAL = 0.9
DEFINITIONS = {
    "survival": "fraction of randomised rollouts (default randomisation, evaluation seeds) that completed: a "
                "fall, a diverged or an impossible simulation is not a survival",
    "t_fall_s": "quartiles of the fall time of the rollouts that fell [s]",
    "pitch_rms_deg": "10/50/90th percentiles of torso pitch RMS over rollouts that stayed up [deg]",
    "speed_mps": "10/50/90th percentiles of forward speed over rollouts that stayed up [m/s]",
    "covered": "a joint table's walks: 10/50/90th percentiles of the covered fraction of the planned forward "
               "distance over rollouts that stayed up (null: an online walk, or no forward plan)",
    "stalled": f"rollouts that stayed up having covered less than {MIN_PROGRESS:.0%} of their planned forward "
               "distance (survival counts them: they stood rather than walked)",
    "push_survival": "per push impulse [N s]: fraction of rollouts with one push of that size that did not fall",
    "largest_push_ns": f"largest push impulse survived in >= {PUSH_SURVIVAL:.0%} of its rollouts, and so "
                       f"every smaller one [N s] (null: not even the smallest)",
    "tracking_steady": "with --commands or --command: measured / commanded velocity along each moving segment's "
                       "own axis over its steady steps (those starting once an engine's accel_* ramp has reached "
                       "the command; a table's from the segment's second step), the median over the segments of "
                       "the walks that stayed up, its IQR, and the median per kind of segment; what the engine's "
                       "stride_* calibration inverts (null: no stream, or nothing measured)",
}

_TABLES: dict = {}


def _table(sim: Simulator, drive: gaits.Drive):
    """``drive``'s joint table for the simulator, planned once per process."""
    key = (drive.key(), id(sim))
    if key not in _TABLES:
        _TABLES.clear()
        _TABLES[key] = drive.table(sim.robot, sim.control_period)
    return _TABLES[key]


def _controller(sim: Simulator, drive: gaits.Drive):
    """A fresh controller of ``drive`` for the simulator; a joint table is planned once per process."""
    if drive.online:
        return drive.controller(sim.robot, sim.control_period)
    return drive.controller(sim.robot, sim.control_period, table=_table(sim, drive))


def _one(task: tuple) -> dict[str, Any]:
    robot, surface, drive, randomisation, seed, push, record, without = task
    sim = simulator(robot, surface)
    p = draw(randomisation.with_push(push), seed, *sim.n_random(), namespace=EVALUATE)
    path, notes = None, ""
    if record is not None:
        kind = f"push{push:g}Ns-{seed[1] - 1_000_000:03d}" if push else f"{seed[1]:03d}"
        path = Path(record) / f"{recording_stem(drive)}--{sim.surface.name}--{kind}.mcap"
        notes = (f"gait-tuner robustness: randomised walk, evaluation seed {seed[0]}, rollout {seed[1]}"
                 + (f", a {push:g} N s push" if push else ""))
    controller = _controller(sim, drive)
    if without:
        controller = WithoutReadings(controller, without)
    with recording(controller, sim, drive, path, "walk", notes) as controller:
        trace = sim.run(controller, perturb=p, **drive.run_options())
    m = summarize(trace)
    row = {"push": push, "seed": list(seed), "fell": m.fell, "outcome": m.outcome, "survived": m.survived,
           "t_fall_s": m.t_fall_s,
           "pitch_rms_deg": m.pitch_rms_deg, "speed_mps": m.speed_mps, "distance_m": m.distance_m,
           "covered": None}
    if not drive.online:
        plan = planned_forward_distance(_table(sim, drive))
        if abs(plan) > 1e-3:
            row["covered"] = float(m.distance_m / plan)
    if drive.stream is not None:
        from .metrics import tracking
        tk = tracking(trace, drive.stream, trace.meta.get("step_starts"))
        row["tracking"] = {k: tk[k] for k in ("vx_rmse_mps", "vy_rmse_mps", "wz_rmse_radps", "steps")}
        row["segments"] = tk["segments"]
    return row


@dataclass
class RobustnessReport:
    robot: str
    surface: str
    params: str
    stabiliser: bool
    rollouts: list[dict[str, Any]]
    pushes: dict[float, list[dict[str, Any]]]
    drive: str = ""                   # how the set was driven and what it walked
    tracking: dict[str, Any] | None = None   # a stream's steady-step tracking (metrics.steady_tracking)

    @property
    def survival(self) -> float:
        return float(np.mean([r["survived"] for r in self.rollouts])) if self.rollouts else 0.0

    def _pct(self, key: str) -> list[float] | None:
        vals = [r[key] for r in self.rollouts if r["survived"] and r.get(key) is not None]
        return [float(v) for v in np.percentile(vals, [10, 50, 90])] if vals else None

    @property
    def stalled(self) -> int:
        """Rollouts that stayed up having covered less than ``MIN_PROGRESS`` of their plan."""
        return sum(1 for r in self.rollouts if r["survived"] and r.get("covered") is not None
                   and r["covered"] < MIN_PROGRESS)

    @property
    def push_survival(self) -> dict[float, float]:
        return {size: float(np.mean([r["survived"] for r in rows])) for size, rows in sorted(self.pushes.items())}

    @property
    def largest_push(self) -> float | None:
        best = None
        for size, frac in self.push_survival.items():
            if frac < PUSH_SURVIVAL:
                break
            best = size
        return best

    def to_dict(self) -> dict[str, Any]:
        falls = [r["t_fall_s"] for r in self.rollouts if r["fell"]]
        outcomes = {o: sum(1 for r in self.rollouts if r.get("outcome", "fell" if r["fell"] else "completed") == o)
                    for o in ("completed", "fell", "diverged", "impossible")}
        return {"robot": self.robot, "surface": self.surface, "params": self.params, "drive": self.drive,
                "stabiliser": self.stabiliser, "rollouts": len(self.rollouts), "survival": self.survival,
                "falls": len(falls), "outcomes": outcomes,
                "t_fall_s": [float(v) for v in np.percentile(falls, [25, 50, 75])] if falls else None,
                "pitch_rms_deg": self._pct("pitch_rms_deg"), "speed_mps": self._pct("speed_mps"),
                "covered": self._pct("covered"), "stalled": self.stalled,
                "push_survival": {f"{k:g}": v for k, v in self.push_survival.items()},
                "largest_push_ns": self.largest_push, "tracking_steady": self.tracking,
                "definitions": DEFINITIONS}

    def format(self) -> str:
        d = self.to_dict()

        def pct(v, fmt):
            return "-" if v is None else " / ".join(format(x, fmt) for x in v)
        lines = [f"robustness of {self.params} on robot {self.robot} / {self.surface} "
                 f"(stabiliser {'on' if self.stabiliser else 'off'})" + (f"\n  walked          {self.drive}"
                                                                          if self.drive else ""),
                 f"  survival        {d['survival']:.1%} of {d['rollouts']} randomised rollouts ({d['falls']} fell"
                 + "".join(f", {n} {o}" for o, n in d["outcomes"].items() if o in ("diverged", "impossible") and n)
                 + ")",
                 f"  time to fall    {pct(d['t_fall_s'], '.2f')} s (quartiles of those that fell)",
                 f"  pitch RMS       {pct(d['pitch_rms_deg'], '.2f')} deg (10/50/90th pct, stayed up)",
                 f"  speed           {pct(d['speed_mps'], '.3f')} m/s (10/50/90th pct, stayed up)"]
        if d["covered"] is not None:
            lines.append(f"  covered         {pct([round(100 * v) for v in d['covered']], 'd')} % of the planned "
                         f"distance (10/50/90th pct, stayed up)")
        if d["stalled"]:
            lines.append(f"  stalled         {d['stalled']} of the rollouts that stayed up covered less than "
                         f"{MIN_PROGRESS:.0%} of their plan: they stood rather than walked (survival counts them)")
        tk = self.tracking
        if tk is not None:
            kinds = ", ".join(f"{k} {tk[k]:.0%}" for k in ("forward", "backward", "sideways", "turning")
                              if tk[k] is not None)
            lines.append(f"  tracking        {tk['median']:.0%} of the command in steady steps (IQR "
                         f"{tk['iqr']:.0%}; stayed up): {kinds}")
        if self.pushes:
            n = len(next(iter(self.pushes.values())))
            row = ", ".join(f"{k} N s {v:.0%}" for k, v in d["push_survival"].items())
            lines.append(f"  pushes          {row} ({n} rollouts each)")
            lp = d["largest_push_ns"]
            lines.append(f"  largest push survived in >= {PUSH_SURVIVAL:.0%}: " + ("none" if lp is None else f"{lp:g} N s"))
        return "\n".join(lines)


def evaluate(robot: str, surface: str, drive: gaits.Drive, *, rollouts: int, seed: int,
             randomisation: Randomisation = Randomisation(), pushes: tuple[float, ...] = DEFAULT_PUSHES,
             push_rollouts: int = 20, workers: int = 2,
             progress: Callable[[int], None] | None = None, record: Path | None = None,
             without: tuple[str, ...] = ()) -> RobustnessReport:
    """Walk what ``drive`` asks under randomisation; see the module docstring. With ``record`` (a
    folder) every walk is recorded there (``record.py``), one MCAP file per walk; ``without``:
    readings the controller is not given (``gaits.control.WithoutReadings``: a robot without foot
    sensors is ``("foot_force",)``)."""
    load_robot(robot)                       # a bad robot fails here, once, in the parent
    load_surface(surface)
    base = (robot, surface, drive, randomisation)
    rec = None if record is None else str(record)
    without = tuple(without)
    tasks = [base + ((seed, i), 0.0, rec, without) for i in range(rollouts)]
    for size in pushes:
        tasks += [base + ((seed, 1_000_000 + i), float(size), rec, without) for i in range(push_rollouts)]
    rows = map_in_order(_one, tasks, workers, progress, chunksize=4)
    plain = rows[:rollouts]
    by_push: dict[float, list] = {}
    for r in rows[rollouts:]:
        by_push.setdefault(r["push"], []).append(r)
    tracking = None
    if drive.stream is not None:
        ramped = drive.engine is not None and gaits.family_of(drive.params).engine == "feedback"
        tracking = steady_tracking(plain, drive.stream, drive.engine if ramped else None)
    return RobustnessReport(load_robot(robot).name, surface, drive.source, drive.closed_loop, plain, by_push,
                            drive.describe(), tracking)


def servo_share(trace: Any, sim: Simulator) -> float:
    """The fastest move the controller asked of any servo, as a share of that servo's nominal speed
    (its targets tick to tick, before the simulator's rate limit: what a servo table of the walk
    would ask, ``robots/servo_table.check_table``). 0 for a walk of one tick."""
    if len(trace.q_ref) < 2:
        return 0.0
    rate = np.abs(np.diff(trace.q_ref, axis=0)) / sim.control_period
    return float(np.max(rate / sim.servo_speed))


def walk_scenario(sim: Simulator, drive: gaits.Drive, stream, pushes, perturb) -> dict[str, Any]:
    """One scenario walk of ``drive`` on ``sim``: fell, pitch, tracking (``metrics.tracking``)."""
    import dataclasses

    from .metrics import tracking
    walk = dataclasses.replace(drive, stream=stream, command=None)
    try:
        controller = walk.controller(sim.robot, sim.control_period)
    except (gaits.ParamError, gaits.UnreachableTargetError) as exc:
        return {"fell": True, "survived": False, "outcome": "invalid", "t_fall_s": 0.0, "walked": 0.0,
                "pitch_rms_deg": None, "invalid": str(exc), "servo_share": 0.0,
                "tracking": None, "segments": [], "pushes": len(pushes)}
    trace = sim.run(controller, perturb=perturb, pushes=pushes, **walk.run_options())
    m = summarize(trace)
    tk = tracking(trace, stream, trace.meta.get("step_starts"))
    return {"fell": m.fell, "survived": m.survived, "outcome": m.outcome, "t_fall_s": m.t_fall_s,
            "walked": float(trace.t[-1]) / stream.duration,
            "pitch_rms_deg": m.pitch_rms_deg, "servo_share": servo_share(trace, sim),
            "tracking": {k: tk[k] for k in ("vx_rmse_mps", "vy_rmse_mps", "wz_rmse_radps", "steps")},
            "segments": tk["segments"], "pushes": len(pushes)}


def _scenario_walk(task: tuple) -> dict[str, Any]:
    """One scenario walk (a worker process): its own stream, pushes and perturbation."""
    from .match_walks import draw_scenario
    robot, surface, drive, scenario, randomisation, seed, namespace = task
    sim = simulator(robot, surface)
    stream, pushes = draw_scenario(scenario, seed, namespace)
    p = draw(randomisation, seed, *sim.n_random(), namespace=namespace)
    return {"seed": list(seed), **walk_scenario(sim, drive, stream, pushes, p)}


def scenario_walks(robot: str, surface: str, drive: gaits.Drive, scenario, *, walks: int, seed: int,
                   randomisation: Randomisation = Randomisation(), namespace: int = EVALUATE, workers: int = 2,
                   progress: Callable[[int], None] | None = None) -> list[dict[str, Any]]:
    """``walks`` scenario walks of a drive (``tuner/sim/match_walks.py``) under randomisation, seeds
    (seed, i) of ``namespace``; one row per walk (fell, pitch, tracking, per segment)."""
    load_robot(robot)
    load_surface(surface)
    tasks = [(robot, surface, drive, scenario, randomisation, (seed, i), namespace) for i in range(walks)]
    return map_in_order(_scenario_walk, tasks, workers, progress, chunksize=1)
