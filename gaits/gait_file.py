"""Gait parameter files: ``{gait: FAMILY, description: ..., params: {...}, stabiliser: {...}, engine: {...},
residual: {...}}``.

The boundary between a user's files and the typed parameters of ``gaits/params.py`` and the
IMU stabiliser's gains (``gaits/imu_stabiliser.py``) and the online walk engine's numbers
(``gaits/engine/``; a set with an ``engine:`` section walks online) and the residual trained on its leg
targets (``gaits/engine/residual.py``; with the engine only): :func:`load_gait_file` validates a file
(every error names the file, the field, the value and the allowed range), :func:`save_gait_file`
writes one it reads back identically.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import re

import yaml

from .files import MAX_BYTES, complete_pending_writes, read_bytes_checked, write_text_atomic
from .engine import EngineParams, ResidualParams, residual_from_mapping
from .engine.residual import FEATURES, LEG_JOINTS
from .imu_stabiliser import StabiliserParams, stabiliser_from_mapping
from .families import families, family_class, params_from_mapping
from .families import family as _family
from .params import GaitParams, ParamError, fields_from_mapping

__all__ = ["GaitFile", "read_yaml", "load_gait_file", "gait_file_from_mapping", "save_gait_file", "gait_file_text",
           "engine_from_mapping"]


@dataclass(frozen=True)
class GaitFile:
    """A parameter file: the family, its parameters and free text saying where they come from."""

    params: GaitParams
    description: str = ""
    stabiliser: StabiliserParams | None = None     # the IMU stabiliser, or None (open loop)
    engine: EngineParams | None = None             # the online walk engine, or None (a joint table)
    residual: ResidualParams | None = None         # a correction on the engine's leg targets, or None

    @property
    def family(self) -> str:
        return self.params.FAMILY


_TOP_KEYS = ("gait", "description", "params", "stabiliser", "engine", "residual")


class DuplicateKey(yaml.YAMLError):
    def __init__(self, key, where: str) -> None:
        super().__init__(f"duplicate key {key!r}")
        self.key, self.where = key, where


#: PyYAML's safe loader on libyaml's C parser where PyYAML was built with it (its wheels are): the
#: pure-Python scanner's cost grows with the square of a file's flow nesting (a hostile 10 kB file took
#: 2-4 s to refuse) and it read the shipped studies and sets at 7.6 ms a file against libyaml's 0.9 ms.
#: Both read the same documents; libyaml refuses nesting beyond 1000 levels itself.
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _StrictLoader(_SAFE_LOADER):
    """PyYAML's safe loader, except that a mapping naming a key twice is an error (PyYAML keeps the
    last one silently)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            if key_node.tag == "tag:yaml.org,2002:merge":
                continue                            # a merge (<<) may be overridden by the mapping's own keys
            key = self.construct_object(key_node, deep=deep)
            try:
                dup = key in seen
            except TypeError:
                dup = False
            if dup:
                m = key_node.start_mark
                raise DuplicateKey(key, f" (line {m.line + 1})")
            try:
                seen.add(key)
            except TypeError:
                pass
        return super().construct_mapping(node, deep=deep)


# YAML 1.1 (PyYAML) reads 2.2e7 or 1e-3 as strings: a float needs a dot there. Physical numbers are
# written so (a stiffness of 2.2e7 N/m^3), so ours reads them as YAML 1.2 does: as numbers.
_StrictLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
                 |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
                 |\.[0-9_]+(?:[eE][-+]?[0-9]+)?
                 |[-+]?\.(?:inf|Inf|INF)
                 |\.(?:nan|NaN|NAN))$""", re.X),
    list("-+0123456789."))


def read_yaml(path: str | Path, what: str, error: type[Exception] = ParamError) -> Any:
    """The parsed document of a user's YAML file; every way it can be wrong is one ``error``
    naming the file: a missing file, anything but a regular file of at most 1 MB
    (:func:`gaits.files.read_bytes_checked`), binary or non-UTF-8 content, YAML syntax, and
    nesting deep enough to exhaust the parser. ``what`` names the kind of file in messages."""
    path = Path(path)
    raw = read_bytes_checked(path, what, MAX_BYTES["yaml"], error)
    if b"\x00" in raw:
        raise error(f"{path}: is a binary file, expected a {what} YAML file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: is not UTF-8 text (byte {exc.start})") from None
    try:
        return yaml.load(text, Loader=_StrictLoader)
    except DuplicateKey as exc:
        raise error(f"{path}: key {exc.key!r} appears twice{exc.where}: a {what} file names each key once") from None
    except yaml.YAMLError as exc:
        if "nesting depth" in str(getattr(exc, "problem", "")):
            raise error(f"{path}: nested too deeply to be a {what} file") from None
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise error(f"{path}: not valid YAML{where}") from None
    except RecursionError:
        raise error(f"{path}: nested too deeply to be a {what} file") from None


def load_gait_file(path: str | Path) -> GaitFile:
    """Read and validate a ``{gait, description, params}`` YAML file."""
    path = Path(path)
    complete_pending_writes(path.parent)          # a group write killed after its commit: finish it first
    return gait_file_from_mapping(read_yaml(path, "parameter"), str(path))


def gait_file_from_mapping(doc: Any, source: str) -> GaitFile:
    """A parameter file's document (as :func:`read_yaml` gives it) validated; ``source`` names it
    in every message."""
    if not isinstance(doc, Mapping):
        raise ParamError(f"{source}: expected a mapping with keys {', '.join(_TOP_KEYS)}")
    for key in doc:
        if key not in _TOP_KEYS:
            raise ParamError(f"{source}: unknown top-level key {key!r} "
                             f"(allowed: {', '.join(_TOP_KEYS)})")
    if "gait" not in doc:
        raise ParamError(f"{source}: missing 'gait' (one of {', '.join(families())})")
    family = doc["gait"]
    if not isinstance(family, str):
        raise ParamError(f"{source}: 'gait' must be a family name, got {family!r}")
    try:
        family_class(family)
    except ParamError as exc:
        raise ParamError(f"{source}: {exc}") from None
    description = doc.get("description") or ""
    if not isinstance(description, str):
        raise ParamError(f"{source}: 'description' must be text")
    stabiliser = None
    if doc.get("stabiliser") is not None:
        stabiliser = stabiliser_from_mapping(doc["stabiliser"], f"{source}: stabiliser")
    engine = None
    if doc.get("engine") is not None:
        engine = engine_from_mapping(doc["engine"], f"{source}: engine")
    residual = None
    if doc.get("residual") is not None:
        if engine is None or _family(family).engine != "feedback":
            raise ParamError(f"{source}: residual: a correction on the online walk engine's targets needs an "
                             f"engine: section and the tlipfm family (this set has "
                             f"{'no engine' if engine is None else family})")
        residual = residual_from_mapping(doc["residual"], f"{source}: residual")
    return GaitFile(params_from_mapping(family, doc.get("params"), source), description, stabiliser, engine, residual)


def engine_from_mapping(doc: Any, source: str = "engine") -> EngineParams:
    """A validated :class:`EngineParams` from a YAML mapping (missing fields take their defaults)."""
    return fields_from_mapping(EngineParams, doc, source, tuple(f["name"] for f in EngineParams.field_table()),
                               expected="the engine's fields (see gaits/engine/)")


def save_gait_file(path: str | Path, params: GaitParams, description: str = "",
                   stabiliser: StabiliserParams | None = None, engine: EngineParams | None = None,
                   residual: ResidualParams | None = None) -> Path:
    """Write a parameter file that :func:`load_gait_file` reads back identically (:func:`gait_file_text`)."""
    return write_text_atomic(Path(path), gait_file_text(params, description, stabiliser, engine, residual))


def gait_file_text(params: GaitParams, description: str = "", stabiliser: StabiliserParams | None = None,
                   engine: EngineParams | None = None, residual: ResidualParams | None = None) -> str:
    """A parameter file's text. Each value carries its unit and meaning as a YAML comment; the IMU
    stabiliser's gains (``gaits/imu_stabiliser.py`` gives the formula) follow when one is given."""
    lines = [f"gait: {params.FAMILY}"]
    if description:
        lines.append("description: " + yaml.safe_dump(description, default_style='"',
                                                       width=10_000).strip())
    lines.append("params:")
    lines += _fields(params)
    if stabiliser is not None:
        lines.append("stabiliser:  # IMU feedback, ours: see gaits/imu_stabiliser.py for the formula")
        for name, value in stabiliser.to_mapping().items():
            text = yaml.safe_dump(value, default_flow_style=True).strip().split("\n")[0]
            lines.append(f"  {name}: {text}")
    if engine is not None:
        lines.append("engine:  # the online walk engine, ours: see gaits/engine/")
        lines += _fields(engine)
    if residual is not None:
        lines.append("residual:  # a correction on the engine's leg targets, trained (ours): see gaits/engine/residual.py")
        lines.append(f"  limit: {residual.limit!r}  # [rad] the most a correction moves a joint")
        for role in ("stance", "swing"):
            lines.append(f"  {role}:  # rows {', '.join(LEG_JOINTS)}; columns {', '.join(FEATURES)} "
                         f"[rad per unit feature]")
            for row in getattr(residual, role):
                lines.append("  - [" + ", ".join(repr(v) for v in row) + "]")
    return "\n".join(lines) + "\n"


def _fields(params: GaitParams) -> list[str]:
    """One commented YAML line per field: value, unit, meaning, the paper's symbol."""
    lines = []
    for row in params.field_table():
        value = getattr(params, row["name"])
        text = yaml.safe_dump(value, default_flow_style=True).strip()
        if text.endswith("\n...") or text.endswith("..."):
            text = text.split("\n")[0]
        paper = f" ({row['paper']})" if row["paper"] else ""
        unit = f"[{row['unit']}] " if row["unit"] and row["unit"] != "-" else ""
        lines.append(f"  {row['name']}: {text}  # {unit}{row['doc']}{paper}")
    return lines
