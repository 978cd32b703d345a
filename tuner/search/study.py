"""Tuning-study definitions: a typed, validated spec read from ``studies/*.yaml``.

A study tunes one gait family on one robot against one or several surfaces::

    name: eros-grass50             # optional: the file name without .yaml
    description: free text
    robot: kidsize                 # built-in name or robot map YAML
    surfaces: [grass50]            # several = a robust study
    aggregate: worst               # robust studies: worst (max) or mean over surfaces
    gait: eros
    base: eros-x24-with            # baseline name or parameter file: the starting point
    fixed: {n_steps: 8}            # overrides of the base, never searched
    space:                         # searched parameters: low, high, optional log: true
      heel_gain: {low: 0.0, high: 6.0}
      t_mn: {low: 0.01, high: 0.05, log: true}
    objectives: [pitch_rms]        # pitch_rms (minimised); add speed (maximised) for a Pareto front
    trials: 60
    duration: null                 # rollout length [s]; null: the whole gait
    enqueue: [casadi, baselines]   # tried first: the CasADi seed and the base (+ `baselines`)
    baselines: []                  # more parameter sets of the same family to try first
    sampler_seed: 0
    robust:                        # optional: K randomised rollouts per surface per trial
      rollouts: 8                  #   seeds 0..K-1 of the tuning stream, the same for every trial
      risk: cvar25                 #   cvar25 (mean of the worst quarter), worst, or mean of the scores
      min_survival: 0.95           #   below this fraction of rollouts standing: infeasible (pruned early)
      randomisation: {}            #   overrides of tuner/sim/randomisation.py's defaults, or none
    stabiliser: {enabled: true}    # optional: the IMU stabiliser's fixed values; its gains may be
                                   #   searched as space keys stabiliser.k_ankle_pitch etc.
    engine: {k_vel: 0.8}           # optional (TLIPFM): walk every trial with the online walk engine
                                   #   (gaits/engine.py), these values fixed; its numbers may be
                                   #   searched as space keys engine.NAME
    scenario:                      # optional: K match walks per surface per trial (tuner/sim/scenario.py)
      walks: 6                     #   scenario seeds 0..K-1 of the tuning stream, the same every trial
      min_survival: 0.9            #   below this share of walks standing: infeasible (stops early)
      tracking_weight: 10.0        #   score = pitch RMS [deg] + this x (vx + vy RMSE [m/s] + 0.1 wz RMSE [rad/s])
      randomisation: {}            #   overrides of tuner/sim/randomisation.py's defaults, or none
      forward: 0.3                 #   the scenario's distribution: any field of tuner/sim/scenario.py
    challenge:                     # optional: the push-recovery challenge (tuner/sim/challenge.py) per
      seeds: [0, 1, 2]             #   surface and push seed; the objective push_distance is per surface
      rope: 1.5                    #   the mean largest fully successful D [m], then the aggregate over
      start: 0.05                  #   surfaces (maximised); the robot walks in place; D raised from
      step: 0.05                   #   start by step [m] until a trial fails
    controller: my_controller.yaml # optional, instead of gait/base: a controller of your own
                                   #   (tuner/controllers.py); its parameters are searched as
                                   #   controller.NAME (default: every range its file declares);
                                   #   the study runs its code
    speed:                         # optional: a speed study, scored by tuner/sim/walk_speed.py
      directions:                  #   forward, backward, left, right, turn_left, turn_right
        forward: {top: 0.45, weight: 1.0}     # top stair [m/s or rad/s], weight in the score
        turn_left: {top: 1.6, weight: 0.2}
      levels: 8                    #   stairs from top / levels up to top
      steps_per_level: 4           #   steps each stair is held (even: whole cycles)
      tolerance: 0.3               #   a stair is held if measured >= (1 - tolerance) x commanded
      pitch_weight: 0.005          #   score = sum(weight x highest stair held) - pitch_weight x pitch RMS [deg]
      mode: weighted               #   weighted: one objective (maximised); pareto: one per
                                   #   direction (maximised) and pitch_rms (minimised)

A speed study has no ``objectives`` key: its objectives follow from ``speed.mode``; nor has a
challenge study: its one objective is ``push_distance``.

Every mistake is a :class:`tuner.errors.UserError` naming the file, the key and
the allowed values.
"""

from __future__ import annotations

import dataclasses
import math
import os
import re
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Mapping


from gaits import DIRECTIONS, Drive, GaitParams, ParamError, UserController, families, family, family_class, walks_direction

from ..errors import UserError
from ..params_io import resolve_params
from ..sim.surfaces import SURFACES, load_surface
from ..yaml_input import read_yaml_file

MAX_DURATION_S = 600.0                                  # [s] longest rollout a study may ask for
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")   # a study name is a file name in runs/

__all__ = ["ParamRange", "SpeedSpec", "StudySpec", "load_study", "STUDY_DIR", "list_studies", "OBJECTIVES"]

STUDY_DIR = Path(__file__).resolve().parents[2] / "studies"
OBJECTIVES = {"pitch_rms": "minimize", "speed": "maximize", "speed_score": "maximize",
              **{d: "maximize" for d in ("forward", "backward", "left", "right", "turn_left", "turn_right")},
              "push_distance": "maximize"}
_KEYS = ("name", "description", "robot", "surfaces", "aggregate", "gait", "base", "fixed", "space",
         "objectives", "trials", "duration", "enqueue", "baselines", "sampler_seed", "robust", "stabiliser",
         "speed", "controller", "engine", "scenario", "challenge")
RISKS = ("cvar25", "worst", "mean")
STAB_PREFIX = "stabiliser."
CTRL_PREFIX = "controller."
ENGINE_PREFIX = "engine."
#: [s] a study's walk of a controller of the user's own when the study gives no duration
USER_DURATION_S = 10.0


@dataclass(frozen=True)
class RobustSpec:
    """A robust study's evaluation: K randomised rollouts per surface (see tuner/sim/randomisation.py)."""

    rollouts: int = 8                 # K per surface per trial
    risk: str = "cvar25"              # cvar25 | worst | mean over all rollouts' scores
    min_survival: float = 0.95        # [-] fraction of rollouts that must stay up
    randomisation: Any = None         # tuner.randomisation.Randomisation


@dataclass(frozen=True)
class SpeedSpec:
    """A speed study's scoring (see tuner/sim/walk_speed.py): directions with top stair and weight."""

    directions: tuple[tuple[str, float, float], ...]   # (name, top [m/s or rad/s], weight)
    levels: int = 8
    steps_per_level: int = 4
    tolerance: float = 0.3
    pitch_weight: float = 0.005
    mode: str = "weighted"

    def staircase(self, name: str, top: float):
        from gaits import SpeedStaircase
        return SpeedStaircase(name, top, self.levels, self.steps_per_level)


MAX_SEED = 2 ** 31 - 1


def _check_integer_ranges(space: list, source: str) -> None:
    """An integer parameter's range must hold an integer (Optuna draws from ceil(low)..floor(high))."""
    for r in space:
        if r.integer and math.ceil(r.low) > math.floor(r.high):
            _fail(source, f"space: {r.name} is an integer, but [{r.low:g}, {r.high:g}] holds no integer")
        if r.integer and r.log and math.ceil(r.low) < 1:
            _fail(source, f"space: {r.name} is an integer on a log scale: low must be at least 1, got {r.low:g}")


@dataclass(frozen=True)
class ParamRange:
    name: str
    low: float
    high: float
    log: bool = False
    integer: bool = False
    unit: str = "-"

    @property
    def label(self) -> str:
        """The parameter's name in Optuna's storage, with its SI unit (``t_mn [rad]``), so the
        dashboard and Optuna's plots show it; dimensionless parameters keep their bare name."""
        return self.name if self.unit in ("", "-") else f"{self.name} [{self.unit}]"


@dataclass(frozen=True)
class StudySpec:
    name: str
    gait: str
    base: GaitParams
    space: tuple[ParamRange, ...]
    surfaces: tuple[str, ...] = ("grass50",)
    robot: str = "kidsize"
    aggregate: str = "worst"
    objectives: tuple[str, ...] = ("pitch_rms",)
    trials: int = 60
    duration: float | None = None
    enqueue: tuple[str, ...] = ("casadi", "baselines")
    baselines: tuple[GaitParams, ...] = ()
    sampler_seed: int = 0
    description: str = ""
    source: str = ""
    extra: dict = field(default_factory=dict)
    robust: RobustSpec | None = None
    stabiliser: Any = None            # gaits.StabiliserParams: the fixed values, or None (open loop)
    speed: SpeedSpec | None = None    # a speed study's scoring, or None
    controller: UserController | None = None   # a controller of the user's own (then gait "user")
    engine: Any = None                # gaits.engine.EngineParams: trials walk the online engine
    scenario: Any = None              # ScenarioSpec: match walks per surface per trial
    challenge: Any = None             # ChallengeSpec: the push-recovery challenge per surface per trial

    @property
    def directions(self) -> list[str]:
        return [OBJECTIVES[o] for o in self.objectives]

    def stabiliser_for(self, sampled: Mapping[str, Any]) -> Any:
        """The study's stabiliser with the sampled gains (keys ``stabiliser.NAME``), or None."""
        if self.stabiliser is None:
            return None
        gains = {k[len(STAB_PREFIX):]: v for k, v in sampled.items() if k.startswith(STAB_PREFIX)}
        return dataclasses.replace(self.stabiliser, **gains)

    def drive_for(self, sampled: Mapping[str, Any], source: str = "") -> Drive:
        """What a trial walks: the sampled set (or the user's controller with the sampled values)
        and the study's stabiliser with the sampled gains. ParamError for an invalid set."""
        stabiliser = self.stabiliser_for(sampled)
        if self.controller is not None:
            values = {k[len(CTRL_PREFIX):]: float(v) for k, v in sampled.items() if k.startswith(CTRL_PREFIX)}
            return Drive(None, stabiliser, source=source, user=self.controller.with_params(values))
        return Drive(self.params_for(sampled), stabiliser, source=source, engine=self.engine_for(sampled))

    def engine_for(self, sampled: Mapping[str, Any]) -> Any:
        """The study's engine with the sampled values (keys ``engine.NAME``), or None."""
        if self.engine is None:
            return None
        values = {k[len(ENGINE_PREFIX):]: v for k, v in sampled.items() if k.startswith(ENGINE_PREFIX)}
        return dataclasses.replace(self.engine, **values)

    def params_for(self, sampled: Mapping[str, Any]) -> GaitParams:
        """The base with the sampled values and the fields that follow from them (the family's
        ``derived`` rule, e.g. TLIPFM's d2 = step_length - d1)."""
        values = {k: v for k, v in sampled.items() if not k.startswith((STAB_PREFIX, CTRL_PREFIX, ENGINE_PREFIX))}
        values.update(family(self.gait).derived(values, self.base))
        return self.base.replace(**values)


def list_studies() -> list[Path]:
    return sorted(STUDY_DIR.glob("*.yaml"))


def _beside(spec: str, study: Path) -> str:
    """A parameter file named by a study: a relative path is taken beside the study file (as its
    robot map is) when a file is there; shipped set names pass through."""
    p = Path(spec)
    if not p.is_absolute() and p.suffix in (".yaml", ".yml") and (study.parent / p).exists():
        return str(study.parent / p)
    return spec


def _fail(source: str, msg: str) -> None:
    raise UserError(f"{source}: {msg}")


def _check_section(sec: Any, name: str, allowed: tuple[str, ...], source: str) -> None:
    """A study's section must be a mapping of the allowed keys (one line naming the first stranger)."""
    if not isinstance(sec, Mapping):
        _fail(source, f"{name} must be a mapping of {', '.join(allowed)}")
    for k in sec:
        if k not in allowed:
            _fail(source, f"{name}: unknown key {k!r} (allowed: {', '.join(allowed)})")


def _study_robot(robot: Any, path: Path, source: str) -> str:
    """The study's robot: a built-in name, or a map path resolved against the study file's folder
    (returned absolute); loaded once here so a bad robot is one line before any worker starts."""
    from ..robots import BUILTIN_ROBOTS, load_robot
    if not isinstance(robot, str) or not robot.strip():
        _fail(source, f"robot = {robot!r}: expected a built-in robot name ({', '.join(BUILTIN_ROBOTS)}) "
              f"or a robot map YAML path")
    if robot not in BUILTIN_ROBOTS:
        p = Path(robot)
        robot = str((p if p.is_absolute() else path.parent / p).resolve())
    try:
        load_robot(robot)
    except UserError as exc:
        _fail(source, f"robot: {exc}")
    return robot


def load_study(path_or_name: str) -> StudySpec:
    """Read and validate a study YAML (a path, or the name of a shipped study)."""
    path = Path(path_or_name)
    if not os.path.lexists(path) and (STUDY_DIR / f"{path_or_name}.yaml").exists():
        path = STUDY_DIR / f"{path_or_name}.yaml"
    source = str(path)
    if not os.path.lexists(path):
        _fail(source, "no such study file (shipped studies: "
              + ", ".join(p.stem for p in list_studies()) + ")")
    doc = read_yaml_file(path, "study")
    if not isinstance(doc, Mapping):
        _fail(source, "expected a mapping of study keys")
    for key in doc:
        if key not in _KEYS:
            _fail(source, f"unknown key {key!r} (allowed: {', '.join(_KEYS)})")
    if doc.get("controller") is not None:
        return _user_study(doc, path, source)
    for key in ("gait", "space"):
        if key not in doc:
            _fail(source, f"missing {key!r}")
    gait = doc["gait"]
    if not isinstance(gait, str):
        _fail(source, f"gait must be a family name ({', '.join(families())}), got {gait!r}")
    try:
        cls = family_class(str(gait))
    except Exception as exc:
        _fail(source, str(exc))
    base_spec = doc.get("base")
    try:
        base = resolve_params(None if base_spec is None else _beside(str(base_spec), path), gait).params
    except Exception as exc:
        _fail(source, f"base: {exc}")
    numeric = {f.name: f for f in fields(cls) if isinstance(f.default, (int, float))
               and not isinstance(f.default, bool)}
    fixed = doc.get("fixed") or {}
    if not isinstance(fixed, Mapping):
        _fail(source, "fixed must be a mapping of parameter: value")
    for k in fixed:
        if k not in {f.name for f in fields(cls)}:
            _fail(source, f"fixed: unknown parameter {k!r} for gait {gait!r}")
    fixed_values = dict(fixed)
    fixed_values.update(family(gait).derived(fixed_values, base))
    try:
        base = base.replace(**fixed_values)
    except Exception as exc:
        _fail(source, f"fixed: {exc}")
    space_doc = doc["space"]
    if not isinstance(space_doc, Mapping) or not space_doc:
        _fail(source, "space must map at least one parameter to {low, high}")
    stabiliser = _study_stabiliser(doc.get("stabiliser"), source)
    engine = _study_engine(doc.get("engine"), gait, source)
    space = []
    for name, rng in space_doc.items():
        if isinstance(name, str) and name.startswith(STAB_PREFIX):
            space.append(_stabiliser_range(name, rng, stabiliser, source))
            continue
        if isinstance(name, str) and name.startswith(ENGINE_PREFIX):
            space.append(_engine_range(name, rng, engine, source))
            continue
        if name not in numeric:
            _fail(source, f"space: unknown or non-numeric parameter {name!r} for gait {gait!r} "
                          f"(numeric parameters: {', '.join(numeric)})")
        if name in fixed:
            _fail(source, f"space: {name!r} is also fixed")
        low, high, log = _range_bounds(name, rng, source)
        meta = numeric[name].metadata
        if low < meta["lo"] or high > meta["hi"]:
            _fail(source, f"space: {name} range [{low}, {high}] leaves the parameter's allowed range "
                          f"[{meta['lo']}, {meta['hi']}] {meta['unit']}")
        space.append(ParamRange(name, float(low), float(high), log,
                                isinstance(numeric[name].default, int), meta["unit"]))
    c = _common(doc, path, source, gait)
    surfaces, aggregate, speed, objectives, trials, duration, enqueue, seed, name, description = c
    extra_sets = []
    if not isinstance(doc.get("baselines") or [], list):
        _fail(source, f"baselines must be a list of parameter sets, got {doc.get('baselines')!r}")
    for b in doc.get("baselines") or []:
        try:
            gf = resolve_params(_beside(str(b), path), gait)
        except Exception as exc:
            _fail(source, f"baselines: {exc}")
        extra_sets.append(gf.params)
    robot = _study_robot(doc.get("robot", "kidsize"), path, source)
    robust = _study_robust(doc.get("robust"), source)
    scenario = _study_scenario(doc.get("scenario"), source)
    if scenario is not None and (robust is not None or speed is not None):
        _fail(source, "scenario does not go with robust or speed: a scenario study has its own randomised walks")
    challenge = _study_challenge(doc, source)
    if speed is not None and engine is not None:
        _fail(source, "speed studies walk tables on staircases: give the engine a scenario: section instead")
    _check_integer_ranges(space, source)
    return StudySpec(name=name, gait=str(gait), base=base,
                     space=tuple(space), surfaces=tuple(str(s) for s in surfaces), robot=str(robot),
                     aggregate=aggregate, objectives=tuple(objectives), trials=trials,
                     duration=None if duration is None else float(duration), enqueue=tuple(enqueue),
                     baselines=tuple(extra_sets), sampler_seed=seed,
                     description=description, source=source, robust=robust,
                     stabiliser=stabiliser, speed=speed, engine=engine, scenario=scenario,
                     challenge=challenge)


def _common(doc: Mapping[str, Any], path: Path, source: str, gait: str) -> tuple:
    """The keys every study reads the same way (surfaces .. description)."""
    if "surfaces" not in doc:
        _fail(source, "missing 'surfaces': name the surfaces to tune on, e.g. surfaces: [grass50] "
                      "(`gait-tuner surfaces` lists them)")
    surfaces = doc["surfaces"]
    if isinstance(surfaces, str):
        surfaces = [surfaces]
    if not isinstance(surfaces, list) or not surfaces:
        _fail(source, "surfaces must be a list of surface names or files")
    for s in surfaces:
        if not isinstance(s, str):
            _fail(source, f"surfaces: {s!r} is not a surface name or file")
        if s not in SURFACES:
            try:
                load_surface(str(s))
            except UserError as exc:
                _fail(source, f"surfaces: {exc}")
    aggregate = doc.get("aggregate", "worst")
    if aggregate not in ("worst", "mean"):
        _fail(source, f"aggregate must be worst or mean, got {aggregate!r}")
    speed = _study_speed(doc.get("speed"), source)
    if speed is not None:
        if "objectives" in doc:
            _fail(source, "a speed study takes its objectives from speed.mode: remove 'objectives'")
        for name, _, _ in speed.directions:
            if not walks_direction(gait, name):
                _fail(source, f"speed.directions: gait {gait!r} does not walk {name} ({family(gait).commands_text})")
        if doc.get("robust") is not None:
            _fail(source, "speed and robust together are not built: list the pedestals under surfaces")
    objectives = doc.get("objectives", ["pitch_rms"])
    if doc.get("challenge") is not None:
        if "objectives" in doc:
            _fail(source, "a challenge study's one objective is push_distance: remove 'objectives'")
        objectives = ["push_distance"]
    elif speed is not None:
        objectives = (["speed_score"] if speed.mode == "weighted"
                      else [d[0] for d in speed.directions] + ["pitch_rms"])
    elif not isinstance(objectives, list) or not objectives or any(o not in OBJECTIVES for o in objectives) \
            or objectives[0] != "pitch_rms" or len(set(objectives)) != len(objectives):
        _fail(source, f"objectives must be [pitch_rms] or [pitch_rms, speed], got {objectives!r}")
    trials = doc.get("trials", 60)
    if not isinstance(trials, int) or isinstance(trials, bool) or not 1 <= trials <= 100_000:
        _fail(source, f"trials must be an integer in [1, 100000], got {trials!r}")
    duration = doc.get("duration")
    if duration is not None and (not isinstance(duration, (int, float)) or isinstance(duration, bool)
                                 or not 0 < duration <= MAX_DURATION_S):
        _fail(source, f"duration must be a number of seconds in (0, {MAX_DURATION_S:g}] or null, "
                      f"got {duration!r}")
    enqueue = doc.get("enqueue", ["casadi", "baselines"])
    if not isinstance(enqueue, list) or any(e not in ("casadi", "baselines") for e in enqueue):
        _fail(source, f"enqueue must list casadi and/or baselines, got {enqueue!r}")
    seed = doc.get("sampler_seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        _fail(source, f"sampler_seed must be an integer, got {seed!r}")
    if not 0 <= seed <= MAX_SEED:
        _fail(source, f"sampler_seed = {seed}: allowed 0 to {MAX_SEED} (the sampler's seed range)")
    name = doc.get("name") or path.stem
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        _fail(source, f"name must be letters, digits, '.', '_' or '-' (at most 100, no path), "
                      f"got {name!r}")
    description = doc.get("description") or ""
    if not isinstance(description, str):
        _fail(source, f"description must be text, got {type(description).__name__}")
    return surfaces, aggregate, speed, objectives, trials, duration, enqueue, seed, name, description


def _user_study(doc: Mapping[str, Any], path: Path, source: str) -> "StudySpec":
    """A study of a controller of the user's own (its file imported here, once)."""
    from ..controllers import load_controller
    for key in ("gait", "base", "fixed", "baselines"):
        if key in doc:
            _fail(source, f"{key!r} does not go with 'controller': the controller's file holds its parameters")
    if doc.get("speed") is not None:
        _fail(source, "speed studies walk a gait's staircases: not built for a controller of your own")
    ref = doc["controller"]
    if not isinstance(ref, str):
        _fail(source, f"controller = {ref!r}: expected the path of a controller YAML")
    cpath = Path(ref) if Path(ref).is_absolute() else path.parent / ref
    try:
        user = load_controller(cpath)
    except UserError as exc:
        _fail(source, f"controller: {exc}")
    stabiliser = _study_stabiliser(doc.get("stabiliser"), source)
    space_doc = doc.get("space")
    if space_doc is None:
        space_doc = {CTRL_PREFIX + k: {"low": lo, "high": hi} for k, (lo, hi) in user.ranges.items()}
    if not isinstance(space_doc, Mapping) or not space_doc:
        _fail(source, "space must map at least one controller.NAME to {low, high} (or the controller's "
                      "file must declare ranges)")
    space = []
    for name, rng in space_doc.items():
        if isinstance(name, str) and name.startswith(STAB_PREFIX):
            space.append(_stabiliser_range(name, rng, stabiliser, source))
            continue
        field_name = name[len(CTRL_PREFIX):] if isinstance(name, str) and name.startswith(CTRL_PREFIX) else None
        if field_name not in user.params:
            _fail(source, f"space: {name!r} is not controller.NAME of one of the controller's parameters "
                          f"({', '.join(user.params) or 'none'})")
        low, high, log = _range_bounds(name, rng, source)
        if field_name in user.ranges:
            lo, hi = user.ranges[field_name]
            if low < lo or high > hi:
                _fail(source, f"space: {name} range [{low}, {high}] leaves the controller's range [{lo}, {hi}]")
        space.append(ParamRange(name, float(low), float(high), log, False, "-"))
    enqueue_doc = doc.get("enqueue", ["baselines"])
    if not isinstance(enqueue_doc, list) or any(e != "baselines" for e in enqueue_doc):
        _fail(source, f"enqueue: a controller study can enqueue [baselines] (its file's values) only, got {enqueue_doc!r}")
    doc = {**doc, "enqueue": enqueue_doc,
           "duration": USER_DURATION_S if doc.get("duration") is None else doc["duration"]}
    c = _common(doc, path, source, "user")
    surfaces, aggregate, _, objectives, trials, duration, enqueue, seed, name, description = c
    robot = _study_robot(doc.get("robot", "kidsize"), path, source)
    return StudySpec(name=name, gait="user", base=None, space=tuple(space), surfaces=tuple(surfaces),
                     robot=str(robot), aggregate=aggregate, objectives=tuple(objectives), trials=trials,
                     duration=duration, enqueue=tuple(enqueue), sampler_seed=seed, description=description,
                     source=source, robust=_study_robust(doc.get("robust"), source), stabiliser=stabiliser,
                     controller=user, challenge=_study_challenge(doc, source))


@dataclass(frozen=True)
class ScenarioSpec:
    """A scenario study's walks: K match walks per surface (``tuner/sim/scenario.py``)."""

    walks: int = 6
    min_survival: float = 0.9
    tracking_weight: float = 10.0      # [deg per m/s]
    randomisation: Any = None          # tuner.sim.randomisation.Randomisation
    scenario: Any = None               # tuner.sim.scenario.Scenario


def _study_scenario(doc: Any, source: str) -> ScenarioSpec | None:
    if doc is None:
        return None
    from ..sim.randomisation import randomisation_from_mapping
    from ..sim.scenario import SCENARIO_FIELDS, scenario_from_mapping
    _check_section(doc, "scenario", ("walks", "min_survival", "tracking_weight", "randomisation") + SCENARIO_FIELDS,
                   source)
    k = doc.get("walks", 6)
    if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= 1000:
        _fail(source, f"scenario: walks = {k!r}: expected a whole number in [1, 1000]")
    ms = doc.get("min_survival", 0.9)
    if not isinstance(ms, (int, float)) or isinstance(ms, bool) or not 0.0 <= ms <= 1.0:
        _fail(source, f"scenario: min_survival = {ms!r}: expected a fraction in [0, 1]")
    tw = doc.get("tracking_weight", 10.0)
    if not isinstance(tw, (int, float)) or isinstance(tw, bool) or not 0.0 <= tw <= 1000.0:
        _fail(source, f"scenario: tracking_weight = {tw!r}: expected a number in [0, 1000] deg per m/s")
    try:
        rnd = randomisation_from_mapping(doc.get("randomisation"), "scenario.randomisation")
        scen = scenario_from_mapping({kk: v for kk, v in doc.items() if kk in SCENARIO_FIELDS}, "scenario")
    except UserError as exc:
        _fail(source, str(exc))
    return ScenarioSpec(k, float(ms), float(tw), rnd, scen)


@dataclass(frozen=True)
class ChallengeSpec:
    """A challenge study's trials (ours): the push-recovery challenge (``tuner/sim/challenge.py``) on
    each surface for each push seed; the score is the mean over them of the largest fully
    successful D [m] (``start - step`` where even ``start`` fails)."""

    seeds: tuple[int, ...] = (0, 1, 2)
    rope: float = 1.5                  # [m] the rules allow 1-2 m
    start: float = 0.05                # [m] the first D tried
    step: float = 0.05                 # [m] D raised by this until a trial fails


def _study_challenge(doc: Mapping[str, Any], source: str) -> ChallengeSpec | None:
    """The ``challenge:`` section, checked against the study's other sections."""
    sec = doc.get("challenge")
    if sec is None:
        return None
    _check_section(sec, "challenge", ("seeds", "rope", "start", "step"), source)
    for other in ("robust", "scenario", "speed"):
        if doc.get(other) is not None:
            _fail(source, f"challenge does not go with {other}: a challenge study walks the challenge's own trials")
    if doc.get("duration") is not None and doc.get("controller") is None:
        _fail(source, "challenge: the challenge's trials last 14 s each: remove 'duration'")
    seeds = sec.get("seeds", [0, 1, 2])
    if not isinstance(seeds, list) or not seeds or len(seeds) > 100 or any(
            not isinstance(k, int) or isinstance(k, bool) or not 0 <= k <= MAX_SEED for k in seeds) \
            or len(set(seeds)) != len(seeds):
        _fail(source, f"challenge: seeds = {seeds!r}: expected a list of 1 to 100 different whole numbers "
                      f"in [0, {MAX_SEED}]")
    vals = {}
    for k, default, lo, hi in (("rope", 1.5, 1.0, 2.0), ("start", 0.05, 0.01, 1.9), ("step", 0.05, 0.01, 1.0)):
        v = sec.get(k, default)
        if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v) or not lo <= v <= hi:
            _fail(source, f"challenge: {k} = {v!r}: expected a number in [{lo:g}, {hi:g}] m")
        vals[k] = float(v)
    if vals["start"] >= 0.95 * vals["rope"]:
        _fail(source, f"challenge: start = {vals['start']:g} m: the bottle is released from below 0.95 of the "
                      f"rope ({0.95 * vals['rope']:g} m): start lower")
    return ChallengeSpec(tuple(int(k) for k in seeds), vals["rope"], vals["start"], vals["step"])


def _study_engine(doc: Any, gait: str, source: str) -> Any:
    if doc is None:
        return None
    from gaits.gait_file import engine_from_mapping
    if gait != "tlipfm":
        _fail(source, f"engine: the walk engine plans TLIPFM steps, not {gait!r}")
    try:
        return engine_from_mapping({} if doc is True else doc, "engine")
    except ParamError as exc:
        _fail(source, str(exc))


def _engine_range(name: str, rng: Any, engine: Any, source: str) -> ParamRange:
    from gaits.engine import EngineParams
    field_name = name[len(ENGINE_PREFIX):]
    if engine is None:
        _fail(source, f"space: {name!r} needs an engine: section (e.g. engine: {{}})")
    rows = {r["name"]: r for r in EngineParams.field_table()}
    numeric = {f.name for f in fields(EngineParams) if isinstance(f.default, (int, float)) and not isinstance(f.default, bool)}
    if field_name not in numeric:
        _fail(source, f"space: unknown or non-numeric engine field {field_name!r} (numeric: {', '.join(sorted(numeric))})")
    low, high, log = _range_bounds(name, rng, source)
    meta = next(f.metadata for f in fields(EngineParams) if f.name == field_name)
    if low < meta["lo"] or high > meta["hi"]:
        _fail(source, f"space: {name} range [{low}, {high}] leaves the allowed range [{meta['lo']}, {meta['hi']}] "
                      f"{rows[field_name]['unit']}")
    integer = isinstance(next(f.default for f in fields(EngineParams) if f.name == field_name), int)
    return ParamRange(name, float(low), float(high), log, integer, meta["unit"])


def _study_stabiliser(doc: Any, source: str) -> Any:
    if doc is None:
        return None
    from gaits.imu_stabiliser import stabiliser_from_mapping
    try:
        return stabiliser_from_mapping(doc, "stabiliser")
    except ParamError as exc:
        _fail(source, str(exc))


def _range_bounds(name: str, rng: Any, source: str) -> tuple[float, float, bool]:
    """(low, high, log) of a space entry {low, high, log}: a mapping of those keys, a boolean
    log flag, finite numbers with low < high, low > 0 when log-scaled; else one line naming it."""
    if not isinstance(rng, Mapping) or not {"low", "high"} <= set(rng) or not set(rng) <= {"low", "high", "log"}:
        _fail(source, f"space: {name} must be {{low: ..., high: ..., log: false}}")
    low, high, log = rng["low"], rng["high"], rng.get("log", False)
    if not isinstance(log, bool):
        _fail(source, f"space: {name}.log must be true or false, got {log!r}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (low, high)):
        _fail(source, f"space: {name} bounds must be numbers, got {low!r}, {high!r}")
    if not all(math.isfinite(v) for v in (low, high)):
        _fail(source, f"space: {name} bounds must be finite, got {low!r}, {high!r}")
    if not low < high:
        _fail(source, f"space: {name} bounds reversed or empty: low = {low}, high = {high}")
    if log and low <= 0:
        _fail(source, f"space: {name} is log-scaled, so low must be > 0 (got {low})")
    return low, high, log


def _stabiliser_range(name: str, rng: Any, stabiliser: Any, source: str) -> ParamRange:
    from gaits.imu_stabiliser import _RANGES
    field_name = name[len(STAB_PREFIX):]
    if stabiliser is None:
        _fail(source, f"space: {name!r} needs a stabiliser: section (e.g. stabiliser: {{enabled: true}})")
    if field_name not in _RANGES:
        _fail(source, f"space: unknown stabiliser gain {field_name!r} (allowed: {', '.join(_RANGES)})")
    low, high, log = _range_bounds(name, rng, source)
    lo, hi, unit = _RANGES[field_name]
    if low < lo or high > hi:
        _fail(source, f"space: {name} range [{low}, {high}] leaves the allowed range [{lo}, {hi}] {unit}")
    return ParamRange(name, float(low), float(high), log, False, unit)


def _study_robust(doc: Any, source: str) -> RobustSpec | None:
    if doc is None:
        return None
    from ..sim.randomisation import randomisation_from_mapping
    _check_section(doc, "robust", ("rollouts", "risk", "min_survival", "randomisation"), source)
    k = doc.get("rollouts", 8)
    if not isinstance(k, int) or isinstance(k, bool) or not 1 <= k <= 1000:
        _fail(source, f"robust.rollouts = {k!r}: expected a whole number in [1, 1000]")
    risk = doc.get("risk", "cvar25")
    if risk not in RISKS:
        _fail(source, f"robust.risk = {risk!r}: expected one of {', '.join(RISKS)}")
    ms = doc.get("min_survival", 0.95)
    if not isinstance(ms, (int, float)) or isinstance(ms, bool) or not 0.0 <= ms <= 1.0:
        _fail(source, f"robust.min_survival = {ms!r}: expected a fraction in [0, 1]")
    try:
        rnd = randomisation_from_mapping(doc.get("randomisation"), "robust.randomisation")
    except UserError as exc:
        _fail(source, str(exc))
    return RobustSpec(k, risk, float(ms), rnd)


def _study_speed(doc: Any, source: str) -> SpeedSpec | None:
    if doc is None:
        return None
    allowed = ("directions", "levels", "steps_per_level", "tolerance", "pitch_weight", "mode")
    if not isinstance(doc, Mapping):
        _fail(source, f"speed must be a mapping of {', '.join(allowed)}")
    for k in doc:
        if k not in allowed:
            _fail(source, f"speed: unknown key {k!r} (allowed: {', '.join(allowed)})")
    dirs = doc.get("directions")
    if not isinstance(dirs, Mapping) or not dirs:
        _fail(source, f"speed.directions must map at least one of {', '.join(DIRECTIONS)} to {{top, weight}}")
    out = []
    for name, d in dirs.items():
        if name not in DIRECTIONS:
            _fail(source, f"speed.directions: unknown direction {name!r} (allowed: {', '.join(DIRECTIONS)})")
        if not isinstance(d, Mapping) or "top" not in d or not set(d) <= {"top", "weight"}:
            _fail(source, f"speed.directions.{name} must be {{top: ..., weight: ...}}")
        top, weight = d["top"], d.get("weight", 1.0)
        unit = "rad/s" if name.startswith("turn") else "m/s"
        if isinstance(top, bool) or not isinstance(top, (int, float)) or not 0 < top <= 3.0:
            _fail(source, f"speed.directions.{name}.top = {top!r}: expected a number in (0, 3] {unit}")
        if isinstance(weight, bool) or not isinstance(weight, (int, float)) or not 0 <= weight <= 100:
            _fail(source, f"speed.directions.{name}.weight = {weight!r}: expected a number in [0, 100]")
        out.append((str(name), float(top), float(weight)))

    def number(key, default, lo, hi, integer=False):
        v = doc.get(key, default)
        ok = isinstance(v, int) if integer else isinstance(v, (int, float))
        if isinstance(v, bool) or not ok or not lo <= v <= hi:
            _fail(source, f"speed.{key} = {v!r}: expected {'a whole number' if integer else 'a number'} "
                          f"in [{lo}, {hi}]")
        return v

    levels = number("levels", 8, 1, 50, True)
    spl = number("steps_per_level", 4, 2, 40, True)
    if spl % 2:
        _fail(source, f"speed.steps_per_level = {spl}: must be even (whole gait cycles)")
    mode = doc.get("mode", "weighted")
    if mode not in ("weighted", "pareto"):
        _fail(source, f"speed.mode = {mode!r}: expected weighted or pareto")
    return SpeedSpec(tuple(out), levels, spl, float(number("tolerance", 0.3, 0.0, 0.9)),
                     float(number("pitch_weight", 0.005, 0.0, 10.0)), mode)
