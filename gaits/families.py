"""One object per gait family, registered once: everything the tool knows about a family.

A :class:`GaitFamily` holds the family's parameter class, its generator, its step period and
step starts (the clock a walk command is planned on), the walk-command axes it walks, its
step-length rule (the same gait at another step length), the fields that follow from others,
its stance width and reach (the step limits of a walk command), the CasADi seed's
correspondence, and its paper baselines. :func:`family` looks one up by name; adding a family
is one :func:`register` call in this file.

The step limits and the commanded walk live here too (ours, not the papers'): the walk engine
needs them on the robot, without a simulator.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping, Protocol

import numpy as np

from . import cosine_law, eros, tlipfm
from .cosine_law import CosineLawParams
from .eros import ErosParams
from .footstep_planner import PlanError, StepLimits
from .leg_kinematics import LegGeometry, UnreachableTargetError
from .params import GaitParams, ParamError
from .tlipfm import TlipfmParams
from .trajectory import GaitTrajectory
from .walk_command import CommandRamp, WalkCommand

__all__ = ["GaitFamily", "RobotGeometry", "register", "family", "family_of", "all_families", "families",
           "family_class", "params_from_mapping", "command_walk", "DEFAULT_REACH"]


class RobotGeometry(Protocol):
    """What the walk needs of a robot: its legs and the bounding box of its soles (length, width) [m]."""

    leg: LegGeometry
    foot_size: tuple[float, float]


#: [leg lengths, leg lengths, leg lengths, rad] reach of a family without reach fields (ours):
#: forward, backward, outward, turn, in thigh + shank lengths (TLIPFM's defaults).
DEFAULT_REACH = (0.45, 0.32, 0.27, 0.6)


def _no_derived(values: Mapping[str, Any], base: GaitParams) -> dict[str, Any]:
    return {}


@dataclass(frozen=True)
class GaitFamily:
    """A gait family: the one place each of its rules is written (module docstring)."""

    name: str
    params_class: type
    paper: str                                            # the source, for `params` and reports
    generator: Callable[..., GaitTrajectory]              # (params, leg, dt, commands=, limits=)
    step_period: Callable[[Any], float]                   # [s] one step of a commanded walk
    step_starts: Callable[[Any, int], np.ndarray]         # [s] (n + 1,) start of each step, end of the last
    command_axes: tuple[bool, bool, bool]                 # which of (vx, vy, wz) it walks
    commands_text: str                                    # what it does with a walk command
    step_field: str                                       # the field that holds the step length
    with_step: Callable[[Any, float], Any]                # the same gait at another signed step [m]
    stance_width: Callable[[Any], float | None]           # [m] between the sole centres
    seed_inputs: Callable[[Any], tuple]                   # (step length, half width or None) [m] the seed plans
    from_seed: Callable[[TlipfmParams, float, Any], Any]  # (seed's TLIPFM set, CoM sway [m], base) -> set
    baselines: tuple[str, ...]                            # the paper's sets compared with a tuned one
    default_baseline: str                                 # the set used when --params is not given
    lift_field: str = ""                                  # the field that holds the swing foot's lift [m]
    derived: Callable[[Mapping[str, Any], Any], dict[str, Any]] = _no_derived
    seed_on_own_masses: bool = False                      # the seed's CoM model takes the base's masses
    engine: str = "table"                                 # online: "feedback" (gaits/engine/) or
                                                          #   "table" (gaits/online_table.py)

    # --- walking -------------------------------------------------------------------------
    def generate(self, params: GaitParams, leg: LegGeometry = LegGeometry(), dt: float = 0.01,
                 commands: np.ndarray | None = None, limits: StepLimits | None = None) -> GaitTrajectory:
        """The family's joint table; with per-step ``commands`` (n, 3) planned within ``limits``."""
        if commands is None:
            return self.generator(params, leg, dt)
        return self.generator(params, leg, dt, commands=commands, limits=limits or StepLimits())

    def walks_direction(self, unit: tuple[float, float, float]) -> bool:
        """Whether it walks a command along ``unit`` (vx, vy, wz) on its command axes."""
        return all(ok or u == 0 for ok, u in zip(self.command_axes, unit))

    def step_limits(self, params: GaitParams, robot: RobotGeometry) -> StepLimits:
        """Step limits of a commanded walk for a robot's legs and a parameter set (ours): the set's
        reaches (``reach_forward``, ``reach_backward``, ``reach_outward`` in thigh + shank lengths
        and ``max_turn``; :data:`DEFAULT_REACH` for a family without them) and the robot's sole
        bounding box for the gap check. The soles keep 10 mm apart, or the set's own standing gap
        if that is narrower (EROS's 65 mm stance leaves 5 mm between 60 mm soles: it walks
        straight at that gap, and a turn, which brings the soles closer, is rejected)."""
        legs = robot.leg.thigh + robot.leg.shank
        length, width = robot.foot_size
        reach = [getattr(params, k, d) for k, d in zip(("reach_forward", "reach_backward", "reach_outward",
                                                        "max_turn"), DEFAULT_REACH)]
        stance = self.stance_width(params)
        min_gap = StepLimits().min_gap
        if stance is not None:
            min_gap = min(min_gap, max(stance - width, 0.0))
        return StepLimits(max_forward=min(reach[0] * legs, 0.5), max_backward=min(reach[1] * legs, 0.5),
                          max_outward=min(reach[2] * legs, 0.3), max_turn=min(reach[3], 1.6),
                          min_gap=min_gap, sole_length=length, sole_width=width)

    def check_stance(self, params: GaitParams, robot: RobotGeometry) -> None:
        """The soles must not overlap standing: the stance width at least the sole's width (a
        ParamError with the overlap in mm)."""
        stance = self.stance_width(params)
        width = float(robot.foot_size[1])
        if stance is not None and stance < width - 1e-9:
            raise ParamError(f"{self.name}: the soles overlap by {(width - stance) * 1000:.1f} mm standing: the "
                             f"feet are {stance * 1000:.1f} mm apart (centre to centre) and the robot's soles "
                             f"{width * 1000:.1f} mm wide; widen the stance")

    def command_limit(self, params: GaitParams, robot: RobotGeometry, unit: tuple[float, float, float]) -> float:
        """The largest command along a unit direction (one axis) the step limits allow [m/s or rad/s];
        0 for a direction the family does not walk."""
        if not self.walks_direction(unit):
            return 0.0
        lim = self.step_limits(params, robot)
        T = self.step_period(params)
        vx, vy, wz = unit
        if vx > 0:
            return lim.max_forward / T
        if vx < 0:
            return lim.max_backward / T
        if vy:
            return lim.max_outward / (2 * T)
        return lim.max_turn / (2 * T)

    def walk(self, params: GaitParams, robot: RobotGeometry, dt: float, commands: np.ndarray,
             limits: StepLimits | None = None) -> GaitTrajectory:
        """The table of a per-step command array within the robot's step limits (or ``limits``); a
        step out of the leg's reach is a PlanError naming the step."""
        limits = limits or self.step_limits(params, robot)
        try:
            return self.generate(params, robot.leg, dt, commands=commands, limits=limits)
        except UnreachableTargetError as exc:
            if exc.t is None:
                raise
            starts = self.step_starts(params, len(commands))
            step = int(np.clip(np.searchsorted(starts, exc.t, side="right") - 1, 0, len(commands) - 1))
            raise PlanError(f"step {step} of the command walk is out of the leg's reach: {exc}") from None


_REGISTRY: dict[str, GaitFamily] = {}


def register(fam: GaitFamily) -> GaitFamily:
    """Register a family (its parameter class must name it; its step and lift fields must be its own)."""
    if fam.params_class.FAMILY != fam.name:
        raise ValueError(f"family {fam.name!r}: its parameter class says {fam.params_class.FAMILY!r}")
    own = {f.name for f in fields(fam.params_class)}
    for what in ("step_field", "lift_field"):
        if getattr(fam, what) not in own:
            raise ValueError(f"family {fam.name!r}: {what} {getattr(fam, what)!r} is not one of its parameters")
    _REGISTRY[fam.name] = fam
    return fam


def family(name: str) -> GaitFamily:
    """The registered family of that name; ParamError naming the known ones."""
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ParamError(f"unknown gait family {name!r}: expected one of {', '.join(sorted(_REGISTRY))}") from None


def family_of(params: GaitParams) -> GaitFamily:
    return family(params.FAMILY)


def all_families() -> tuple[GaitFamily, ...]:
    return tuple(_REGISTRY[k] for k in sorted(_REGISTRY))


def families() -> tuple[str, ...]:
    """Names of the registered gait families."""
    return tuple(sorted(_REGISTRY))


def family_class(name: str) -> type[GaitParams]:
    """A registered family's parameter class (ParamError naming the registered ones)."""
    return family(name).params_class


def params_from_mapping(family: str, data: Mapping[str, Any] | None,
                        source: str = "<params>") -> GaitParams:
    """Build a family's parameters from a mapping; missing keys take their defaults."""
    cls = family_class(family)
    data = {} if data is None else data
    if not isinstance(data, Mapping):
        raise ParamError(f"{source}: 'params' must be a mapping of name: value, "
                         f"got {type(data).__name__}")
    known = [f.name for f in fields(cls)]
    for key in data:
        if key not in known:
            raise ParamError(f"{source}: unknown parameter {key!r} for gait {family!r} "
                             f"(known: {', '.join(known)})")
    try:
        return cls(**dict(data))
    except ParamError as exc:
        raise ParamError(f"{source}: {exc}") from None


def command_walk(params: GaitParams, robot: RobotGeometry, command: WalkCommand, dt: float,
                 ramp: CommandRamp | None = None) -> GaitTrajectory:
    """The ramped walk at ``command`` (``gaits.CommandRamp``), with the steady window the metrics
    measure its velocity over in ``meta["steady"]``; a command beyond the set's reach is a
    PlanError naming the step and the limit."""
    ramp = ramp or CommandRamp(command)
    if ramp.target != command:
        ramp = dataclasses.replace(ramp, target=command)
    fam = family_of(params)
    commands = ramp.per_step()
    traj = fam.walk(params, robot, dt, commands)
    first, last = ramp.steady_steps()
    starts = fam.step_starts(params, len(commands))
    traj.meta["steady"] = (float(starts[first]), float(starts[last]))
    traj.meta["command"] = [command.vx, command.vy, command.wz]
    return traj


# --- the three papers' families ---------------------------------------------------------------

def _tlipfm_with_step(p: TlipfmParams, step: float) -> TlipfmParams:
    ratio = p.d1 / p.step_length if p.step_length else 0.5
    return p.replace(step_length=step, d1=step * ratio, d2=step * (1 - ratio))


def _tlipfm_derived(values: Mapping[str, Any], base: TlipfmParams) -> dict[str, Any]:
    """d2 = step_length - d1 when either is set and d2 is not: the ZMP reference stays continuous."""
    if "d2" in values or not ({"step_length", "d1"} & set(values)):
        return {}
    return {"d2": values.get("step_length", base.step_length) - values.get("d1", base.d1)}


def _eros_from_seed(seed: TlipfmParams, sway: float, base: ErosParams) -> ErosParams:
    """Step X = S_L, sway Y = the CoM's lateral amplitude, one step = two transitions of T/2, i.e.
    T_mn = 90 deg per T/2 of ticks; the base's own step X is kept."""
    ticks = max(2, round(seed.period / 2 / base.tick))
    sway = float(np.clip(sway, 0.0, min(0.08, base.stance_width)))
    return base.replace(sway_y=sway, t_mn=float(np.clip((math.pi / 2) / ticks, math.radians(0.25), math.radians(45))))


def _cosine_from_seed(seed: TlipfmParams, sway: float, base: CosineLawParams) -> CosineLawParams:
    """One motion per two step periods; the base's own step S is kept."""
    return base.replace(motion_time=float(np.clip(2 * seed.period, 0.2, 20.0)))


register(GaitFamily(
    name="tlipfm", params_class=TlipfmParams,
    paper="Wong, Xiao, Aoyama, Natural Walking Trajectory Generator ... Three-Mass LIPFM (IEEE Access 2020)",
    generator=tlipfm.generate, step_period=lambda p: p.period,
    step_starts=lambda p, n: p.t_start + np.arange(n + 1) * p.period,
    command_axes=(True, True, True),
    commands_text="any (vx, vy, wz): the footstep planner's steps, hip yaw turns the feet",
    step_field="step_length", with_step=_tlipfm_with_step, derived=_tlipfm_derived, lift_field="h_z",
    stance_width=lambda p: 2.0 * p.half_width,
    seed_inputs=lambda p: (p.step_length, p.half_width), from_seed=lambda seed, sway, base: seed,
    seed_on_own_masses=True, engine="feedback",
    baselines=("tkux-table2",), default_baseline="tkux-table2"))

register(GaitFamily(
    name="eros", params_class=ErosParams,
    paper="Pristovani et al., Walking Trajectory Optimization Algorithm for Robot Humanoid on Synthetic Grass",
    generator=eros.generate, step_period=eros.step_period, step_starts=eros.step_starts,
    command_axes=(True, True, True),
    commands_text="any (vx, vy, wz): the footstep planner's steps walked with the paper's quarter-circle "
                  "via points (side steps and turns follow eq 37's X profile, ours), hip yaw turns the feet",
    step_field="step_x", with_step=lambda p, step: p.replace(step_x=step), lift_field="foot_lift",
    stance_width=lambda p: p.stance_width,
    seed_inputs=lambda p: (abs(p.step_x) if p.step_x else 0.02, p.stance_width / 2), from_seed=_eros_from_seed,
    baselines=("eros-x24-without", "eros-x24-with"), default_baseline="eros-x8-without"))

register(GaitFamily(
    name="cosine", params_class=CosineLawParams,
    paper="Setiono et al., bipedal robot walking diagram (MEV 2012)",
    generator=cosine_law.generate, step_period=cosine_law.step_period, step_starts=cosine_law.step_starts,
    command_axes=(True, False, False),
    commands_text="forward and backward (vx) only: one motion per step, S = vx t_f; the 5-DoF leg has "
                  "no hip yaw and the paper keeps the roll static, so no side steps or turns",
    step_field="step", with_step=lambda p, step: p.replace(step=step), lift_field="swing_height",
    stance_width=lambda p: p.stance_width,
    seed_inputs=lambda p: (abs(p.step) or 0.02, None), from_seed=_cosine_from_seed,
    baselines=("cosine-setiono",), default_baseline="cosine-setiono"))
