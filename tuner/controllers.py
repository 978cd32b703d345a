"""Bring your own controller: a controller class of a team's own, named in a YAML file.

A controller file says which class to run and with which parameters::

    class: march.py:MarchInPlace    # a .py file (relative to this YAML) and a class in it,
                                    # or module:Class on the Python path
    description: free text
    params:                         # the values the class is built with: cls(params, robot, dt)
      period: 0.5
      lift: 0.03
    ranges:                         # optional: the search range of each tunable parameter
      period: {low: 0.35, high: 0.9}
    time_limit: {tick: 1.0, walk: 600, import: 30}   # optional [s], these are the defaults

The class implements ``gaits.control.Controller`` (``dt``, ``duration``, ``start_pose``, ``reset``,
``step``, ``plan``); ``examples/controllers/`` has one. **Naming a controller file runs its code**,
in every process of a study (``tune`` and ``worker`` say which file they import). Every mistake
in the file, and any exception its import raises (or a ``sys.exit`` in it), is one line naming the
file. Its code runs under time limits (``time_limit:``, :class:`gaits.drive.TimeLimits`): one call
(``start_pose``, ``reset``, ``step``, ``plan``), one walk's calls together, its import; a call past
its limit is stopped and named in one line.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import sys
from pathlib import Path
from typing import Any, Mapping

from gaits import UserController
from gaits.drive import TimeLimits, time_limit
from gaits.files import write_text_atomic
from gaits.policy import POLICY_FILE_KEYS as _POLICY_KEYS

from .errors import UserError
from .yaml_input import read_yaml_file

__all__ = ["load_controller", "import_class", "save_controller"]

_KEYS = ("class", "description", "params", "ranges", "time_limit")
#: [s] the bounds of each time limit a controller file may set
_LIMIT_RANGES = {"tick": (0.01, 60.0), "walk": (1.0, 86400.0), "import": (1.0, 3600.0)}


def import_class(spec: str, relative_to: Path, source: str, seconds: float | None = None) -> tuple[Any, str]:
    """(class, where it came from) of ``path.py:Class`` (relative to ``relative_to``) or ``module:Class``;
    the import runs for at most ``seconds``."""
    def expired() -> UserError:
        return UserError(f"{source}: importing {spec.split(':')[0]} ran past its limit of {seconds:g} s "
                         f"(time_limit.import in the file) and was stopped")
    if not isinstance(spec, str) or spec.count(":") != 1 or not all(spec.split(":")):
        raise UserError(f"{source}: class = {spec!r}: expected path/to/file.py:ClassName or module:ClassName")
    where, name = spec.split(":")
    try:
        if where.endswith(".py"):
            path = Path(where)
            path = (path if path.is_absolute() else relative_to / path).resolve()
            if not path.is_file():
                raise UserError(f"{source}: class {spec!r}: no such file {path}")
            mod_name = f"gait_tuner_user_{abs(hash(str(path)))}"
            module = sys.modules.get(mod_name)
            if module is None:
                loader_spec = importlib.util.spec_from_file_location(mod_name, path)
                module = importlib.util.module_from_spec(loader_spec)
                sys.modules[mod_name] = module
                try:
                    with time_limit(seconds, expired):
                        loader_spec.loader.exec_module(module)
                except BaseException:
                    del sys.modules[mod_name]
                    raise
            origin = str(path)
        else:
            with time_limit(seconds, expired):
                module = importlib.import_module(where)
            origin = getattr(module, "__file__", where) or where
    except UserError:
        raise
    except SystemExit as exc:     # sys.exit() in its module: one line, not the code's exit status
        raise UserError(f"{source}: importing {where} called sys.exit({exc.code!r})") from None
    except Exception as exc:  # noqa: BLE001 - the user's code may raise anything on import
        raise UserError(f"{source}: importing {where} failed: {type(exc).__name__}: "
                        f"{' '.join(str(exc).split())}") from None
    cls = getattr(module, name, None)
    if cls is None or not callable(cls):
        raise UserError(f"{source}: {where} has no class {name!r}")
    return cls, f"{origin}:{name}"


def _number(value: Any, what: str, source: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise UserError(f"{source}: {what} = {value!r}: expected a finite number")
    return float(value)


def load_controller(path: str | Path) -> UserController:
    """The controller a YAML file names, its class imported (see the module docstring)."""
    path = Path(path)
    source = str(path)
    doc = read_yaml_file(path, "controller")
    if not isinstance(doc, Mapping):
        raise UserError(f"{source}: expected a mapping with keys {', '.join(_KEYS)}")
    if "policy" in doc:
        return _load_policy(doc, path)
    if "placo" in doc:
        return _load_placo(doc, path)
    for k in doc:
        if k not in _KEYS:
            raise UserError(f"{source}: unknown key {k!r} (allowed: {', '.join(_KEYS)})")
    if "class" not in doc:
        raise UserError(f"{source}: missing 'class' (path/to/file.py:ClassName or module:ClassName)")
    params, ranges = _params_and_ranges(doc, source)
    limits = _limits(doc.get("time_limit"), source)
    cls, origin = import_class(doc["class"], path.parent, source, limits.import_)
    return UserController(cls, params, origin, ranges, limits)


def _params_and_ranges(doc: Mapping, source: str, known: Mapping[str, float] | None = None
                       ) -> tuple[dict[str, float], dict[str, tuple[float, float]]]:
    """A controller file's ``params:`` (name: number; ``known``: only these names, their values the
    defaults) and ``ranges:`` (name: {low, high}, each holding its value)."""
    params_doc = doc.get("params") or {}
    if not isinstance(params_doc, Mapping):
        raise UserError(f"{source}: params must be a mapping of name: number")
    params = {str(k): _number(v, f"params.{k}", source) for k, v in params_doc.items()}
    if known is not None:
        for k in params:
            if k not in known:
                raise UserError(f"{source}: params.{k}: not tunable (a policy's: {', '.join(known) or 'none'})")
        params = {**known, **params}
    ranges_doc = doc.get("ranges") or {}
    if not isinstance(ranges_doc, Mapping):
        raise UserError(f"{source}: ranges must map parameter names to {{low, high}}")
    ranges = {}
    for k, r in ranges_doc.items():
        if k not in params:
            raise UserError(f"{source}: ranges.{k}: not one of the params ({', '.join(params) or 'none'})")
        if not isinstance(r, Mapping) or set(r) != {"low", "high"}:
            raise UserError(f"{source}: ranges.{k} must be {{low: ..., high: ...}}")
        low, high = _number(r["low"], f"ranges.{k}.low", source), _number(r["high"], f"ranges.{k}.high", source)
        if not low < high:
            raise UserError(f"{source}: ranges.{k}: low = {low:g} must be below high = {high:g}")
        if not low <= params[k] <= high:
            raise UserError(f"{source}: params.{k} = {params[k]:g} lies outside its range [{low:g}, {high:g}]")
        ranges[str(k)] = (low, high)
    return params, ranges


def _section(doc: Mapping, keys: tuple[str, ...], what: str, read: Any, source: str) -> Any:
    """A file kind's own section (its first key) read by ``read(section, source)``, after its keys
    are checked; a ``ParamError`` becomes the one line of a ``UserError``."""
    from gaits import ParamError
    for k in doc:
        if k not in keys:
            raise UserError(f"{source}: unknown key {k!r} in {what} (allowed: {', '.join(keys)})")
    try:
        return read(doc[keys[0]], source)
    except ParamError as exc:
        raise UserError(str(exc)) from None


def _load_policy(doc: Mapping, path: Path) -> UserController:
    """A policy file (``gaits/policy.py``): its spec checked, its model opened and checked against
    it, as a controller whose parameters are what the spec lets a study tune."""
    from gaits import ParamError
    from gaits.policy import PolicyFactory, check_sizes, policy_from_mapping
    source = str(path)
    spec = _section(doc, _POLICY_KEYS, "a policy file", policy_from_mapping, source)
    model = Path(spec.model)
    model = (model if model.is_absolute() else path.parent / model).resolve()
    if not model.is_file():
        raise UserError(f"{source}: policy.model: no such file {model}")
    params, ranges = _params_and_ranges(doc, source, known=spec.tunables())
    factory = PolicyFactory(spec, str(model), source)
    try:
        _, n_in, n_out = factory.runner()
        check_sizes(spec, n_in, n_out, source)
    except ParamError as exc:
        raise UserError(str(exc)) from None
    return UserController(factory, params, source, ranges, _limits(doc.get("time_limit"), source))


def _limits(doc: Any, source: str) -> TimeLimits:
    """The file's ``time_limit:`` section (each in its range [s]); the defaults where it says none."""
    if doc is None:
        return TimeLimits()
    if not isinstance(doc, Mapping):
        raise UserError(f"{source}: time_limit must be a mapping of {', '.join(_LIMIT_RANGES)} [s]")
    values = {}
    for k, v in doc.items():
        if k not in _LIMIT_RANGES:
            raise UserError(f"{source}: time_limit: unknown key {k!r} (allowed: {', '.join(_LIMIT_RANGES)})")
        lo, hi = _LIMIT_RANGES[k]
        v = _number(v, f"time_limit.{k}", source)
        if not lo <= v <= hi:
            raise UserError(f"{source}: time_limit.{k} = {v:g}: expected a number in [{lo:g}, {hi:g}] s")
        values["import_" if k == "import" else k] = v
    return TimeLimits(**values)


def save_controller(path: str | Path, user: UserController, description: str = "") -> Path:
    """Write a controller file that :func:`load_controller` reads back: the class (absolute path),
    the parameter values and the ranges."""
    import yaml
    path = Path(path)
    doc = {"class": user.source, "description": description,
           "params": {k: float(v) for k, v in user.params.items()},
           "ranges": {k: {"low": float(lo), "high": float(hi)} for k, (lo, hi) in user.ranges.items()}}
    if not description:
        del doc["description"]
    if user.limits != TimeLimits():
        doc["time_limit"] = {"tick": user.limits.tick, "walk": user.limits.walk, "import": user.limits.import_}
    write_text_atomic(path, "# a controller of your own (tuner/controllers.py); naming this file runs its "
                            "class's code\n" + yaml.safe_dump(doc, sort_keys=False))
    return path


_PLACO_KEYS = ("placo", "description", "ranges", "time_limit")


def _load_placo(doc: Mapping, path: Path) -> UserController:
    """A placo file (``tuner/placo_walk.py``): placo's walk as a controller whose parameters are its
    ``placo:`` section (a study searches those with ``ranges:``)."""
    from .placo_walk import PlacoFactory, placo_params
    source = str(path)
    params = _section(doc, _PLACO_KEYS, "a placo file", placo_params, source)
    _, ranges = _params_and_ranges({"ranges": doc.get("ranges")}, source, known=params)
    limits = _limits(doc.get("time_limit"), source)
    if "time_limit" not in doc:              # placo reads the URDF and its meshes when it is built: seconds
        limits = TimeLimits(tick=30.0, walk=limits.walk, import_=limits.import_)
    return UserController(PlacoFactory(), params, source, ranges, limits)
