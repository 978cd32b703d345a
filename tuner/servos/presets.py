"""Named servo presets, read from ``presets.yaml`` (beside this file; each entry says its source).

A dc-motor preset holds the firmware's constants (the voltage it was measured at, the duty per
radian per P unit, the largest duty, a P register value) and one parameter set per friction form
(BAM's m1 ... m6); :func:`preset` gives one as a servo. A pd preset (``-pd``) is the law of rounds
one to four.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import yaml

from gaits import did_you_mean

from ..errors import UserError
from .law import LAWS, ServoLaw
from .motor import MotorServo

__all__ = ["preset", "preset_names", "preset_source", "PRESETS_FILE"]

PRESETS_FILE = Path(__file__).with_name("presets.yaml")


@lru_cache(maxsize=1)
def _table() -> dict[str, dict[str, Any]]:
    return yaml.safe_load(PRESETS_FILE.read_text(encoding="utf-8"))


def preset_names() -> tuple[str, ...]:
    return tuple(_table())


def preset_source(name: str) -> str:
    return " ".join(str(_table()[name]["source"]).split())


def friction_models(name: str) -> tuple[str, ...]:
    """The friction forms a dc-motor preset carries (empty for another law)."""
    return tuple(_table()[name].get("models", {}))


@lru_cache(maxsize=None)
def preset(name: str, friction_model: str | None = None) -> ServoLaw:
    """The preset ``name`` as a servo; a dc-motor preset in friction form ``friction_model``
    (default m1). Unknown names and forms are one line naming the allowed ones."""
    table = _table()
    if name not in table:
        raise UserError(f"preset = {name!r}: unknown{did_you_mean(name, table)} (allowed: {', '.join(table)})")
    entry = table[name]
    law = entry.get("law", MotorServo.law)
    if law != MotorServo.law:
        if friction_model not in (None, "m1"):
            raise UserError(f"friction_model = {friction_model!r}: preset {name!r} is a {law}-law servo, it has none")
        return LAWS[law](**entry["fields"])
    model = friction_model or "m1"
    models = entry["models"]
    if model not in models:
        raise UserError(f"friction_model = {model!r}: preset {name!r} has only {', '.join(models)} (the forms its "
                        f"source identified)")
    firmware = entry["firmware"]
    extra = {"profile_speed": entry["profile_speed"]} if "profile_speed" in entry else {}
    return MotorServo(preset=name, friction_model=model, voltage=firmware["voltage"],
                      error_gain=firmware["error_gain"], max_duty=firmware["max_duty"],
                      p_gain=firmware["p_gain"], **extra, **models[model])
