"""The rigid floor: the soil plane alone (``layer_height`` = 0), its friction the surface's ``friction``."""

from __future__ import annotations

import mujoco

from ..surfaces import Surface
from .kind import PREFIX, GroundKind, register_kind

__all__ = ["Rigid"]


@register_kind
class Rigid(GroundKind):
    """A hard floor: MuJoCo's contact with the soil plane, nothing between two ticks (the base)."""

    name = "rigid"
    fields = ("friction",)

    @classmethod
    def claims(cls, surface: Surface) -> bool:
        return surface.layer_height == 0.0

    def add_geoms(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault) -> None:
        """The soil plane, its friction the surface's ``friction`` (the floor; ``soil_friction`` is
        the soil under a layer): what ``identify ground`` fits on a rigid floor."""
        super().add_geoms(spec, gt)
        spec.geom(PREFIX + "soil").friction = [self.surface.friction, 0.005, 0.0001]
