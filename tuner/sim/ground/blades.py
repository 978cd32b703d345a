"""The blade layer (ours): artificial grass as springs under each sole point, by pressure, in two
stages, with blades that hold a point where it entered until friction lets go.

Why (measured, docs/simulation.md "The turf test methods, simulated"): MuJoCo's soft contact, the
pedestals' layer, sets an *acceleration* stiffness, so a toe and a flat sole sink alike and a
layer soft enough to catch a toe holds one sole against rolling at under twice the robot's
m g h (19 N m/rad against 10.7): the full-lift EROS walk falls at its first step there. Turf
sinks by pressure, and its flexible blade tips stand over a stiff base of blades and infill: a
toe edge, carrying a landing on a fraction of the sole, goes through the tips to the base while
the heel still rides on them, and a flat stance sole, its weight shared, rests on the base.

The model, per sole point standing for ``area`` [m^2] of sole, with d its depth below the blade
tips (``layer_height`` above the soil) and v its velocity:

* support: F_z = k1 d while d < d1 (the tips: ``blade_tip_modulus`` x area, ``blade_tip_depth``),
  k1 d1 + k2 (d - d1) below (the base: ``blade_modulus`` x area), minus c v_z
  (``blade_damping`` x area); nothing above the tips; the soil (a MuJoCo contact) below;
* hold: where a point enters the blades it is held by a spring k_h (``blade_shear`` x area) to
  that place, its anchor, and damped by ``drag``; when the spring pulls harder than the layer's
  ``friction`` x the point's support, the anchor slides along (a bristle model of friction);
* a sole turning in the blades meets its points' holds and drag: a torque, as turf resists a
  turning boot;
* jam (with ``blade_jam_speed`` > 0): a point that enters the blades faster than that (downward,
  its mean speed over the control tick it entered in) is jammed where it entered: a vertical
  spring k_h to that height, beside its support, and the base's damping hold it there (it sinks
  no further than the spring lets it, and rises only against it) until the spring pulls it up
  harder than ``blade_jam_pressure`` x its area, or it leaves the blades; its hold lets go at
  friction x all of its support. This is the EROS paper's own
  account of its robot's falls on grass (Sec. V: "the toe of the foot was landed first, and it
  caused the toe stuck in the synthetic grass. The landing speed of steps are also makes toe
  stuck harder"), written as a mechanism; the speed at which a turf jams a sole is not in any
  source here (docs/simulation.md "A sole jammed by a fast landing").
* jam by sliding (with ``blade_jam_slide`` > 0; ours): a point that enters the blades moving
  horizontally faster than that (its mean horizontal speed over the tick it entered in: a toe
  dragged into the blades rather than set down in them) is jammed the same way. Either jam may be
  on, or both. docs/simulation.md "A sole jammed by a fast landing" says what each reproduces of the paper's
  tables and what neither does.

Each point has three site-transmission actuators with affine gains (``Blades.add_point``): MuJoCo
computes the forces every physics step, the damping implicitly (``implicitfast``); once per
control tick :class:`BladeLayer` switches on the points inside the layer, picks each point's
spring stage and moves the anchors (a few vector operations: no per-step Python). The surface
fields, units and bounds are in ``surfaces.py``; ``blade_modulus`` = 0 keeps the contact layer.
"""

from __future__ import annotations

from typing import Any

import mujoco
import numpy as np

from ..surfaces import Surface
from .kind import PREFIX, GroundKind, register_kind

__all__ = ["Blades", "BladeLayer", "BLADE_ACTUATORS"]

#: actuators per sole point: the support, then the hold along world x and along y
BLADE_ACTUATORS = 3


@register_kind
class Blades(GroundKind):
    """The blade layer as a kind of ground: no contact layer; three actuators on each sole point
    driven by :class:`BladeLayer` every control tick (module docstring)."""

    name = "blades"
    fields = ("blade_modulus", "blade_damping", "blade_shear", "friction")

    def __init__(self, surface: Surface) -> None:
        super().__init__(surface)
        self.layer: BladeLayer | None = None
        self.friction = surface.friction          # the blades' friction in the walk now

    @classmethod
    def claims(cls, surface: Surface) -> bool:
        return surface.blade_modulus > 0.0

    @property
    def on_points(self) -> bool:
        return True

    def add_geoms(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault) -> None:
        super().add_geoms(spec, gt)
        self.add_slab(spec, gt)

    def add_point(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault, site: str, label: str) -> int:
        """The three actuators on one sole point, in the order :class:`BladeLayer` drives them
        (gains set per tick)."""
        ref = self.ref_site(spec, gt)
        for axis, gear in (("z", [0, 0, 1, 0, 0, 0]), ("x", [1, 0, 0, 0, 0, 0]), ("y", [0, 1, 0, 0, 0, 0])):
            act = spec.add_actuator(default=gt, name=f"{PREFIX}blades/{label}_{axis}", target=site, refsite=ref,
                                    trntype=mujoco.mjtTrn.mjTRN_SITE)
            act.gear = gear
            act.gaintype = mujoco.mjtGain.mjGAIN_AFFINE
            act.gainprm[:3] = [0.0, 0.0, 0.0]
            act.biastype = mujoco.mjtBias.mjBIAS_NONE
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [0.0, 1.0]
        return BLADE_ACTUATORS

    def point_force(self, label: str) -> str | None:
        """The blades carry the sole without a contact: the point's support actuator's force."""
        return f"{PREFIX}blades/{label}_z"

    def bind(self, model: mujoco.MjModel, areas: np.ndarray, period: float, points=None, *,
             native: bool = False) -> None:
        super().bind(model, areas, period, points)
        self.layer = BladeLayer(self.surface, np.asarray(areas, dtype=float), self.first, period)

    @property
    def python_tick(self) -> bool:
        return True

    def reset(self) -> None:
        self.layer.reset()

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        self.layer.update(model, data, self._points(data), self.layer_height, self.friction)

    def perturb(self, model: mujoco.MjModel, nominal: dict[str, np.ndarray], p: Any) -> None:
        """As the base, and the blades' height, friction and drag as a contact layer's."""
        super().perturb(model, nominal, p)
        self.layer_height = self.surface.layer_height * p.layer_height
        self.friction = self.surface.friction * p.friction
        self.layer.drag_scale = p.drag

    def restore(self) -> None:
        super().restore()
        self.friction = self.surface.friction
        self.layer.drag_scale = 1.0

    def at_rest(self) -> Surface:
        """A foot set down on the blades is not jammed (a foot let fall onto them would be)."""
        s = self.surface
        return s.replace(blade_jam_speed=0.0, blade_jam_slide=0.0) if s.jams else s

    def carry_over(self, other: GroundKind) -> None:
        assert isinstance(other, Blades) and other.layer is not None
        self.layer.inside[:], self.layer.anchor[:] = other.layer.inside, other.layer.anchor


class BladeLayer:
    """The per-tick state of the blade layer on N sole points (module docstring).

    ``areas`` (N,) [m^2]: the sole each point stands for; ``first`` the index of the first point's
    first actuator (each point's three follow in :meth:`Blades.add_point`'s order)."""

    def __init__(self, surface: Surface, areas: np.ndarray, first: int, dt: float) -> None:
        a = np.asarray(areas, dtype=float)
        self.dt = float(dt)                    # [s] between two calls of update (the entry speed's)
        self.k_base = surface.blade_modulus * a
        self.k_tip = surface.blade_tip_modulus * a if surface.blade_tip_depth > 0.0 else self.k_base
        self.d_tip = surface.blade_tip_depth
        self.c = surface.blade_damping * a
        self.c_tip = surface.blade_tip_damping * a if surface.blade_tip_depth > 0.0 else self.c
        self.k_hold = surface.blade_shear * a
        self.drag = surface.drag
        self.drag_scale = 1.0                  # a randomised rollout's drag factor
        self.first = first
        self.n = len(a)
        self.anchor = np.zeros((self.n, 2))
        self.inside = np.zeros(self.n, dtype=bool)
        self._f0_base = (self.k_tip - self.k_base) * self.d_tip
        self._k_hold2 = self.k_hold * self.k_hold
        self._rows = slice(first, first + BLADE_ACTUATORS * self.n)
        self._block = np.zeros((self.n, BLADE_ACTUATORS, 3))     # each point's three gain rows
        self._block[:, 1:, 1] = -self.k_hold[:, None]
        self.jam_speed = surface.blade_jam_speed
        self.jam_slide = surface.blade_jam_slide
        self.jams = surface.jams
        self.jam_force = surface.blade_jam_pressure * a
        self.jammed = np.zeros(self.n, dtype=bool)
        self.jam_z = np.zeros(self.n)
        self._z_prev = np.full(self.n, np.nan)
        self._xy_prev = np.full((self.n, 2), np.nan)
        self.entry_speed = np.full(self.n, np.nan)
        self.slide_speed = np.full(self.n, np.nan)

    def reset(self) -> None:
        """A new walk: no point is in the blades."""
        self.inside[:] = False
        self.jammed[:] = False
        self._z_prev[:] = np.nan
        self._xy_prev[:] = np.nan

    def update(self, model: mujoco.MjModel, data: mujoco.MjData, p_world: np.ndarray, layer_height: float,
               friction: float) -> np.ndarray:
        """One control tick: the points at ``p_world`` (N, 3) [m], the layer ``layer_height`` [m]
        tall and ``friction`` strong. Sets the actuators' ctrl and gains; returns each point's
        support [N] (zero outside the layer; a jammed point's includes its jam's spring, and its
        hold lets go at friction x that)."""
        h = layer_height
        z = p_world[:, 2]
        xy = p_world[:, :2]
        now = z < h
        entered = now & ~self.inside
        if entered.any():
            self.anchor[entered] = xy[entered]
        depth = h - z
        base = depth > self.d_tip
        k = np.where(base, self.k_base, self.k_tip)
        f0 = np.where(base, self._f0_base, 0.0)
        load = (f0 + k * depth) * now
        if self.jams:                             # a jammed point's spring carries it too
            load = load + self._jam(z, xy, now, entered)
        np.maximum(load, 0.0, out=load)
        d = self.anchor - xy
        pull2 = (d * d).sum(axis=1) * self._k_hold2
        limit = friction * load
        slip = now & (pull2 > limit * limit)
        if slip.any():                    # the anchor slides to where the hold is friction x load
            scale = limit[slip] / np.sqrt(pull2[slip])
            self.anchor[slip] = xy[slip] + d[slip] * scale[:, None]
        self.inside = now
        # support F = f0 + k (h - z) - c v_z (+ k_h (z_jam - z) where jammed); hold F = k_h (anchor
        # - x) - drag v_x (gains, ctrl)
        blk = self._block
        blk[:, 0, 0] = f0 + k * h
        blk[:, 0, 1] = -k
        blk[:, 0, 2] = np.where(base, -self.c, -self.c_tip)
        if self.jammed.any():
            j = self.jammed
            blk[j, 0, 0] += self.k_hold[j] * self.jam_z[j]
            blk[j, 0, 1] -= self.k_hold[j]
            blk[j, 0, 2] = -self.c[j]             # damped as the base (the tips may have none)
        blk[:, 1:, 0] = self.k_hold[:, None] * self.anchor
        blk[:, 1:, 2] = -self.drag * self.drag_scale
        model.actuator_gainprm[self._rows, :3] = blk.reshape(-1, 3)
        data.ctrl[self._rows] = np.repeat(now, BLADE_ACTUATORS)
        return load

    def _jam(self, z: np.ndarray, xy: np.ndarray, now: np.ndarray, entered: np.ndarray) -> np.ndarray:
        """The jam (module docstring): points entering faster than ``jam_speed`` (downward) or
        ``jam_slide`` (horizontally), where that is > 0, are jammed at the height they entered; a
        jam lets go when its spring pulls the point up harder than ``jam_force`` or the point is out
        of the blades. Returns the jams' springs' support [N] (zero where none holds);
        ``entry_speed`` and ``slide_speed`` keep each point's downward and horizontal speed over
        this tick [m/s] (NaN on a walk's first tick)."""
        self.entry_speed = (self._z_prev - z) / self.dt
        self._z_prev[:] = z
        d = xy - self._xy_prev
        self.slide_speed = np.sqrt((d * d).sum(axis=1)) / self.dt
        self._xy_prev[:] = xy
        fast = np.zeros(self.n, dtype=bool)                            # NaN compares False
        if self.jam_speed > 0.0:
            fast |= self.entry_speed > self.jam_speed
        if self.jam_slide > 0.0:
            fast |= self.slide_speed > self.jam_slide
        fast &= entered
        self.jam_z[fast] = z[fast]
        spring = self.k_hold * (self.jam_z - z)
        self.jammed = ((self.jammed & now) | fast) & ~(-spring > self.jam_force)
        return self.jammed * spring
