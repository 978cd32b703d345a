"""The one output shape of every gait family: a joint-target table plus its Cartesian references.

A generator produces world-frame references (pelvis, CoM, feet, ZMP reference,
support phase, ankle-pitch offsets); :func:`assemble` turns them into joint
targets q_ref(t) with the EROS leg IK and packs everything into a
:class:`GaitTrajectory`, which exports as CSV.

Frames: world x forward, y left, z up, the ground at z = 0. The pelvis is kept
upright; its heading is zero for the papers' straight walks, and follows the feet
for a walk command (``yaw_world_pelvis``), when the IK targets are the world
differences of sole and pelvis turned into the pelvis frame.
"""

from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .files import write_text_atomic
from .leg_kinematics import LEG_JOINTS, LegGeometry, leg_ik, refine_ik, rot_y, rot_z

__all__ = [
    "JOINT_NAMES",
    "LEFT_LEG",
    "RIGHT_LEG",
    "GaitTrajectory",
    "assemble",
    "cart_table_zmp",
    "resample",
    "GRAVITY",
]

GRAVITY = 9.81  # [m/s^2]

LEFT_LEG = tuple(f"l_{j}" for j in LEG_JOINTS)
RIGHT_LEG = tuple(f"r_{j}" for j in LEG_JOINTS)
#: The 20 joints of the EROS layout (Table 1): 2 head, 3 per arm, 6 per leg.
JOINT_NAMES = (("head_yaw", "head_pitch",
                "l_shoulder_pitch", "l_shoulder_roll", "l_elbow",
                "r_shoulder_pitch", "r_shoulder_roll", "r_elbow")
               + LEFT_LEG + RIGHT_LEG)
#: a joint name a map or a policy may give beyond :data:`JOINT_NAMES` (a robot's extra joint, by the
#: name its map's ``extra_joints:`` gives it): lower-case letters, digits and underscores
JOINT_NAME_PATTERN = re.compile(r"[a-z][a-z0-9_]*")


@dataclass(frozen=True)
class GaitTrajectory:
    """Joint targets and the Cartesian references they came from, sampled every ``dt``.

    Shapes: N samples; positions in metres, angles in radians, world frame.
    ``support`` is +1 on left single support, -1 on right, 0 in double support.
    """

    family: str
    t: np.ndarray                  # (N,) [s]
    q_ref: np.ndarray              # (N, 20) [rad], columns JOINT_NAMES
    p_world_pelvis: np.ndarray     # (N, 3) [m]
    p_world_com: np.ndarray        # (N, 3) [m]
    p_world_zmp_ref: np.ndarray    # (N, 2) [m]
    p_world_foot_l: np.ndarray     # (N, 3) [m] sole centre
    p_world_foot_r: np.ndarray     # (N, 3) [m]
    support: np.ndarray            # (N,) int
    joint_names: tuple[str, ...] = JOINT_NAMES
    zmp_source: str = "model"      # "model" (the family's own ZMP reference) or "cart-table"
    meta: dict = field(default_factory=dict)
    yaw_world_pelvis: np.ndarray | None = None   # (N,) [rad] heading; None: straight ahead (0)
    yaw_world_feet: np.ndarray | None = None     # (N, 2) [rad] left, right sole headings

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0]) if len(self.t) > 1 else 0.0

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    def joint(self, name: str) -> np.ndarray:
        """One column of q_ref by joint name."""
        try:
            return self.q_ref[:, self.joint_names.index(name)]
        except ValueError:
            raise KeyError(f"no joint {name!r}; joints are {', '.join(self.joint_names)}") from None

    def columns(self) -> dict[str, np.ndarray]:
        """Every exported column, named with its unit."""
        cols: dict[str, np.ndarray] = {"t[s]": self.t}
        for i, name in enumerate(self.joint_names):
            cols[f"{name}[rad]"] = self.q_ref[:, i]
        for label, arr, axes in (("com", self.p_world_com, "xyz"),
                                 ("zmp_ref", self.p_world_zmp_ref, "xy"),
                                 ("pelvis", self.p_world_pelvis, "xyz"),
                                 ("foot_l", self.p_world_foot_l, "xyz"),
                                 ("foot_r", self.p_world_foot_r, "xyz")):
            for k, ax in enumerate(axes):
                cols[f"{label}_{ax}[m]"] = arr[:, k]
        if self.yaw_world_pelvis is not None:
            cols["pelvis_yaw[rad]"] = self.yaw_world_pelvis
            cols["foot_l_yaw[rad]"] = self.yaw_world_feet[:, 0]
            cols["foot_r_yaw[rad]"] = self.yaw_world_feet[:, 1]
        cols["support[-]"] = self.support
        return cols

    def to_csv(self, path: str | Path, comment: str | None = None) -> Path:
        """Write the joint table and references as CSV (one row per sample); ``comment`` goes
        first as a ``#`` line (what robot, study and surfaces the table is for)."""
        return write_text_atomic(path, self.csv_text(comment))

    def csv_text(self, comment: str | None = None) -> str:
        """The text :meth:`to_csv` writes."""
        cols = self.columns()
        names = list(cols)
        data = np.column_stack([np.asarray(cols[n], dtype=float) for n in names])
        fh = io.StringIO(newline="")
        if comment:
            fh.write("# " + " ".join(comment.split()) + "\n")
        w = csv.writer(fh)
        w.writerow(names)
        for row in data:
            w.writerow([f"{v:.9g}" for v in row])
        return fh.getvalue()


def cart_table_zmp(t: np.ndarray, p_world_com: np.ndarray, g: float = GRAVITY) -> np.ndarray:
    """ZMP of the cart-table model, p = c - (z_c / g) c'', for a CoM path (N, 3) -> (N, 2).

    Used for families that define no ZMP reference of their own (EROS, cosine
    law), so their traces can still be scored for ZMP tracking. ``c''`` is a
    second-order finite difference, so velocity jumps in the CoM show as spikes.
    """
    t = np.asarray(t, dtype=float)
    c = np.asarray(p_world_com, dtype=float)
    if c.ndim != 2 or c.shape[1] != 3 or c.shape[0] != t.shape[0]:
        raise ValueError(f"cart_table_zmp expects t (N,) and com (N, 3), got {t.shape} and {c.shape}")
    if len(t) < 3:
        return c[:, :2].copy()
    acc = np.gradient(np.gradient(c[:, :2], t, axis=0), t, axis=0)
    return c[:, :2] - (c[:, 2:3] / g) * acc


def resample(t_src: np.ndarray, values: np.ndarray, t_new: np.ndarray) -> np.ndarray:
    """Linear interpolation of (N, ...) samples onto new times, column by column."""
    values = np.asarray(values, dtype=float)
    flat = values.reshape(len(t_src), -1)
    out = np.column_stack([np.interp(t_new, t_src, flat[:, k]) for k in range(flat.shape[1])])
    return out.reshape((len(t_new),) + values.shape[1:])


def _turn(yaw: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (N, 3) or (3,) about z by yaw (N,) [rad] -> (N, 3)."""
    v = np.broadcast_to(np.asarray(v, dtype=float), (len(yaw), 3))
    c, s = np.cos(yaw), np.sin(yaw)
    return np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]])


def assemble(family: str, t: np.ndarray, leg: LegGeometry, *,
             p_world_pelvis: np.ndarray, p_world_foot_l: np.ndarray, p_world_foot_r: np.ndarray,
             support: np.ndarray, p_world_zmp_ref: np.ndarray | None = None,
             ankle_pitch_offset: np.ndarray | None = None,
             yaw_world_pelvis: np.ndarray | None = None, yaw_world_feet: np.ndarray | None = None,
             pitch_pelvis: float = 0.0, meta: dict | None = None) -> GaitTrajectory:
    """Leg IK on world references -> :class:`GaitTrajectory`.

    ``ankle_pitch_offset`` (N, 2) [rad] (left, right) is added to the ankle
    pitch after the IK, as the EROS heel-strike gait does (eqs 46-47). Without a
    ZMP reference the cart-table ZMP of the CoM is recorded instead.
    ``yaw_world_pelvis`` (N,) and ``yaw_world_feet`` (N, 2) [rad] turn the pelvis and the
    soles (a walk command); the hip-yaw joints take the difference (EROS eq 9).
    ``pitch_pelvis`` [rad] leans the pelvis (and the torso on it) forward by a constant angle
    (ours): the paper's flat-foot IK starts a full-pose Gauss-Newton refinement
    (``leg_kinematics.refine_ik``) that keeps each sole flat, at its heading and position.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    for name, arr in (("p_world_pelvis", p_world_pelvis), ("p_world_foot_l", p_world_foot_l),
                      ("p_world_foot_r", p_world_foot_r)):
        if np.shape(arr) != (n, 3):
            raise ValueError(f"{name} must have shape ({n}, 3) to match t, got {np.shape(arr)}")
    turning = yaw_world_pelvis is not None
    if turning:
        if np.shape(yaw_world_pelvis) != (n,) or np.shape(yaw_world_feet) != (n, 2):
            raise ValueError(f"yaw_world_pelvis must have shape ({n},) and yaw_world_feet ({n}, 2), "
                             f"got {np.shape(yaw_world_pelvis)} and {np.shape(yaw_world_feet)}")
        psi = np.asarray(yaw_world_pelvis, dtype=float)
        yaw_feet = np.asarray(yaw_world_feet, dtype=float)
    else:
        psi = np.zeros(n)
        yaw_feet = np.zeros((n, 2))
    # The family's pelvis path is where it wants the CoM (horizontally): the pelvis itself is
    # moved by the robot's CoM offset, and each ankle by its sole offset (LegGeometry, ours).
    p_world_pelvis = (np.asarray(p_world_pelvis, dtype=float)
                      - _turn(psi, np.array([leg.com_forward, leg.com_lateral, 0.0])))
    lean = rot_y(float(pitch_pelvis))
    p_world_com = p_world_pelvis + _turn(psi, lean @ leg.com_in_pelvis)
    q = np.zeros((n, len(JOINT_NAMES)))
    up = np.array([0.0, 0.0, leg.ankle_height])
    legs = []
    for side, foot, yaw_f in ((1, p_world_foot_l, yaw_feet[:, 0]), (-1, p_world_foot_r, yaw_feet[:, 1])):
        # the ankle sits ankle_height straight above the flat sole, in the world
        ankle = np.asarray(foot, dtype=float) - _turn(yaw_f, leg.sole_in_ankle(side)) + up
        target = _turn(-psi, ankle - p_world_pelvis) @ lean - up      # lean.T @ v, row-wise
        q_leg = leg_ik(target, yaw_f - psi, leg, side, t=t)
        if pitch_pelvis:
            # the sole flat in the world is turned by -lean in the leaning pelvis frame
            R_d = lean.T @ rot_z(yaw_f - psi)
            q_leg = refine_ik(q_leg, target + up - R_d @ up, R_d, leg, side)
        legs.append(q_leg)
    q_l, q_r = legs
    if ankle_pitch_offset is not None:
        off = np.asarray(ankle_pitch_offset, dtype=float)
        if off.shape != (n, 2):
            raise ValueError(f"ankle_pitch_offset must have shape ({n}, 2), got {off.shape}")
        q_l[:, 4] += off[:, 0]
        q_r[:, 4] += off[:, 1]
    il = JOINT_NAMES.index(LEFT_LEG[0])
    ir = JOINT_NAMES.index(RIGHT_LEG[0])
    q[:, il:il + 6] = q_l
    q[:, ir:ir + 6] = q_r
    if p_world_zmp_ref is None:
        zmp = cart_table_zmp(t, p_world_com)
        source = "cart-table"
    else:
        zmp = np.asarray(p_world_zmp_ref, dtype=float)
        source = "model"
    traj = GaitTrajectory(family=family, t=t, q_ref=q, p_world_pelvis=np.asarray(p_world_pelvis),
                          p_world_com=p_world_com, p_world_zmp_ref=zmp,
                          p_world_foot_l=np.asarray(p_world_foot_l),
                          p_world_foot_r=np.asarray(p_world_foot_r),
                          support=np.asarray(support, dtype=int), zmp_source=source,
                          meta=dict(meta or {}),
                          yaw_world_pelvis=psi if turning else None,
                          yaw_world_feet=yaw_feet if turning else None)
    if not np.all(np.isfinite(traj.q_ref)):
        raise ValueError(f"{family}: the joint table has non-finite values")
    return traj
