"""What a kind of ground is to the simulator (ours, after dm_control's arenas): one class that puts
its parts into a MuJoCo scene and runs its own term between control ticks.

A kind is bound to one :class:`~tuner.sim.surfaces.Surface` (its numbers) and lives as long as one
compiled scene: the robot's (``scene.build_scene``, ``rollout.Simulator``) or a turf test rig's
(``turf_tests.py``). In order, the scene or rig calls

1. :meth:`GroundKind.add_geoms` (the planes and what is drawn), then, when :attr:`on_points`,
   :meth:`GroundKind.attach` at each sole point (a site: a corner of each sole on the robot), and
   reads :attr:`GroundKind.user_slots` (``mjData.userdata`` entries the kind needs);
2. once the model is compiled, :meth:`GroundKind.bind` (the model, the sole area each point stands
   for, how often :meth:`tick` runs, and where the points are);
3. for each walk: :meth:`reset`, :meth:`arm`, and every control tick :meth:`tick` when
   :attr:`python_tick` (MuJoCo's native rollout runs a walk whose ground needs none), then
   :meth:`disarm`; a randomised walk calls :meth:`perturb` first and :meth:`restore` after.

A surface names its kind (``kind:``), or leaves it to its fields: the built-in kinds claim the
surfaces they were written for (:meth:`GroundKind.claims`). Adding a kind: one module with a
subclass decorated with :func:`register_kind`, imported in ``tuner/sim/ground/__init__.py`` (or by
whoever uses it: ``tests/test_ground.py`` adds one in the test itself).
"""

from __future__ import annotations

from typing import Any, Callable, ClassVar

import mujoco
import numpy as np

from ...errors import UserError
from ..surfaces import Surface

__all__ = ["GroundKind", "KINDS", "register_kind", "kind_of", "PREFIX", "REF_SITE"]

#: the namespace of everything our scenes add to a robot's model (``scene.py``)
PREFIX = "gt/"
#: the world reference site of every site-transmission actuator of the ground (blades and drag)
REF_SITE = PREFIX + "drag_ref"

#: the registered kinds by name, in registration order
KINDS: dict[str, type["GroundKind"]] = {}


def register_kind(cls: type["GroundKind"]) -> type["GroundKind"]:
    """Class decorator: make a kind of ground known by its ``name`` (a surface's ``kind:``)."""
    if not cls.name:
        raise ValueError(f"{cls.__name__}: a ground kind needs a name")
    if cls.name in KINDS and KINDS[cls.name] is not cls:
        raise ValueError(f"ground kind {cls.name!r} is registered twice ({KINDS[cls.name].__name__}, {cls.__name__})")
    KINDS[cls.name] = cls
    return cls


def kind_of(surface: Surface) -> "GroundKind":
    """A fresh kind bound to ``surface``: the one it names, or the one its fields make it (the
    first registered kind that claims it). An unknown name is refused in one line."""
    if surface.kind:
        cls = KINDS.get(surface.kind)
        if cls is None:
            raise UserError(f"surface {surface.name!r}: kind = {surface.kind!r} is not a ground kind "
                            f"(known: {', '.join(KINDS)})")
        if cls.claims.__func__ is not GroundKind.claims.__func__ and not cls.claims(surface):
            # a built-in kind named on fields that make another: half of them would be ignored
            other = next((c.name for c in KINDS.values() if c.claims(surface)), "another")
            raise UserError(f"surface {surface.name!r}: kind = {surface.kind!r}, but its fields make it "
                            f"{other!r} (layer_height = {surface.layer_height:g} m, blade_modulus = "
                            f"{surface.blade_modulus:g} N/m^3); drop kind: or the other kind's fields")
        return cls(surface)
    for cls in KINDS.values():
        if cls.claims(surface):
            return cls(surface)
    raise UserError(f"surface {surface.name!r}: no ground kind takes its fields; name one with kind: "
                    f"({', '.join(KINDS)})")


class GroundKind:
    """A kind of ground (module docstring). The base is the soil: a plane at z = 0 with the
    surface's ``soil_friction``, no term of its own; subclasses add their layer."""

    #: the name a surface's ``kind:`` gives
    name: ClassVar[str] = ""
    #: the surface fields a walk on this ground can tell (``identify ground``), the main two first
    fields: ClassVar[tuple[str, ...]] = ("friction",)

    def __init__(self, surface: Surface) -> None:
        self.surface = surface
        #: [m] the layer's height in the walk now (a randomised walk scales it)
        self.layer_height = surface.layer_height
        self.sites: list[str] = []          # the sole points attached, in order
        self.first = 0                      # the index of the kind's first actuator
        self.n_actuators = 0
        self.site_ids = np.zeros(0, dtype=int)
        self._geoms: list[int] = []
        self._points: Callable[[mujoco.MjData], np.ndarray] | None = None

    @classmethod
    def claims(cls, surface: Surface) -> bool:
        """Whether a surface that names no kind is of this one (by its fields)."""
        return False

    def fit_fields(self) -> tuple[str, ...]:
        """The fields ``identify ground`` fits on this surface, the main two first."""
        return self.fields

    # --- the scene -------------------------------------------------------------------
    @property
    def on_points(self) -> bool:
        """Whether the kind acts at each sole point (the scene then puts a site there)."""
        return False

    @property
    def runs_in_step(self) -> bool:
        """Whether the kind's term can run inside MuJoCo's step (``native_step.c``) where that
        callback is installed, rather than once a control tick here."""
        return False

    @property
    def user_slots(self) -> int:
        """``mjData.userdata`` entries the kind needs at the end of the block."""
        return 0

    def contact_geoms(self) -> tuple[str, ...]:
        """The geoms a sole touches (a randomised walk scales their friction)."""
        return (PREFIX + "soil",)

    def add_geoms(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault) -> None:
        """The soil plane (and what is drawn: a checker, a light)."""
        soil = spec.worldbody.add_geom(default=gt, name=PREFIX + "soil", type=mujoco.mjtGeom.mjGEOM_PLANE,
                                       size=[0, 0, 0.05])
        soil.friction = [self.surface.soil_friction, 0.005, 0.0001]
        soil.priority = 2
        soil.contype = 0
        soil.conaffinity = 1
        soil.rgba = [0.45, 0.35, 0.25, 1]
        # drawn only: a 10 cm checker on the ground (motion and slip are visible in a video) and
        # a light from above; neither touches the physics
        tex = spec.add_texture(name=PREFIX + "grid", type=mujoco.mjtTexture.mjTEXTURE_2D,
                               builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, width=256, height=256,
                               rgb1=[0.66, 0.56, 0.42], rgb2=[0.50, 0.40, 0.30])
        mat = spec.add_material(name=PREFIX + "grid")
        mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = tex.name
        mat.texrepeat = [10, 10]
        mat.texuniform = True
        soil.material = mat.name
        sun = spec.worldbody.add_light(name=PREFIX + "sun", pos=[0, 0, 3], dir=[0.2, 0.3, -1],
                                       diffuse=[0.8, 0.8, 0.8], specular=[0.2, 0.2, 0.2])
        sun.castshadow = False

    def add_slab(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault) -> None:
        """Drawn only: a translucent slab as tall as the layer, so a video shows how deep the feet
        sink (no contact, no mass)."""
        h = self.surface.layer_height
        slab = spec.worldbody.add_geom(default=gt, name=PREFIX + "blades", type=mujoco.mjtGeom.mjGEOM_BOX,
                                       size=[4.0, 4.0, h / 2], pos=[0, 0, h / 2])
        slab.contype = 0
        slab.conaffinity = 0
        slab.group = 1
        slab.rgba = [0.35, 0.85, 0.3, 0.22]

    def attach(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault, site: str, label: str) -> int:
        """The kind's actuators on one sole point (``site``, named ``label`` in theirs); returns how
        many were added (they follow one another, point after point)."""
        if self.n_actuators == 0:
            self.first = len(spec.actuators)
        self.sites.append(site)
        n = self.add_point(spec, gt, site, label)
        self.n_actuators += n
        return n

    def add_point(self, spec: mujoco.MjSpec, gt: mujoco.MjsDefault, site: str, label: str) -> int:
        """Subclasses: the actuators at one point (:meth:`attach` calls it)."""
        return 0

    @staticmethod
    def ref_site(spec: mujoco.MjSpec, gt: mujoco.MjsDefault) -> str:
        """The world reference site of the ground's site-transmission actuators (added once)."""
        if REF_SITE not in {x.name for x in spec.sites}:
            spec.worldbody.add_site(default=gt, name=REF_SITE, pos=[0, 0, 0])
        return REF_SITE

    def point_force(self, label: str) -> str | None:
        """The actuator whose force is a sole point's support where no contact carries the sole (a
        foot's force sensor reads it there); None where contacts carry it."""
        return None

    # --- a simulation ------------------------------------------------------------------
    def bind(self, model: mujoco.MjModel, areas: np.ndarray, period: float,
             points: Callable[[mujoco.MjData], np.ndarray] | None = None, *, native: bool = False) -> None:
        """The compiled model: ``areas`` (N,) [m^2] the sole each attached point stands for,
        ``period`` [s] between two :meth:`tick` calls, ``points`` the points' world positions
        (N, 3) from the data (default: their sites'); ``native``: the kind may run its term inside
        MuJoCo's step where it can (the robot's simulator; the rigs tick it themselves)."""
        self._geoms = [model.geom(n).id for n in self.contact_geoms()]
        self.site_ids = np.array([model.site(s).id for s in self.sites], dtype=int)
        ids = self.site_ids
        self._points = points if points is not None else (lambda d: d.site_xpos[ids])

    @property
    def python_tick(self) -> bool:
        """Whether :meth:`tick` must run every control tick (else the walk may run natively)."""
        return False

    def reset(self) -> None:
        """A new walk."""

    def arm(self, model: mujoco.MjModel, data: mujoco.MjData, nstep: int) -> None:
        """A walk starts now (``nstep`` physics steps a control tick)."""

    def disarm(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """The walk ended."""

    def tick(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """One control tick's part of the ground, before its physics."""

    def perturb(self, model: mujoco.MjModel, nominal: dict[str, np.ndarray], p: Any) -> None:
        """A randomised walk's ground: the friction of the geoms a sole touches and the kind's
        actuators' damping by their factors (``p`` a ``randomisation.Perturbation``; ``nominal`` the
        model's arrays before any)."""
        for g in self._geoms:
            model.geom_friction[g, 0] = nominal["geom_friction"][g, 0] * p.friction
        rows = slice(self.first, self.first + self.n_actuators)
        model.actuator_gainprm[rows, 2] = nominal["actuator_gainprm"][rows, 2] * p.drag

    def restore(self) -> None:
        """After a randomised walk (the simulator restores the model's arrays itself)."""
        self.layer_height = self.surface.layer_height

    def at_rest(self) -> Surface:
        """The surface a rig's foot is set down on before a test (the same, but for a state the
        setting down would trigger)."""
        return self.surface

    def carry_over(self, other: "GroundKind") -> None:
        """Take the per-point state ``other`` (the same kind, on the same points) was left in."""
