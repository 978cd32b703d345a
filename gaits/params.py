"""Typed, validated gait parameters with units, bounds and paper names.

Every gait family has a frozen dataclass of parameters (``ErosParams``,
``TlipfmParams``, ``CosineLawParams``). Each field is declared with
:func:`param`, which records its SI unit, its allowed range, a one-line
description and the symbol the source paper uses for it. Validation runs in
``__post_init__``, so a parameter set that exists is a valid one, whether it was
read from YAML, built by hand or sampled by an optimiser.

YAML is only the boundary: ``gaits/gait_file.py`` reads and writes
``{gait: FAMILY, params: {...}, stabiliser: {...}}`` files, and every error names
the file, the field, the value and the allowed range.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Mapping

__all__ = [
    "fields_from_mapping",
    "ParamError",
    "GaitParams",
    "param",
    "register_family",
    "families",
    "family_class",
    "params_from_mapping",
]


class ParamError(ValueError):
    """A parameter set or file is malformed; the message names what and where."""


def param(default: Any, unit: str, lo: float | None = None, hi: float | None = None,
          doc: str = "", paper: str | None = None,
          choices: tuple[Any, ...] | None = None) -> Any:
    """Declare a gait parameter: default, SI unit, inclusive bounds, doc, paper symbol."""
    return field(default=default, metadata={
        "unit": unit, "lo": lo, "hi": hi, "doc": doc, "paper": paper, "choices": choices})


def _kind(default: Any) -> str:
    if isinstance(default, bool):
        return "bool"
    if isinstance(default, int):
        return "int"
    if isinstance(default, float):
        return "float"
    if isinstance(default, str):
        return "str"
    raise TypeError(f"unsupported parameter default {default!r}")


def _range_text(meta: Mapping[str, Any]) -> str:
    if meta["choices"] is not None:
        return "one of " + ", ".join(repr(c) for c in meta["choices"])
    if meta["lo"] is None:
        return "true or false"
    return f"[{meta['lo']:g}, {meta['hi']:g}] {meta['unit']}".rstrip()


@dataclass(frozen=True)
class GaitParams:
    """Base class: field checks (type, range, choices) and the family's own consistency rules."""

    FAMILY: ClassVar[str] = ""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            meta = f.metadata
            kind = _kind(f.default)
            where = f"{self.FAMILY}.{f.name}"
            if kind == "float":
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    raise ParamError(f"{where} must be a number in {_range_text(meta)}, "
                                     f"got {type(value).__name__} {value!r}")
                if not math.isfinite(value):
                    raise ParamError(f"{where} must be finite, got {value!r}")
                object.__setattr__(self, f.name, float(value))
            elif kind == "int":
                if isinstance(value, bool) or not isinstance(value, int):
                    raise ParamError(f"{where} must be an integer in {_range_text(meta)}, "
                                     f"got {type(value).__name__} {value!r}")
            elif kind == "bool":
                if not isinstance(value, bool):
                    raise ParamError(f"{where} must be true or false, "
                                     f"got {type(value).__name__} {value!r}")
            elif kind == "str":
                if not isinstance(value, str):
                    raise ParamError(f"{where} must be a string ({_range_text(meta)}), "
                                     f"got {type(value).__name__} {value!r}")
            if meta["choices"] is not None:
                if value not in meta["choices"]:
                    raise ParamError(f"{where} = {value!r} is not allowed: "
                                     f"expected {_range_text(meta)}")
            elif kind in ("float", "int"):
                lo, hi = meta["lo"], meta["hi"]
                if not (lo <= value <= hi):
                    raise ParamError(f"{where} = {value:g} {meta['unit']} is out of range "
                                     f"{_range_text(meta)}")
        self.check_consistency()

    def check_consistency(self) -> None:
        """Cross-field rules of the family; raise :class:`ParamError` naming the fields."""

    # --- introspection -------------------------------------------------------
    @classmethod
    def field_table(cls) -> list[dict[str, Any]]:
        """One row per field: name, default, unit, range, paper symbol, doc."""
        rows = []
        for f in fields(cls):
            m = f.metadata
            rows.append({"name": f.name, "default": f.default, "unit": m["unit"],
                         "range": _range_text(m), "paper": m["paper"], "doc": m["doc"]})
        return rows

    def to_mapping(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def replace(self, **changes: Any) -> "GaitParams":
        """A copy with some fields changed (validated again)."""
        return dataclasses.replace(self, **changes)


_FAMILIES: dict[str, type[GaitParams]] = {}


def register_family(cls: type[GaitParams]) -> type[GaitParams]:
    """Class decorator: make a parameter class loadable by its ``FAMILY`` name."""
    _FAMILIES[cls.FAMILY] = cls
    return cls


def families() -> tuple[str, ...]:
    """Names of the registered gait families."""
    return tuple(sorted(_FAMILIES))


def family_class(name: str) -> type[GaitParams]:
    try:
        return _FAMILIES[name]
    except KeyError:
        raise ParamError(f"unknown gait family {name!r}: expected one of "
                         f"{', '.join(families())}") from None


def fields_from_mapping(cls: type, doc: Any, source: str, allowed: tuple[str, ...] | None = None,
                        error: type[Exception] = ParamError, expected: str = "") -> Any:
    """``cls(**doc)`` for a YAML section of a dataclass's fields (missing ones take their defaults):
    not a mapping, an unknown field (the allowed ones listed) or a value ``cls`` refuses is one
    ``error`` prefixed with ``source``. ``allowed``: the field names (default: the dataclass's);
    ``expected``: what the section is, said when it is not a mapping (default: the field list)."""
    names = tuple(f.name for f in fields(cls)) if allowed is None else tuple(allowed)
    if not isinstance(doc, Mapping):
        raise error(f"{source}: expected a mapping of {expected or ', '.join(names)}")
    for k in doc:
        if k not in names:
            raise error(f"{source}: unknown field {k!r} (allowed: {', '.join(names)})")
    try:
        return cls(**dict(doc))
    except error as exc:
        raise error(f"{source}: {exc}") from None


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
