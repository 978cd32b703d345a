"""The one output shape of every gait family: a joint-target table plus its Cartesian references.

A generator produces world-frame references (pelvis, CoM, feet, ZMP reference,
support phase, ankle-pitch offsets); :func:`assemble` turns them into joint
targets q_ref(t) with the EROS leg IK and packs everything into a
:class:`GaitTrajectory`, which exports as CSV.

Frames: world x forward, y left, z up, the ground at z = 0. The pelvis is kept
upright with zero heading (straight walking), so ``p_pelvis_sole`` is the world
difference of sole and pelvis.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .leg_kinematics import LEG_JOINTS, LegGeometry, leg_ik

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
        cols["support[-]"] = self.support
        return cols

    def to_csv(self, path: str | Path, comment: str | None = None) -> Path:
        """Write the joint table and references as CSV (one row per sample); ``comment`` goes
        first as a ``#`` line (what robot, study and surfaces the table is for)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        cols = self.columns()
        names = list(cols)
        data = np.column_stack([np.asarray(cols[n], dtype=float) for n in names])
        with path.open("w", newline="", encoding="utf-8") as fh:
            if comment:
                fh.write("# " + " ".join(comment.split()) + "\n")
            w = csv.writer(fh)
            w.writerow(names)
            for row in data:
                w.writerow([f"{v:.9g}" for v in row])
        return path


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


def assemble(family: str, t: np.ndarray, leg: LegGeometry, *,
             p_world_pelvis: np.ndarray, p_world_foot_l: np.ndarray, p_world_foot_r: np.ndarray,
             support: np.ndarray, p_world_zmp_ref: np.ndarray | None = None,
             ankle_pitch_offset: np.ndarray | None = None,
             meta: dict | None = None) -> GaitTrajectory:
    """Leg IK on world references -> :class:`GaitTrajectory`.

    ``ankle_pitch_offset`` (N, 2) [rad] (left, right) is added to the ankle
    pitch after the IK, as the EROS heel-strike gait does (eqs 46-47). Without a
    ZMP reference the cart-table ZMP of the CoM is recorded instead.
    """
    t = np.asarray(t, dtype=float)
    n = len(t)
    for name, arr in (("p_world_pelvis", p_world_pelvis), ("p_world_foot_l", p_world_foot_l),
                      ("p_world_foot_r", p_world_foot_r)):
        if np.shape(arr) != (n, 3):
            raise ValueError(f"{name} must have shape ({n}, 3) to match t, got {np.shape(arr)}")
    # The family's pelvis path is where it wants the CoM (horizontally): the pelvis itself is
    # moved by the robot's CoM offset, and each ankle by its sole offset (LegGeometry, ours).
    p_world_pelvis = np.asarray(p_world_pelvis, dtype=float) - np.array([leg.com_forward, leg.com_lateral, 0.0])
    p_world_com = p_world_pelvis + leg.com_in_pelvis
    q = np.zeros((n, len(JOINT_NAMES)))
    q_l = leg_ik(p_world_foot_l - leg.sole_in_ankle(1) - p_world_pelvis, 0.0, leg, "left", t=t)
    q_r = leg_ik(p_world_foot_r - leg.sole_in_ankle(-1) - p_world_pelvis, 0.0, leg, "right", t=t)
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
                          meta=dict(meta or {}))
    if not np.all(np.isfinite(traj.q_ref)):
        raise ValueError(f"{family}: the joint table has non-finite values")
    return traj
