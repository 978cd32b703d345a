"""The ground under the robot: a kind of ground per module, each one class that puts its parts into
a scene and runs its own term between ticks (``kind.py`` says how; a surface's numbers are in
``tuner/sim/surfaces.py``).

* ``rigid.py``: the soil plane alone;
* ``layer.py``: carpet or grass as a soft contact layer, with the blades' drag on each sole corner;
* ``blades.py``: grass as springs under each sole point by pressure, with blades that hold (ours).

A new kind: one module here with a :class:`GroundKind` subclass decorated with
:func:`register_kind`, imported below; a surface file then names it (``kind: NAME``).
"""

from .kind import KINDS, PREFIX, REF_SITE, GroundKind, kind_of, register_kind
from . import rigid, layer, blades  # the built-in kinds register themselves

__all__ = ["KINDS", "PREFIX", "REF_SITE", "GroundKind", "kind_of", "register_kind", "rigid", "layer", "blades"]
