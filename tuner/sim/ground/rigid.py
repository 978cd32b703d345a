"""The rigid floor: the soil plane alone (``layer_height`` = 0)."""

from __future__ import annotations

from ..surfaces import Surface
from .kind import GroundKind, register_kind

__all__ = ["Rigid"]


@register_kind
class Rigid(GroundKind):
    """A hard floor: MuJoCo's contact with the soil plane, nothing between two ticks (the base)."""

    name = "rigid"
    fields = ("friction",)

    @classmethod
    def claims(cls, surface: Surface) -> bool:
        return surface.layer_height == 0.0
