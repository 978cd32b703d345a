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
      t2: {low: 0.6, high: 0.9, of: period}    # a share of another parameter (every draw t2 < period)
    objectives: [pitch_rms]        # pitch_rms (minimised); add speed (maximised) for a Pareto front
    trials: 60
    duration: null                 # rollout length [s]; null: the whole gait
    enqueue: [casadi, baselines]   # tried first: the CasADi seed and the base (+ `baselines`)
    baselines: []                  # more parameter sets of the same family to try first
    sampler_seed: 0
    stabiliser: {enabled: true}    # optional: the IMU stabiliser's fixed values; its gains may be
                                   #   searched as space keys stabiliser.k_ankle_pitch etc.
    engine: {k_vel: 0.8}           # optional (TLIPFM): walk every trial with the online walk engine
                                   #   (gaits/engine/), these values fixed; its numbers may be
                                   #   searched as space keys engine.NAME
    controller: my_controller.yaml # optional, instead of gait/base: a controller of your own
                                   #   (tuner/controllers.py); its parameters are searched as
                                   #   controller.NAME (default: every range its file declares);
                                   #   the study runs its code
    robust: | scenario: | challenge: | speed:   # optional, at most one: the scenario trials walk in
    runs: runs                     # optional: the folder of its journal, relative to this file
                                   #   (init writes it: the journal beside the study); default ./runs

What a trial's score stands on (the robot, the surfaces, the scenario, the objectives, what is held
fixed: ``workers.scoring_parts``) is stored with the study's first trials; a resume with other
parts is one line (a widened space resumes).

Without one of those sections a trial walks each surface once. Each section is a scenario of
``tuner/scenarios`` (``robust.py`` randomised walks, ``match.py`` match walks under the key
``scenario``, ``challenge.py`` the push-recovery challenge, ``speed.py`` speed staircases); its
file documents its keys, its objectives and its scoring. A speed study takes its objectives from
``speed.mode``, a challenge study has the one objective ``push_distance``.

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


from gaits import Drive, GaitParams, ParamError, UserController, did_you_mean, families, family, family_class

from ..errors import UserError
from ..params_io import SHIPPED_DIR, resolve_params
from ..scenarios import SCENARIOS, scenario_for_doc, scenario_named
from ..scenarios.base import MAX_SEED, OBJECTIVES, fail
from ..sim.surfaces import SURFACES, load_surface
from ..yaml_input import read_yaml_file

MAX_DURATION_S = 600.0                                  # [s] longest rollout a study may ask for
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]{0,99}")   # a study name is a file name in runs/

__all__ = ["ParamRange", "StudySpec", "load_study", "STUDY_DIR", "list_studies", "OBJECTIVES"]

STUDY_DIR = SHIPPED_DIR
#: the keys every study file may have; each registered scenario adds its section
_COMMON_KEYS = ("name", "description", "robot", "surfaces", "aggregate", "gait", "base", "fixed", "space",
                "objectives", "trials", "duration", "enqueue", "baselines", "sampler_seed", "stabiliser",
                "controller", "engine", "runs")
STAB_PREFIX = "stabiliser."
CTRL_PREFIX = "controller."
ENGINE_PREFIX = "engine."
#: [s] a study's walk of a controller of the user's own when the study gives no duration
USER_DURATION_S = 10.0


def _check_integer_ranges(space: list, source: str) -> None:
    """An integer parameter's range must hold an integer (Optuna draws from ceil(low)..floor(high))."""
    for r in space:
        if r.integer and math.ceil(r.low) > math.floor(r.high):
            fail(source, f"space: {r.name} is an integer, but [{r.low:g}, {r.high:g}] holds no integer")
        if r.integer and r.log and math.ceil(r.low) < 1:
            fail(source, f"space: {r.name} is an integer on a log scale: low must be at least 1, got {r.low:g}")


@dataclass(frozen=True)
class ParamRange:
    name: str
    low: float
    high: float
    log: bool = False
    integer: bool = False
    unit: str = "-"
    of: str | None = None             # searched as a share of this parameter (``t2: {low, high, of: period}``)

    @property
    def label(self) -> str:
        """The parameter's name in Optuna's storage, with its SI unit (``t_mn [rad]``), so the
        dashboard and Optuna's plots show it; dimensionless parameters keep their bare name; a share
        says of what (``t2 [x period]``)."""
        if self.of is not None:
            return f"{self.name} [x {self.of}]"
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
    stabiliser: Any = None            # gaits.StabiliserParams: the fixed values, or None (open loop)
    controller: UserController | None = None   # a controller of the user's own (then gait "user")
    engine: Any = None                # gaits.engine.EngineParams: trials walk the online engine
    kind: str = "walk"                # the scenario a trial walks in (tuner/scenarios: walk, robust, match, ...)
    settings: Any = None              # that scenario's section, read (its dataclass; None for plain walks)
    runs: Path | None = None          # the folder of its journal (its file's runs:), or None: --runs / ./runs

    @property
    def directions(self) -> list[str]:
        return [OBJECTIVES[o] for o in self.objectives]

    @property
    def scenario_room(self) -> Any:
        """The registered scenario (``tuner/scenarios``) the study's trials walk in."""
        return scenario_named(self.kind)

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
        for r in self.space:              # a share of another parameter: its value now
            if r.of is not None and r.name in values:
                values[r.name] = values[r.name] * values.get(r.of, getattr(self.base, r.of))
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


def _keys() -> tuple[str, ...]:
    return _COMMON_KEYS + tuple(sc.section for sc in SCENARIOS.values() if sc.section is not None)


def _study_robot(robot: Any, path: Path, source: str) -> str:
    """The study's robot: a built-in name, or a map path resolved against the study file's folder
    (returned absolute); loaded once here so a bad robot is one line before any worker starts."""
    from ..robots import BUILTIN_ROBOTS, load_robot
    if not isinstance(robot, str) or not robot.strip():
        fail(source, f"robot = {robot!r}: expected a built-in robot name ({', '.join(BUILTIN_ROBOTS)}) "
              f"or a robot map YAML path")
    if robot not in BUILTIN_ROBOTS:
        p = Path(robot)
        robot = str((p if p.is_absolute() else path.parent / p).resolve())
    try:
        gap = load_robot(robot).sensing_gap()
    except UserError as exc:
        fail(source, f"robot: {exc}")
    if gap is not None:                 # a study tunes what the robot side can read, or nothing
        fail(source, f"robot: {gap}")
    return robot


def load_study(path_or_name: str) -> StudySpec:
    """Read and validate a study YAML (a path, or the name of a shipped study); its ``runs:`` (the
    folder of its journal, relative to the file: init writes ``runs: runs``, beside the study) is
    resolved here."""
    path = Path(path_or_name)
    if not os.path.lexists(path) and (STUDY_DIR / f"{path_or_name}.yaml").exists():
        path = STUDY_DIR / f"{path_or_name}.yaml"
    source = str(path)
    if not os.path.lexists(path):
        fail(source, f"no such study file{did_you_mean(path_or_name, [p.stem for p in list_studies()])} (shipped studies: "
              + ", ".join(p.stem for p in list_studies()) + ")")
    doc = read_yaml_file(path, "study")
    if not isinstance(doc, Mapping):
        fail(source, "expected a mapping of study keys")
    keys = _keys()
    for key in doc:
        if key not in keys:
            fail(source, f"unknown key {key!r}{did_you_mean(key, keys)} (allowed: {', '.join(keys)})")
    spec = _study_from(doc, path, source)
    runs = doc.get("runs")
    if runs is None:
        return spec
    if not isinstance(runs, str) or not runs.strip():
        fail(source, f"runs = {runs!r}: expected the folder of the study's journal (relative to this file)")
    return dataclasses.replace(spec, runs=Path(runs) if Path(runs).is_absolute() else path.parent / runs)


def _study_from(doc: Mapping[str, Any], path: Path, source: str) -> StudySpec:
    """The study a checked document gives (its keys known)."""
    if doc.get("controller") is not None:
        return _user_study(doc, path, source)
    for key in ("gait", "space"):
        if key not in doc:
            fail(source, f"missing {key!r}")
    gait = doc["gait"]
    if not isinstance(gait, str):
        fail(source, f"gait must be a family name ({', '.join(families())}), got {gait!r}")
    try:
        cls = family_class(str(gait))
    except Exception as exc:
        fail(source, str(exc))
    base_spec = doc.get("base")
    try:
        base = resolve_params(None if base_spec is None else _beside(str(base_spec), path), gait, "").params
    except Exception as exc:
        fail(source, f"base: {exc}")
    numeric = {f.name: f for f in fields(cls) if isinstance(f.default, (int, float))
               and not isinstance(f.default, bool)}
    fixed = doc.get("fixed") or {}
    if not isinstance(fixed, Mapping):
        fail(source, "fixed must be a mapping of parameter: value")
    for k in fixed:
        if k not in {f.name for f in fields(cls)}:
            fail(source, f"fixed: unknown parameter {k!r} for gait {gait!r}")
    fixed_values = dict(fixed)
    fixed_values.update(family(gait).derived(fixed_values, base))
    try:
        base = base.replace(**fixed_values)
    except Exception as exc:
        fail(source, f"fixed: {exc}")
    space_doc = doc["space"]
    if not isinstance(space_doc, Mapping) or not space_doc:
        fail(source, "space must map at least one parameter to {low, high}")
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
            fail(source, f"space: unknown or non-numeric parameter {name!r} for gait {gait!r} "
                          f"(numeric parameters: {', '.join(numeric)})")
        if name in fixed:
            fail(source, f"space: {name!r} is also fixed")
        of = rng.get("of") if isinstance(rng, Mapping) else None
        if of is not None:
            if of not in numeric or of == name or isinstance(numeric[name].default, int):
                fail(source, f"space: {name}.of = {of!r}: expected another numeric parameter of gait {gait!r} "
                             f"(the share's whole), for a parameter that is not an integer")
            rng = {k: v for k, v in rng.items() if k != "of"}
        low, high, log = _range_bounds(name, rng, source)
        meta = numeric[name].metadata
        if meta["choices"] is not None or meta["lo"] is None:
            fail(source, f"space: {name} takes " + (f"one of {', '.join(map(repr, meta['choices']))}"
                                                     if meta["choices"] else "no range") +
                 ": it is not searched as a range; give it under fixed")
        if of is not None:
            if not 0 < low < high <= 1:
                fail(source, f"space: {name} as a share of {of}: low and high in (0, 1], got [{low}, {high}]")
        elif low < meta["lo"] or high > meta["hi"]:
            fail(source, f"space: {name} range [{low}, {high}] leaves the parameter's allowed range "
                          f"[{meta['lo']}, {meta['hi']}] {meta['unit']}")
        space.append(ParamRange(name, float(low), float(high), log,
                                isinstance(numeric[name].default, int), meta["unit"], of))
    c = _common(doc, path, source, gait)
    surfaces, aggregate, trials, duration, enqueue, seed, name, description = c
    kind, settings, objectives = _scenario(doc, source, gait=str(gait), engine=engine, controller=None)
    extra_sets = []
    if not isinstance(doc.get("baselines") or [], list):
        fail(source, f"baselines must be a list of parameter sets, got {doc.get('baselines')!r}")
    for b in doc.get("baselines") or []:
        try:
            gf = resolve_params(_beside(str(b), path), gait, "")
        except Exception as exc:
            fail(source, f"baselines: {exc}")
        extra_sets.append(gf.params)
    robot = _study_robot(doc.get("robot", "kidsize"), path, source)
    _check_integer_ranges(space, source)
    return StudySpec(name=name, gait=str(gait), base=base,
                     space=tuple(space), surfaces=tuple(str(s) for s in surfaces), robot=str(robot),
                     aggregate=aggregate, objectives=tuple(objectives), trials=trials,
                     duration=None if duration is None else float(duration), enqueue=tuple(enqueue),
                     baselines=tuple(extra_sets), sampler_seed=seed,
                     description=description, source=source, stabiliser=stabiliser, engine=engine,
                     kind=kind, settings=settings)


def _scenario(doc: Mapping[str, Any], source: str, **context: Any) -> tuple[str, Any, tuple[str, ...]]:
    """(name, settings, objectives) of the scenario the study file chooses (``tuner/scenarios``)."""
    room = scenario_for_doc(doc, source)
    settings = room.parse(doc.get(room.section) if room.section else None, doc, source)
    objectives = room.objectives(settings, doc, source)
    room.check(settings, source=source, **context)
    return room.name, settings, objectives


def _common(doc: Mapping[str, Any], path: Path, source: str, gait: str) -> tuple:
    """The keys every study reads the same way (surfaces .. description)."""
    if "surfaces" not in doc:
        fail(source, "missing 'surfaces': name the surfaces to tune on, e.g. surfaces: [grass50] "
                      "(`gait-tuner surfaces` lists them)")
    surfaces = doc["surfaces"]
    if isinstance(surfaces, str):
        surfaces = [surfaces]
    if not isinstance(surfaces, list) or not surfaces:
        fail(source, "surfaces must be a list of surface names or files")
    for s in surfaces:
        if not isinstance(s, str):
            fail(source, f"surfaces: {s!r} is not a surface name or file")
        if s not in SURFACES:
            try:
                load_surface(str(s))
            except UserError as exc:
                fail(source, f"surfaces: {exc}")
    aggregate = doc.get("aggregate", "worst")
    if aggregate not in ("worst", "mean"):
        fail(source, f"aggregate must be worst or mean, got {aggregate!r}")
    trials = doc.get("trials", 60)
    if not isinstance(trials, int) or isinstance(trials, bool) or not 1 <= trials <= 100_000:
        fail(source, f"trials must be an integer in [1, 100000], got {trials!r}")
    duration = doc.get("duration")
    if duration is not None and (not isinstance(duration, (int, float)) or isinstance(duration, bool)
                                 or not 0 < duration <= MAX_DURATION_S):
        fail(source, f"duration must be a number of seconds in (0, {MAX_DURATION_S:g}] or null, "
                      f"got {duration!r}")
    enqueue = doc.get("enqueue", ["casadi", "baselines"])
    if not isinstance(enqueue, list) or any(e not in ("casadi", "baselines") for e in enqueue):
        fail(source, f"enqueue must list casadi and/or baselines, got {enqueue!r}")
    seed = doc.get("sampler_seed", 0)
    if not isinstance(seed, int) or isinstance(seed, bool):
        fail(source, f"sampler_seed must be an integer, got {seed!r}")
    if not 0 <= seed <= MAX_SEED:
        fail(source, f"sampler_seed = {seed}: allowed 0 to {MAX_SEED} (the sampler's seed range)")
    name = doc.get("name") or path.stem
    if not isinstance(name, str) or not NAME_PATTERN.fullmatch(name):
        fail(source, f"name must be letters, digits, '.', '_' or '-' (at most 100, no path), "
                      f"got {name!r}")
    description = doc.get("description") or ""
    if not isinstance(description, str):
        fail(source, f"description must be text, got {type(description).__name__}")
    return surfaces, aggregate, trials, duration, enqueue, seed, name, description


def _user_study(doc: Mapping[str, Any], path: Path, source: str) -> "StudySpec":
    """A study of a controller of the user's own (its file imported here, once)."""
    from ..controllers import load_controller
    for key in ("gait", "base", "fixed", "baselines"):
        if key in doc:
            fail(source, f"{key!r} does not go with 'controller': the controller's file holds its parameters")
    ref = doc["controller"]
    if not isinstance(ref, str):
        fail(source, f"controller = {ref!r}: expected the path of a controller YAML")
    cpath = Path(ref) if Path(ref).is_absolute() else path.parent / ref
    try:
        user = load_controller(cpath)
    except UserError as exc:
        fail(source, f"controller: {exc}")
    stabiliser = _study_stabiliser(doc.get("stabiliser"), source)
    space_doc = doc.get("space")
    if space_doc is None:
        space_doc = {CTRL_PREFIX + k: {"low": lo, "high": hi} for k, (lo, hi) in user.ranges.items()}
    if not isinstance(space_doc, Mapping) or not space_doc:
        fail(source, "space must map at least one controller.NAME to {low, high} (or the controller's "
                      "file must declare ranges)")
    space = []
    for name, rng in space_doc.items():
        if isinstance(name, str) and name.startswith(STAB_PREFIX):
            space.append(_stabiliser_range(name, rng, stabiliser, source))
            continue
        field_name = name[len(CTRL_PREFIX):] if isinstance(name, str) and name.startswith(CTRL_PREFIX) else None
        if field_name not in user.params:
            fail(source, f"space: {name!r} is not controller.NAME of one of the controller's parameters "
                          f"({', '.join(user.params) or 'none'})")
        low, high, log = _range_bounds(name, rng, source)
        if field_name in user.ranges:
            lo, hi = user.ranges[field_name]
            if low < lo or high > hi:
                fail(source, f"space: {name} range [{low}, {high}] leaves the controller's range [{lo}, {hi}]")
        space.append(ParamRange(name, float(low), float(high), log, False, "-"))
    enqueue_doc = doc.get("enqueue", ["baselines"])
    if not isinstance(enqueue_doc, list) or any(e != "baselines" for e in enqueue_doc):
        fail(source, f"enqueue: a controller study can enqueue [baselines] (its file's values) only, got {enqueue_doc!r}")
    doc = {**doc, "enqueue": enqueue_doc,
           "duration": USER_DURATION_S if doc.get("duration") is None else doc["duration"]}
    c = _common(doc, path, source, "user")
    surfaces, aggregate, trials, duration, enqueue, seed, name, description = c
    kind, settings, objectives = _scenario(doc, source, gait="user", engine=None, controller=user)
    robot = _study_robot(doc.get("robot", "kidsize"), path, source)
    return StudySpec(name=name, gait="user", base=None, space=tuple(space), surfaces=tuple(surfaces),
                     robot=str(robot), aggregate=aggregate, objectives=tuple(objectives), trials=trials,
                     duration=duration, enqueue=tuple(enqueue), sampler_seed=seed, description=description,
                     source=source, stabiliser=stabiliser, controller=user, kind=kind, settings=settings)


def _study_engine(doc: Any, gait: str, source: str) -> Any:
    if doc is None:
        return None
    from gaits.gait_file import engine_from_mapping
    if family(gait).engine != "feedback":
        fail(source, f"engine: the walk engine plans TLIPFM steps, not {gait!r}")
    try:
        return engine_from_mapping({} if doc is True else doc, "engine")
    except ParamError as exc:
        fail(source, str(exc))


def _engine_range(name: str, rng: Any, engine: Any, source: str) -> ParamRange:
    from gaits.engine import EngineParams
    field_name = name[len(ENGINE_PREFIX):]
    if engine is None:
        fail(source, f"space: {name!r} needs an engine: section (e.g. engine: {{}})")
    rows = {r["name"]: r for r in EngineParams.field_table()}
    numeric = {f.name for f in fields(EngineParams) if isinstance(f.default, (int, float)) and not isinstance(f.default, bool)}
    if field_name not in numeric:
        fail(source, f"space: unknown or non-numeric engine field {field_name!r} (numeric: {', '.join(sorted(numeric))})")
    low, high, log = _range_bounds(name, rng, source)
    meta = next(f.metadata for f in fields(EngineParams) if f.name == field_name)
    if low < meta["lo"] or high > meta["hi"]:
        fail(source, f"space: {name} range [{low}, {high}] leaves the allowed range [{meta['lo']}, {meta['hi']}] "
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
        fail(source, str(exc))


def _range_bounds(name: str, rng: Any, source: str) -> tuple[float, float, bool]:
    """(low, high, log) of a space entry {low, high, log}: a mapping of those keys, a boolean
    log flag, finite numbers with low < high, low > 0 when log-scaled; else one line naming it."""
    if not isinstance(rng, Mapping) or not {"low", "high"} <= set(rng) or not set(rng) <= {"low", "high", "log"}:
        fail(source, f"space: {name} must be {{low: ..., high: ..., log: false}}")
    low, high, log = rng["low"], rng["high"], rng.get("log", False)
    if not isinstance(log, bool):
        fail(source, f"space: {name}.log must be true or false, got {log!r}")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (low, high)):
        fail(source, f"space: {name} bounds must be numbers, got {low!r}, {high!r}")
    if not all(math.isfinite(v) for v in (low, high)):
        fail(source, f"space: {name} bounds must be finite, got {low!r}, {high!r}")
    if not low < high:
        fail(source, f"space: {name} bounds reversed or empty: low = {low}, high = {high}")
    if log and low <= 0:
        fail(source, f"space: {name} is log-scaled, so low must be > 0 (got {low})")
    return low, high, log


def _stabiliser_range(name: str, rng: Any, stabiliser: Any, source: str) -> ParamRange:
    from gaits.imu_stabiliser import _RANGES
    field_name = name[len(STAB_PREFIX):]
    if stabiliser is None:
        fail(source, f"space: {name!r} needs a stabiliser: section (e.g. stabiliser: {{enabled: true}})")
    if field_name not in _RANGES:
        fail(source, f"space: unknown stabiliser gain {field_name!r} (allowed: {', '.join(_RANGES)})")
    low, high, log = _range_bounds(name, rng, source)
    lo, hi, unit = _RANGES[field_name]
    if low < lo or high > hi:
        fail(source, f"space: {name} range [{low}, {high}] leaves the allowed range [{lo}, {hi}] {unit}")
    return ParamRange(name, float(low), float(high), log, False, unit)
