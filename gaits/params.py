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
import difflib
import math
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Iterable, Mapping

__all__ = [
    "did_you_mean",
    "fields_from_mapping",
    "ParamError",
    "GaitParams",
    "param",
]


class ParamError(ValueError):
    """A parameter set or file is malformed; the message names what and where."""


def did_you_mean(word: Any, choices: Iterable[str]) -> str:
    """``" (did you mean 'x'?)"`` for the choice closest to a mistyped ``word`` (difflib's ratio at
    least 0.6, case ignored), else ``""``: appended to a message that names an unknown name."""
    if not isinstance(word, str) or not word:
        return ""
    choices = [c for c in choices if isinstance(c, str)]
    by_lower = {c.lower(): c for c in choices}
    close = difflib.get_close_matches(word.lower(), list(by_lower), n=1, cutoff=0.6)
    return f" (did you mean {by_lower[close[0]]!r}?)" if close and by_lower[close[0]] != word else ""


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

