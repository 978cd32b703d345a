"""Ground surfaces: a rigid floor, carpet and artificial grass as calibrated MuJoCo contact layers.

Model. Hard soil is a plane at z = 0. A carpet or grass is a second plane at
the same height whose contact *margin* is the blade height: a sole point less
than ``layer_height`` above the soil is in contact with the layer, whose
support is soft (MuJoCo ``solref``/``solimp``: weak at the blade tips, stiffer
deeper in). Blades also hold a foot that moves sideways inside them: every sole
corner inside the layer feels a horizontal drag ``-drag * v`` (with ``drag_depth`` > 0, ours:
``-drag * min(1, depth / drag_depth) * v``, growing with how deep the corner is below the blade
tips; a sole turning in the layer meets a torque ``drag * sum(r_i^2) * w`` from its corners'
drag, r_i their distances from its centre). Each corner has
two MuJoCo damper actuators (site transmission along world x and y), so the
force is computed by MuJoCo at every physics step and integrated implicitly
(``implicitfast``): stable at any drag, with no per-step Python callback. Once
per control tick the simulator switches on the dampers of the corners that are
below the blade tips. A rollout on grass costs ~1.4x the rigid floor's
(``benchmarks/bench_simulate.py``).

Measured (``tests/test_simulation.py``, ``Simulator.landing_test``): the same
toe-first landing pitches the robot more on grass50 than on carpet4 and leaves
it pitched forward (toe held) while on carpet it rocks back. That comes from
the soft, deep layer; a stronger drag plants the whole sole and *reduces* the
pitch (e.g. 6.1 deg at drag 0, 5.5 at 300, 3.5 at 3000 N s/m in an ad-hoc run).

A surface with ``blade_modulus`` > 0 is the **blade layer** instead (ours, ``blades.py``): no
contact layer; springs under each sole corner by pressure, in two stages (flexible tips over a
stiff base), blades that hold a corner where it entered until friction lets go, and the drag; with
``blade_jam_speed`` > 0, a corner that lands faster than that is jammed near the tips (the EROS
paper's account of a toe stuck in the grass, as a mechanism); with ``blade_jam_slide`` > 0, one
that enters the blades sliding faster than that (a toe dragged into them) is jammed the same way.
The built-in pedestals keep the contact layer (their calibration); ``examples/surfaces`` has blade
layers of grass50's height (and jam files of grass30's), and ``examples/surfaces/calibrated`` the
blade layers ``gait-tuner calibrate --layer blades`` chose for the three grass pedestals.

How each kind of ground enters the scene and the loop is its class in ``tuner/sim/ground/``
(``rigid``, ``layer``, ``blades``, or one registered and named by ``kind``); this module holds the
numbers.

The four built-in surfaces mirror the EROS paper's pedestals (Sec. 5, Figs
20-23): grass50 (50 mm blades, sparse, irregular), grass30 (30 mm, dense,
smooth), grass10 (10 mm, dense, rough) and carpet4 (4 mm carpet); ``rigid`` is
a reference floor. How their numbers were chosen is in ``docs`` of each entry
and in the calibration note of docs/simulation.md.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any, Mapping


from gaits.params import GaitParams, ParamError, did_you_mean, param

from ..errors import UserError
from ..yaml_input import read_yaml_file

__all__ = ["Surface", "SURFACES", "load_surface", "surface_names"]


@dataclass(frozen=True)
class Surface(GaitParams):
    """A ground surface (SI units). ``layer_height = 0`` is a rigid floor."""

    FAMILY = "surface"
    name: str = param("custom", "-", doc="surface name")
    layer_height: float = param(0.0, "m", 0.0, 0.10, "blade height / pile thickness (0: rigid)")
    layer_timeconst: float = param(0.02, "s", 0.002, 0.5, "time constant of the layer's support (solref[0])")
    layer_dampratio: float = param(1.0, "-", 0.1, 5.0, "damping ratio of the layer's support (solref[1])")
    layer_dmin: float = param(0.5, "-", 0.0001, 0.9999, "constraint impedance at the blade tips (solimp[0])")
    layer_dmax: float = param(0.95, "-", 0.0001, 0.9999, "constraint impedance at the soil (solimp[1])")
    friction: float = param(0.9, "-", 0.05, 3.0, "sliding friction of the layer (or the rigid floor)")
    drag: float = param(0.0, "N s/m", 0.0, 5000.0, "horizontal drag on each sole corner inside the layer")
    drag_depth: float = param(0.0, "m", 0.0, 0.10, "depth below the blade tips over which the drag grows "
                              "linearly to its full value (0: full as soon as a corner is inside; ours)")
    soil_friction: float = param(0.9, "-", 0.05, 3.0, "sliding friction of the soil below the layer")
    blade_modulus: float = param(0.0, "N/m^3", 0.0, 1.0e9, "blade layer (ours): vertical support per sole "
                                 "area per depth below the tips (0: the soft contact layer instead)")
    blade_damping: float = param(0.0, "N s/m^3", 0.0, 1.0e8, "blade layer: vertical damping per sole area")
    blade_shear: float = param(0.0, "N/m^3", 0.0, 1.0e9, "blade layer: how stiffly the blades hold a sole "
                               "point where it entered, per sole area, until friction x its load lets go")
    blade_tip_depth: float = param(0.0, "m", 0.0, 0.10, "blade layer: depth of the flexible tips, above the "
                                   "stiff base of blades and infill (0: the whole layer is one)")
    blade_tip_modulus: float = param(0.0, "N/m^3", 0.0, 1.0e9, "blade layer: vertical support of the flexible "
                                     "tips, per sole area per depth")
    blade_tip_damping: float = param(0.0, "N s/m^3", 0.0, 1.0e8, "blade layer: vertical damping of the flexible "
                                     "tips, per sole area")
    blade_jam_speed: float = param(0.0, "m/s", 0.0, 10.0, "blade layer (ours): a sole point entering the "
                                   "blades faster than this (downward) is jammed at the height it entered, "
                                   "held there by blade_shear until pulled out (0: no point jams)")
    blade_jam_slide: float = param(0.0, "m/s", 0.0, 10.0, "blade layer (ours): a sole point entering the "
                                   "blades sliding faster than this (horizontally) is jammed the same way (0: no "
                                   "point jams so)")
    blade_jam_pressure: float = param(0.0, "Pa", 0.0, 1.0e7, "blade layer: the upward pull per sole area that "
                                      "frees a jammed point")
    description: str = param("", "-", doc="where the numbers come from")
    kind: str = param("", "-", doc="the kind of ground (tuner/sim/ground/): rigid, layer, blades or one "
                      "registered; empty: the one its fields make it")

    def __repr__(self) -> str:
        """The dataclass's, without an empty ``kind`` (a study's scoring parts digest it: a surface
        written before kinds were named reads as it did)."""
        shown = [f"{f.name}={getattr(self, f.name)!r}" for f in fields(self)
                 if f.repr and not (f.name == "kind" and not self.kind)]
        return f"{type(self).__name__}({', '.join(shown)})"

    def check_consistency(self) -> None:
        if self.layer_dmin > self.layer_dmax:
            raise ParamError(f"surface {self.name!r}: layer_dmin = {self.layer_dmin:g} must not exceed "
                             f"layer_dmax = {self.layer_dmax:g}")
        for name in ("drag_depth", "blade_tip_depth"):          # depths within the layer
            if getattr(self, name) > self.layer_height:
                raise ParamError(f"surface {self.name!r}: {name} = {getattr(self, name):g} m must not exceed "
                                 f"layer_height = {self.layer_height:g} m")
        for name in ("blade_jam_speed", "blade_jam_slide"):
            value = getattr(self, name)
            if value > 0.0 and (self.blade_modulus == 0.0 or self.blade_shear == 0.0):
                raise ParamError(f"surface {self.name!r}: {name} = {value:g} m/s needs the blade layer "
                                 f"(blade_modulus > 0) and its hold (blade_shear > 0): a jammed point is held by it")
        default_soil = type(self).__dataclass_fields__["soil_friction"].default
        if self.layer_height == 0.0 and self.kind in ("", "rigid") and self.soil_friction not in (default_soil,
                                                                                                  self.friction):
            raise ParamError(f"surface {self.name!r}: soil_friction = {self.soil_friction:g} on a rigid floor: the "
                             f"floor's friction is friction = {self.friction:g} (soil_friction is the soil under "
                             f"a layer); set friction")
        for name, value, unit in (("blade_modulus", self.blade_modulus, "N/m^3"), ("drag", self.drag, "N s/m")):
            if self.layer_height == 0.0 and value > 0.0:         # what acts in a layer needs one
                raise ParamError(f"surface {self.name!r}: {name} = {value:g} {unit} needs a layer "
                                 f"(layer_height > 0)")

    @property
    def jams(self) -> bool:
        """The blade layer jams a sole point that enters too fast: downward (``blade_jam_speed``),
        sliding (``blade_jam_slide``), or both."""
        return self.blade_jam_speed > 0.0 or self.blade_jam_slide > 0.0


SURFACES: dict[str, Surface] = {
    "rigid": Surface(name="rigid", friction=0.9, soil_friction=0.9,
                     description="hard floor, friction 0.9: the reference"),
    "carpet4": Surface(name="carpet4", layer_height=0.004, layer_timeconst=0.01, layer_dampratio=1.0,
                       layer_dmin=0.9, layer_dmax=0.95, friction=1.0, drag=0.0,
                       description="EROS pedestal 4: green carpet, 4 mm, smooth and soft (no blades to drag)"),
    "grass10": Surface(name="grass10", layer_height=0.010, layer_timeconst=0.01, layer_dampratio=1.0,
                       layer_dmin=0.7, layer_dmax=0.95, friction=0.9, drag=30.0,
                       description="EROS pedestal 3: 10 mm blades, 5 mm apart (dense), rough; support and drag "
                                   "from gait-tuner calibrate (18 of 20 table cells)"),
    "grass30": Surface(name="grass30", layer_height=0.030, layer_timeconst=0.02, layer_dampratio=1.0,
                       layer_dmin=0.8, layer_dmax=0.95, friction=0.8, drag=200.0,
                       description="EROS pedestal 2: 30 mm blades, 5 mm apart (dense), smooth; support and drag "
                                   "from gait-tuner calibrate (16 of 20 table cells)"),
    "grass50": Surface(name="grass50", layer_height=0.050, layer_timeconst=0.04, layer_dampratio=1.0,
                       layer_dmin=0.4, layer_dmax=0.95, friction=0.8, drag=80.0,
                       description="EROS pedestal 1: 50 mm blades, 10 mm apart (sparse), irregular; soft enough "
                                   "to catch a toe-first landing (no layer that carries the full-lift EROS walk does)"),
}


def surface_names() -> list[str]:
    return list(SURFACES)


def load_surface(name_or_path: str) -> Surface:
    """A built-in surface by name, or a YAML file of :class:`Surface` fields."""
    if name_or_path in SURFACES:
        return SURFACES[name_or_path]
    path = Path(name_or_path)
    if not os.path.lexists(path):
        raise UserError(f"--surface {name_or_path!r}: not a built-in surface{did_you_mean(name_or_path, SURFACES)} "
                        f"({', '.join(SURFACES)}) and no such file")
    doc: Any = read_yaml_file(path, "surface")
    if not isinstance(doc, Mapping):
        raise UserError(f"{path}: expected a mapping of surface fields")
    known = [row["name"] for row in Surface.field_table()]
    for key in doc:
        if key not in known:
            raise UserError(f"{path}: unknown surface field {key!r}{did_you_mean(key, known)} (known: {', '.join(known)})")
    data = dict(doc)
    data.setdefault("name", path.stem)
    try:
        return Surface(**data)
    except ParamError as exc:
        raise UserError(f"{path}: {exc}") from None
