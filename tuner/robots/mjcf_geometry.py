"""What the gait needs to know of a robot, read off its MJCF at the zero pose.

* Joint axes are *lines*: a hinge may be anchored anywhere on its axis, so two axes
  "intersect" when the closest distance between their lines is small
  (:func:`axis_line_distance`), and the hip centre is the point where the hip roll and
  hip pitch lines meet, the ankle centre where the ankle pitch and roll lines meet.
* Thigh and shank are the distances between the parallel pitch axes (hip-knee, knee-ankle).
* The sole is the convex hull of the lowest points of every collision geom of the foot body
  and of the bodies welded to it (cleats, plates): boxes, capsules, cylinders, spheres,
  ellipsoids, meshes; in the foot frame
  (:func:`sole_polygon`).
* The whole-body CoM offset from the torso origin is taken with the legs bent by the IK to a
  walking crouch (:func:`com_offset`): the generators plan the CoM, not the pelvis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import mujoco
import numpy as np

# the walking crouch at which the CoM offset is taken (its angles: the robot side's, gaits)
from gaits.leg_kinematics import CROUCH, crouch_angles

__all__ = ["axis_line_distance", "SolePolygon", "sole_polygon", "com_offset", "body_chain", "leg_masses",
           "foot_geoms", "welded_bodies", "CROUCH", "crouch_angles"]


def axis_line_distance(p1: np.ndarray, a1: np.ndarray, p2: np.ndarray,
                       a2: np.ndarray) -> tuple[float, np.ndarray]:
    """Closest distance [m] between the lines p1 + s a1 and p2 + t a2, and the midpoint of the
    closest points (for parallel lines: the distance, and the midpoint of p1 and its foot on
    line 2). Shapes: points and axes (3,)."""
    a1 = np.asarray(a1, float) / np.linalg.norm(a1)
    a2 = np.asarray(a2, float) / np.linalg.norm(a2)
    p1, p2 = np.asarray(p1, float), np.asarray(p2, float)
    w = p2 - p1
    n = np.cross(a1, a2)
    nn = float(n @ n)
    if nn < 1e-12:                                 # parallel
        perp = w - (w @ a1) * a1
        return float(np.linalg.norm(perp)), p1 + perp / 2
    s = float(np.cross(w, a2) @ n) / nn
    t = float(np.cross(w, a1) @ n) / nn
    c1, c2 = p1 + s * a1, p2 + t * a2
    return float(np.linalg.norm(c1 - c2)), (c1 + c2) / 2


def welded_bodies(model: mujoco.MjModel, body: int) -> list[int]:
    """A body and every descendant joined to it without a joint (cleats, sole plates)."""
    out = [body]
    for b in range(body + 1, model.nbody):
        if model.body_jntnum[b] == 0 and int(model.body_parentid[b]) in out:
            out.append(b)
    return out


def foot_geoms(model: mujoco.MjModel, body: int) -> list[int]:
    """Collision geoms (contype or conaffinity set) of a foot body and the bodies welded to it."""
    bodies = set(welded_bodies(model, body))
    return [g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in bodies
            and (model.geom_contype[g] or model.geom_conaffinity[g])]


def _geom_points(model: mujoco.MjModel, data: mujoco.MjData, g: int) -> np.ndarray:
    """Points on a geom's surface, world frame, dense enough to find its lowest face (K, 3)."""
    c = data.geom_xpos[g]
    R = data.geom_xmat[g].reshape(3, 3)
    size = model.geom_size[g]
    kind = int(model.geom_type[g])
    G = mujoco.mjtGeom
    ring = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    if kind == int(G.mjGEOM_BOX):
        local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * size
    elif kind == int(G.mjGEOM_SPHERE):
        u = np.array([[0, 0, -1], [0, 0, 1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]], float)
        return c + size[0] * u                       # a sphere's lowest point is straight below
    elif kind in (int(G.mjGEOM_CAPSULE), int(G.mjGEOM_CYLINDER)):
        r, h = size[0], size[1]
        ends = []
        for z in (-h, h):
            circle = np.column_stack([r * np.cos(ring), r * np.sin(ring), np.full_like(ring, z)])
            ends.append(circle)
        local = np.vstack(ends)
        if kind == int(G.mjGEOM_CAPSULE):   # hemispherical caps: the lowest points are the caps' lowest
            axis = R[:, 2]
            return np.array([c + z * axis - np.array([0, 0, r]) for z in (-h, h)])
    elif kind == int(G.mjGEOM_ELLIPSOID):
        th, ph = np.meshgrid(np.linspace(0, np.pi, 13), ring)
        u = np.column_stack([(np.sin(th) * np.cos(ph)).ravel(), (np.sin(th) * np.sin(ph)).ravel(),
                             np.cos(th).ravel()])
        local = u * size
    elif kind == int(G.mjGEOM_MESH):
        m = model.geom_dataid[g]
        start, count = model.mesh_vertadr[m], model.mesh_vertnum[m]
        local = model.mesh_vert[start:start + count].astype(float)
    else:                                             # planes, height fields: not a foot
        lo = model.geom_aabb[g][:3] - model.geom_aabb[g][3:]
        hi = model.geom_aabb[g][:3] + model.geom_aabb[g][3:]
        local = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return c + local @ R.T


def _cross2(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def _hull(points: np.ndarray) -> np.ndarray:
    """Convex hull of 2-D points, counter-clockwise, by the monotone chain (M, 2)."""
    pts = np.unique(np.round(points, 9), axis=0)
    if len(pts) < 3:
        return pts
    pts = pts[np.lexsort((pts[:, 1], pts[:, 0]))]

    def half(seq):
        out: list[np.ndarray] = []
        for p in seq:
            while len(out) >= 2 and _cross2(out[-1] - out[-2], p - out[-2]) <= 0:
                out.pop()
            out.append(p)
        return out
    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


@dataclass(frozen=True)
class SolePolygon:
    """A foot's sole: the hull of its collision geoms' lowest points.

    The *sole frame* has its origin at the foot body's origin and the torso's axes at the
    zero pose (x forward, y left, z up), whatever way the foot body's own frame is turned
    (turned onto the sole's plane for a foot tilted at the zero pose: :func:`sole_polygon`).
    """

    hull: np.ndarray            # (M, 2) [m] counter-clockwise, sole-frame x, y
    z: float                    # [m] height of the sole plane in the sole frame
    R_sole_foot: np.ndarray     # (3, 3) foot-frame vectors -> sole-frame vectors
    geoms: tuple[str, ...]      # the collision geoms it came from
    R_torso_sole: np.ndarray = field(default_factory=lambda: np.eye(3))   # sole-frame vectors -> torso frame
    #                             (the identity but for a foot tilted at the zero pose: sole_polygon)

    @property
    def centre_sole(self) -> np.ndarray:
        """Centre of the hull's bounding rectangle (x, y, z) in the sole frame [m]."""
        lo, hi = self.hull.min(axis=0), self.hull.max(axis=0)
        return np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, self.z])

    @property
    def centre(self) -> np.ndarray:
        """The same centre in the foot body's frame [m] (3,)."""
        return self.R_sole_foot.T @ self.centre_sole

    @property
    def size(self) -> tuple[float, float]:
        """Length (x) and width (y) of the hull's bounding rectangle [m]."""
        ext = self.hull.max(axis=0) - self.hull.min(axis=0)
        return float(ext[0]), float(ext[1])


def sole_polygon(model: mujoco.MjModel, data: mujoco.MjData, body: int, R_world_torso: np.ndarray | None = None,
                 tolerance: float = 0.001) -> SolePolygon | None:
    """The sole of a foot body at the current pose (kinematics must be up to date): every
    collision-geom point within ``tolerance`` [m] of the lowest one, as a hull in the sole
    frame (the torso's axes ``R_world_torso``, default the world's). None when the body has
    no collision geom.

    A foot that stands tilted at the zero pose (a team's URDF whose legs are bent there, its sole
    pitched 15 deg) has its sole on another plane (ours): of the torso's z and the foot frame's
    axes, the normal whose lowest points span the largest area (more than twice the torso z's) is
    the sole's, and the sole frame is turned onto it (``R_torso_sole``; x the torso's x on the
    plane)."""
    geoms = foot_geoms(model, body)
    if not geoms:
        return None
    R_t = np.eye(3) if R_world_torso is None else np.asarray(R_world_torso)
    pts = np.vstack([_geom_points(model, data, g) for g in geoms])
    R_foot = data.xmat[body].reshape(3, 3)

    def plane(S: np.ndarray) -> tuple[float, np.ndarray, float]:
        """(area, the lowest points in the frame S (torso axes -> S), their height) along S's z."""
        local = (pts - data.xpos[body]) @ R_t @ S
        low = local[:, 2].min()
        near = local[local[:, 2] <= low + tolerance]
        if len(near) < 3:
            return 0.0, near, low
        hull = _hull(near[:, :2])
        x, y = hull[:, 0], hull[:, 1]
        return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1))), near, low

    best = (np.eye(3),) + plane(np.eye(3))
    for axis in (R_t.T @ R_foot).T:                  # the foot frame's axes, in the torso frame
        for n in (axis, -axis):
            if n[2] < math.cos(math.radians(45)):    # a sole faces down: its normal (up) near the torso's z
                continue
            if n[2] > math.cos(math.radians(1)):     # the torso's own z: tried first
                continue
            x = np.array([1.0, 0.0, 0.0]) - n[0] * n
            x /= np.linalg.norm(x)
            S = np.column_stack([x, np.cross(n, x), n])
            cand = (S,) + plane(S)
            if cand[1] > 2.0 * best[1] and cand[1] > 0.0:
                best = cand
    S, _, near, low = best
    R_sole_foot = S.T @ R_t.T @ R_foot
    names = tuple(mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom#{g}" for g in geoms)
    return SolePolygon(_hull(near[:, :2]), float(low), R_sole_foot, names, S)


def body_chain(model: mujoco.MjModel, body: int) -> list[int]:
    """Bodies from ``body`` up to the world (inclusive of ``body``, exclusive of the world)."""
    out = []
    while body > 0:
        out.append(body)
        body = int(model.body_parentid[body])
    return out


def com_offset(model: mujoco.MjModel, torso: str, leg_q: Mapping[str, float]) -> np.ndarray:
    """Whole-body CoM in the torso frame [m] (3,), at the zero pose but for the joints in
    ``leg_q`` (MJCF joint name -> angle [rad]), typically the legs bent to the walking crouch."""
    d = mujoco.MjData(model)
    for name, value in leg_q.items():
        d.qpos[model.jnt_qposadr[model.joint(name).id]] = value
    mujoco.mj_kinematics(model, d)
    mujoco.mj_comPos(model, d)
    b = model.body(torso).id
    R = d.xmat[b].reshape(3, 3)
    return R.T @ (d.subtree_com[b] - d.xpos[b])


def self_overlaps(model: mujoco.MjModel, poses: list[Mapping[str, float]],
                  depth: float = 1e-4) -> list[tuple[str, str, float]]:
    """Pairs of the robot's bodies whose collision geoms interpenetrate by more than ``depth`` [m]
    in any of ``poses`` (MJCF joint name -> angle [rad], the others at zero), as the file's own
    collision filters leave them: (body1, body2, deepest penetration [m]), sorted by name.

    A real robot cannot stand with its parts inside each other, so such a pair is an artefact of
    the file's shapes (a URDF's meshes are often drawn overlapping at the joints; ROS simulators
    leave a robot's self-collision off by default), and the robot map excludes it (ours)."""
    found: dict[tuple[str, str], float] = {}
    for pose in poses:
        d = mujoco.MjData(model)
        for name, value in pose.items():
            d.qpos[model.jnt_qposadr[model.joint(name).id]] = value
        mujoco.mj_forward(model, d)
        for c in d.contact[:d.ncon]:
            b1, b2 = int(model.geom_bodyid[c.geom1]), int(model.geom_bodyid[c.geom2])
            if b1 == 0 or b2 == 0 or c.dist > -depth:
                continue
            pair = tuple(sorted((model.body(b1).name, model.body(b2).name)))
            found[pair] = max(found.get(pair, 0.0), -float(c.dist))
    return [(a, b, v) for (a, b), v in sorted(found.items())]


def _subtree(model: mujoco.MjModel, body: int) -> list[int]:
    """``body`` and every body below it."""
    children: dict[int, list[int]] = {}
    for c in range(1, model.nbody):
        children.setdefault(int(model.body_parentid[c]), []).append(c)
    out, todo = [], [body]
    while todo:
        b = todo.pop()
        out.append(b)
        todo += children.get(b, [])
    return out


def leg_masses(robot) -> tuple[float, float, float, dict[str, str]]:
    """(upper body, thigh, calf with foot) [kg] of a robot model (means of the two legs), and where
    each came from."""
    model = robot.model()
    total = float(np.sum(model.body_mass))
    thighs, calves = [], []
    for side in ("l_", "r_"):
        # the leg from its first hip joint (the one nearest the torso: yaw on most robots, roll first on some)
        hip = min((model.jnt_bodyid[model.joint(robot.joint_map[side + k][0]).id]
                   for k in ("hip_yaw", "hip_roll", "hip_pitch")), key=lambda b: len(body_chain(model, b)))
        knee = model.jnt_bodyid[model.joint(robot.joint_map[side + "knee"][0]).id]
        leg = set(_subtree(model, hip))
        calf = set(_subtree(model, knee))
        calves.append(float(sum(model.body_mass[b] for b in calf)))
        thighs.append(float(sum(model.body_mass[b] for b in leg - calf)))
    m_t, m_c = float(np.mean(thighs)), float(np.mean(calves))
    upper = total - 2 * (m_t + m_c)
    return upper, m_t, m_c, {
        "mass_upper": f"the model's {total:.3f} kg less both legs (2 x {m_t + m_c:.3f} kg)",
        "mass_thigh": f"the bodies from the first hip joint to the knee, mean of both legs ({', '.join(f'{v:.3f}' for v in thighs)} kg)",
        "mass_calf": f"the bodies from the knee down, foot included, mean of both legs ({', '.join(f'{v:.3f}' for v in calves)} kg)"}
