"""The contact layer: carpet or grass as a second plane at the soil's height whose contact margin is
the blade height (``tuner/sim/surfaces.py`` says what each field stands for), and the blades' drag
on each sole corner inside it.

A sole point less than ``layer_height`` above the soil is in contact with the layer, whose support
is soft (MuJoCo ``solref``/``solimp``: weak at the blade tips, stiffer deeper in). With ``drag`` > 0
every sole corner has two dampers (site transmission along world x and y): force = -drag * v *
gate, computed by MuJoCo every physics step and integrated implicitly (``implicitfast``), so it is
stable at any drag. The gate (:func:`drag_gate`) switches on the corners below the blade tips: in
MuJoCo's step (``native_step.c``) where that callback is installed, else once a control tick here.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..native_step import BLOCK as GATE_BLOCK
from ..native_step import arm as arm_native_gate
from ..native_step import disarm as disarm_native_gate
from ..native_step import install as install_native_gate
from ..surfaces import Surface
from .kind import PREFIX, GroundKind, register_kind

__all__ = ["ContactLayer", "drag_gate"]


def drag_gate(z: np.ndarray, layer_height: float, drag_depth: float = 0.0) -> np.ndarray:
    """The drag dampers' ctrl of points at heights ``z`` [m] above the soil: inside the layer 1, or
    with ``drag_depth`` > 0 the depth below the blade tips over ``drag_depth``, at most 1."""
    inside = z < layer_height
    if drag_depth <= 0.0:
        return inside.astype(float)
    return np.where(inside, np.minimum(1.0, (layer_height - z) / drag_depth), 0.0)


@register_kind
class ContactLayer(GroundKind):
    """Carpet or grass as a soft contact layer, with the blades' drag (module docstring)."""

    name = "layer"
    fields = ("layer_timeconst", "drag", "layer_dampratio", "friction")

    def __init__(self, surface: Surface) -> None:
        super().__init__(surface)
        #: whether MuJoCo's step gates the drag (``native_step.c``); :meth:`bind` decides
        self.native = False
        self._layer = -1

    @classmethod
    def claims(cls, surface: Surface) -> bool:
        return surface.layer_height > 0.0 and surface.blade_modulus == 0.0

    def fit_fields(self) -> tuple[str, ...]:
        return tuple(f for f in self.fields if f != "drag" or self.on_points)

    @property
    def on_points(self) -> bool:
        return self.surface.drag > 0.0

    @property
    def runs_in_step(self) -> bool:
        return self.on_points                           # the drag gate (native_step.c)

    @property
    def user_slots(self) -> int:
        return GATE_BLOCK if self.runs_in_step else 0    # the native gate's numbers

    def contact_geoms(self) -> tuple[str, ...]:
        return (PREFIX + "soil", PREFIX + "layer")

    def add_geoms(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault) -> None:
        super().add_geoms(spec, gt)
        s = self.surface
        layer = spec.worldbody.add_geom(default=gt, name=PREFIX + "layer", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                        size=[0, 0, 0.05])
        layer.margin = s.layer_height
        layer.friction = [s.friction, 0.005, 0.0001]
        layer.solref = [s.layer_timeconst, s.layer_dampratio]
        layer.solimp = [s.layer_dmin, s.layer_dmax, s.layer_height, 0.5, 2.0]
        layer.priority = 2
        layer.contype = 0
        layer.conaffinity = 1
        layer.group = 1
        layer.rgba = [0.2, 0.6, 0.2, 0.0]     # invisible: at the soil's height it would z-fight; the slab shows it
        self.add_slab(spec, gt)

    def add_point(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault, site: str, label: str) -> int:
        """The layer's drag on one point: a damper along world x and one along y, gated by ctrl."""
        ref = self.ref_site(spec, gt)
        for axis, gear in (("x", [1, 0, 0, 0, 0, 0]), ("y", [0, 1, 0, 0, 0, 0])):
            act = spec.add_actuator(default=gt, name=f"{PREFIX}drag/{label}_{axis}", target=site,
                                    refsite=ref, trntype=mujoco.mjtTrn.mjTRN_SITE)
            act.set_to_damper(kv=self.surface.drag)
            act.gear = gear
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [0.0, 1.0]
        return 2

    def bind(self, model: mujoco.MjModel, areas: np.ndarray, period: float, points=None, *,
             native: bool = False) -> None:
        """As the base; with ``native`` the drag is gated in MuJoCo's step when the callback can be
        installed (``native_step.py``)."""
        super().bind(model, areas, period, points)
        self._layer = model.geom(PREFIX + "layer").id
        self.native = bool(self.runs_in_step and native and install_native_gate())

    @property
    def python_tick(self) -> bool:
        return self.on_points and not self.native

    def arm(self, model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
        if self.native:           # MuJoCo gates the drag inside its steps from here on (native_step.c)
            arm_native_gate(model, data, height=self.layer_height, depth=self.surface.drag_depth, nstep=nstep,
                            first=self.first, n_points=len(self.site_ids))

    def disarm(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if self.native:
            disarm_native_gate(model, data)

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        # the corners' heights MuJoCo computed in the last step (what native_step.c reads)
        inside = drag_gate(data.site_xpos[self.site_ids, 2], self.layer_height, self.surface.drag_depth)
        data.ctrl[self.first:self.first + self.n_actuators] = np.repeat(inside, 2)      # x and y per corner

    def perturb(self, model: mujoco.MjModel, nominal: dict[str, np.ndarray], p: Any) -> None:
        """As the base, and the layer's height (its margin and where its support stiffens) and
        time constant by their factors."""
        super().perturb(model, nominal, p)
        g = self._layer
        self.layer_height = self.surface.layer_height * p.layer_height
        model.geom_margin[g] = nominal["geom_margin"][g] * p.layer_height
        model.geom_solimp[g, 2] = nominal["geom_solimp"][g, 2] * p.layer_height
        model.geom_solref[g, 0] = nominal["geom_solref"][g, 0] * p.layer_timeconst
