"""A learned correction on the engine's leg targets: the residual (ours).

The engine plans a LIPM walk and puts its servos' give back into its targets; it cannot plan what
its model leaves out (the trunk's rotation, a soft servo's lag at speed, a grass blade). The
residual adds to each leg's six targets a linear map of what the robot senses and where its step
stands, trained in the tool's own closed loop (``gait-tuner train``: random search over the map,
Mania, Guy & Recht 2018's ARS, ``tuner/search/train.py``). Nothing here is from the three papers.

**Mirror symmetry.** A leg's correction depends on its *role* in the step, stance or swing, not on
its side: one map per role, shared by both legs. Each leg reads the lateral quantities (sideways
command, turn, roll, roll rate, sideways CoM error) times its side sign sigma (+1 left, -1 right)
and its lateral joints (hip yaw, hip roll, ankle roll) take their rows times sigma, so a walk
mirrored left to right gets the mirrored correction (``tests/test_residual.py``). Standing, or
in the weight shift before the first step, both legs are in stance and the step's progress is 0.

**Features** (``FEATURES``, each scaled to about 1 at its typical largest, ours), by column:

* 0: 1 (a constant);
* 1, 2: sin(pi s), sin(2 pi s), s in [0, 1] the progress of the current step;
* 3, 4, 5: vx / 0.3 m/s, sigma vy / 0.3 m/s, sigma wz / 1.0 rad/s, the command the engine plans for
  (after its ramp);
* 6, 7: the pitch beyond the planned lean / 0.2 rad, sigma the roll / 0.2 rad (the engine's
  filtered tilt);
* 8, 9: the gyro's pitch rate / 2 rad/s, sigma its roll rate / 2 rad/s;
* 10, 11: the CoM velocity estimated minus planned, forward / 0.2 m/s and sigma sideways / 0.2 m/s.

A correction is clipped to +-``limit`` [rad] per joint. All-zero weights are the engine itself,
target for target. The map's rows are the leg's joints in ``LEG_JOINTS`` order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..control import READINGS, Measurement, Wrapped
from ..params import ParamError
from ..trajectory import JOINT_NAMES
from .walk import WALK

__all__ = ["ResidualParams", "ResidualWalk", "FEATURES", "LEG_JOINTS", "ROLES", "residual_from_mapping",
           "features"]

#: the six joints of a leg a correction moves, in its rows' order
LEG_JOINTS = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
#: which of them turn about a lateral axis (their rows, and the lateral features, change sign per side)
_LATERAL = np.array([True, True, False, False, False, True])
ROLES = ("stance", "swing")
FEATURES = ("constant", "sin(pi s)", "sin(2 pi s)", "vx", "vy", "wz", "pitch", "roll", "pitch rate",
            "roll rate", "com vx error", "com vy error")
_SCALES = (1.0, 1.0, 1.0, 1 / 0.3, 1 / 0.3, 1 / 1.0, 1 / 0.2, 1 / 0.2, 1 / 2.0, 1 / 2.0, 1 / 0.2, 1 / 0.2)
_MIRRORED = (False, False, False, False, True, True, False, True, False, True, False, True)
N_FEATURES = len(FEATURES)
#: each side's factor per feature: its scale, times the side's sign where the feature is lateral
_SIDE_SCALES = {sign: np.array([s * (sign if m else 1.0) for s, m in zip(_SCALES, _MIRRORED)])
                for sign in (1, -1)}
_COLUMNS = {1: np.array([JOINT_NAMES.index(f"l_{j}") for j in LEG_JOINTS]),
            -1: np.array([JOINT_NAMES.index(f"r_{j}") for j in LEG_JOINTS])}
LIMIT_RANGE = (0.0, 1.0)      # [rad] the clip a file may set: (0, 1]


@dataclass(frozen=True)
class ResidualParams:
    """The residual's map: ``stance`` and ``swing`` each six rows (``LEG_JOINTS``) of twelve weights
    (``FEATURES``) [rad per unit feature], and the clip ``limit`` [rad]."""

    stance: tuple[tuple[float, ...], ...] = ((0.0,) * N_FEATURES,) * len(LEG_JOINTS)
    swing: tuple[tuple[float, ...], ...] = ((0.0,) * N_FEATURES,) * len(LEG_JOINTS)
    limit: float = 0.3            # [rad] the most a correction moves a joint (ours)

    def __post_init__(self) -> None:
        for role in ROLES:
            rows = getattr(self, role)
            shape = np.shape(np.asarray(rows, dtype=object))
            if shape != (len(LEG_JOINTS), N_FEATURES):
                raise ParamError(f"{role}: expected {len(LEG_JOINTS)} rows ({', '.join(LEG_JOINTS)}) of "
                                 f"{N_FEATURES} numbers ({', '.join(FEATURES)}), got shape {shape}")
            for i, row in enumerate(rows):
                for j, v in enumerate(row):
                    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                        raise ParamError(f"{role}[{LEG_JOINTS[i]}][{FEATURES[j]}] = {v!r}: expected a finite "
                                         f"number [rad]")
            object.__setattr__(self, role, tuple(tuple(float(v) for v in row) for row in rows))
        lo, hi = LIMIT_RANGE
        if isinstance(self.limit, bool) or not isinstance(self.limit, (int, float)) or not lo < self.limit <= hi:
            raise ParamError(f"limit = {self.limit!r}: expected a clip in ({lo:g}, {hi:g}] rad")
        object.__setattr__(self, "limit", float(self.limit))

    @classmethod
    def from_matrix(cls, w: np.ndarray, limit: float = 0.3) -> "ResidualParams":
        """From a (2, 6, 12) array: roles (stance, swing) x ``LEG_JOINTS`` x ``FEATURES``."""
        w = np.asarray(w, dtype=float)
        if w.shape != (len(ROLES), len(LEG_JOINTS), N_FEATURES):
            raise ParamError(f"a residual's weights are (2, 6, 12), got {w.shape}")
        return cls(tuple(map(tuple, w[0].tolist())), tuple(map(tuple, w[1].tolist())), limit)

    @property
    def matrix(self) -> np.ndarray:
        """(2, 6, 12): roles x joints x features."""
        return np.array([self.stance, self.swing], dtype=float)

    def to_mapping(self) -> dict[str, Any]:
        return {"limit": self.limit, "stance": [list(r) for r in self.stance], "swing": [list(r) for r in self.swing]}


def residual_from_mapping(doc: Any, source: str = "residual") -> ResidualParams:
    """A validated :class:`ResidualParams` from a set file's ``residual:`` section."""
    keys = ("limit", "stance", "swing")
    if not isinstance(doc, Mapping):
        raise ParamError(f"{source}: expected a mapping of {', '.join(keys)}")
    for k in doc:
        if k not in keys:
            raise ParamError(f"{source}: unknown field {k!r} (allowed: {', '.join(keys)})")
    zero = ResidualParams()
    try:
        return ResidualParams(doc.get("stance", zero.stance), doc.get("swing", zero.swing), doc.get("limit", zero.limit))
    except ParamError as exc:
        raise ParamError(f"{source}: {exc}") from None
    except TypeError:
        raise ParamError(f"{source}: stance and swing are each six rows of twelve numbers") from None


def features(progress: float, command: np.ndarray, tilt: np.ndarray, gyro: np.ndarray | None,
             vel_error: np.ndarray, sign: float) -> np.ndarray:
    """(12,) the features of the leg of side ``sign`` (+1 left, -1 right): ``progress`` s in [0, 1],
    ``command`` (vx, vy, wz), ``tilt`` (roll, pitch beyond the planned lean) [rad], ``gyro`` (roll,
    pitch, yaw rates) [rad/s] or None (no reading: zero), ``vel_error`` (2,) [m/s]."""
    return _raw_features(progress, command, tilt, gyro, vel_error) * _SIDE_SCALES[1 if sign > 0 else -1]


def _raw_features(progress: float, command: np.ndarray, tilt: np.ndarray, gyro: np.ndarray | None,
                  vel_error: np.ndarray) -> np.ndarray:
    """(12,) the features before each side's scale and sign (:func:`features`): the same for both legs."""
    gx, gy = (0.0, 0.0) if gyro is None else (float(gyro[0]), float(gyro[1]))
    return np.array((1.0, math.sin(math.pi * progress), math.sin(2 * math.pi * progress),
                     float(command[0]), float(command[1]), float(command[2]),
                     float(tilt[1]), float(tilt[0]), gy, gx, float(vel_error[0]), float(vel_error[1])))


class ResidualWalk(Wrapped):
    """The engine (``inner``, a :class:`gaits.engine.WalkEngine`) with the residual added to its leg
    targets (module docstring); every other call and attribute is the engine's."""

    def __init__(self, inner: Any, params: ResidualParams) -> None:
        super().__init__(inner)
        self.params = params
        self.senses = frozenset(getattr(inner, "senses", READINGS)) | {"imu_rpy", "gyro"}
        self._w = params.matrix
        self._gyro: np.ndarray | None = None
        self.last_correction = np.zeros(len(JOINT_NAMES))

    def reset(self, m: Measurement) -> None:
        self._gyro = None
        self.last_correction = np.zeros(len(JOINT_NAMES))
        self.inner.reset(m)

    def step(self, m: Measurement, command: np.ndarray | None = None) -> np.ndarray:
        q = np.array(self.inner.step(m, command), dtype=float)
        eng = self.inner
        if m.gyro is not None and math.isfinite(float(np.sum(m.gyro))):
            self._gyro = np.asarray(m.gyro, dtype=float)           # a dropped reading: the last one holds
        cur = eng.cur if eng.mode == WALK else None
        progress = 0.0 if cur is None else min(max((eng.t - eng.step_t0) / max(cur.T, 1e-6), 0.0), 1.0)
        vel_error = eng.estimator.velocity - eng.vel
        lim = self.params.limit
        out = np.zeros(len(JOINT_NAMES))
        raw = _raw_features(progress, eng.command, eng.tilt, self._gyro, vel_error)    # once a tick, both legs
        for sign in (1, -1):
            role = 0 if cur is None or cur.side == sign else 1
            d = self._w[role] @ (raw * _SIDE_SCALES[sign])
            d[_LATERAL] *= sign
            out[_COLUMNS[sign]] = np.clip(d, -lim, lim)
        self.last_correction = out
        return q + out
