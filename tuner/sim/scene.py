"""The one adapter between a robot's MJCF and our simulation: the robot on a surface, with our
servos, instruments and grass drag added in a namespace and a default class of their own.

Everything added is named ``gt/...`` and created from the default class ``gt``, whose
actuator, geom and site settings are MuJoCo's own defaults (copied from a fresh element),
so a file's top-level ``<default>`` (a ``ctrlrange``, a ``forcerange``, a contact ``margin``)
never leaks into what we add, and a file's own names (a site called ``imu``) never clash.

What the adapter changes in the file, and why (``robot check`` lists it per robot):

* its ground planes are removed (the surface is ours);
* its actuators are removed: every hinge joint gets our position servo with the numbers the
  robot model carries (by default read from those same actuators, see ``servo.py``), so all
  robots share one servo model with a speed limit; its sensors are removed with them;
* its joints' armature, damping and friction loss are set from the servo model;
* its keyframes get a ``ctrl`` rebuilt for our actuators from their ``qpos`` (the servo
  targets that hold the keyframe's pose), or are dropped when their ``qpos`` no longer fits.

Actuator order: the mapped joints in :data:`gaits.JOINT_NAMES` order, then the map's extra joints, then the held joints,
then the drag dampers. Sensor order: see :class:`SceneLayout`.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np


from ..robots.robot_model import RobotModel
from ..robots.solver import SOLVER_OPTIONS
from ..servos import configure
from .ground import PREFIX, GroundKind, kind_of
from .surfaces import Surface

__all__ = ["PREFIX", "SceneLayout", "build_scene", "CORNERS", "IMU_SITE_POS", "fall_height_at_com"]

#: Sole corners and touch quadrants, (sign x, sign y): toe-left, toe-right, heel-left, heel-right.
CORNERS = ((1, 1), (1, -1), (-1, 1), (-1, -1))
#: [m] the IMU site in the torso frame (axes the torso's)
IMU_SITE_POS = (0.0, 0.0, 0.05)


@dataclass(frozen=True)
class SceneLayout:
    """Where our pieces sit in the compiled model's control and sensor vectors."""

    servo_joints: tuple[str, ...]      # our names of the mapped joints, JOINT_NAMES order, then the extra joints
    held_joints: tuple[str, ...]       # MJCF names of the other actuated joints
    n_drag: int                        # the ground's actuators (on the sole corners; 0 on rigid/carpet)
    sensors: tuple[tuple[str, int], ...]   # (block name, width) in sensordata order
    touch_quadrant: tuple[int, ...]    # per touch sensor, its sole quadrant 0..7 (left 0-3, right 4-7)
    friction_terms: int = 0            # servos with a per-step friction term (native_step.c runs them)
    ground: GroundKind | None = None   # the surface's kind, its points attached (``tuner/sim/ground/``)


def fall_height_at_com(robot: RobotModel) -> bool:
    """Whether the fall check's height is the torso's centre of mass rather than its frame's origin:
    for a torso whose origin lies below its hips (a base frame at the floor, as an Onshape export's),
    whose origin's height says nothing of a fall (ours)."""
    return robot.leg.hip_offset_z < 0.0


def _our_default(spec: mujoco.MjSpec) -> mujoco.MjsDefault:
    """A default class ``gt`` holding MuJoCo's own actuator, geom and site defaults."""
    fresh = mujoco.MjSpec()
    body = fresh.worldbody.add_body()
    pristine = {"actuator": fresh.add_actuator(), "geom": body.add_geom(), "site": body.add_site()}
    ours = spec.add_default(PREFIX + "default", spec.default)
    skip = {"plugin", "classname", "name", "info", "target", "refsite", "slidersite", "userdata",
            "material", "meshname", "hfieldname", "frame", "parent", "id", "signature", "compiler"}
    for kind, element in pristine.items():
        dst = getattr(ours, kind)
        for attr in dir(dst):
            if attr.startswith("_") or attr in skip or not hasattr(element, attr):
                continue
            value = getattr(element, attr)
            if not callable(value):
                setattr(dst, attr, value)
    return ours


def _reset_solver(spec: mujoco.MjSpec) -> None:
    fresh = mujoco.MjSpec()
    for name in SOLVER_OPTIONS:
        setattr(spec.option, name, getattr(fresh.option, name))


def _nq(spec: mujoco.MjSpec) -> int:
    sizes = {mujoco.mjtJoint.mjJNT_FREE: 7, mujoco.mjtJoint.mjJNT_BALL: 4,
             mujoco.mjtJoint.mjJNT_SLIDE: 1, mujoco.mjtJoint.mjJNT_HINGE: 1}
    return sum(sizes[j.type] for j in spec.joints)


def build_scene(robot: RobotModel, surface: Surface) -> tuple[mujoco.MjSpec, SceneLayout]:
    """The editable model of ``robot`` on ``surface`` with our servos, sensors and drag."""
    r, s = robot, surface
    spec = r.spec()
    _reset_solver(spec)
    spec.option.timestep = r.sim.timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    nq = _nq(spec)
    for g in list(spec.worldbody.geoms):           # the robot file's own floor, if any
        if g.type == mujoco.mjtGeom.mjGEOM_PLANE:
            spec.delete(g)
    for a in list(spec.actuators):                 # our servo model replaces the file's actuators
        spec.delete(a)
    for sn in list(spec.sensors):
        spec.delete(sn)
    gt = _our_default(spec)

    ground = kind_of(s)
    ground.add_geoms(spec, gt)

    spec.body(r.torso).add_site(default=gt, name=PREFIX + "imu", pos=list(IMU_SITE_POS))
    depth = s.layer_height + 0.03
    pad = 0.005           # reach past the sole's edge so corner contacts are not lost
    for i, (side, fname) in enumerate(zip("lr", r.feet)):
        fl, fw = r.foot_size_of(i)                # each foot's own sole
        foot = spec.body(fname)
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, np.ascontiguousarray(np.asarray(r.sole_axes[i]).T).ravel())
        foot.add_site(default=gt, name=f"{PREFIX}{side}_sole", pos=list(r.soles[i]), quat=list(quat))
        R_foot_site = np.asarray(r.sole_axes[i]).T
        for k, (sx, sy) in enumerate(CORNERS):    # four quadrants of the sole's bounding box
            offset = [sx * (fl / 4 + pad / 2), sy * (fw / 4 + pad / 2), -depth / 2 + 0.004]
            p_foot = r.sole_points(i, [offset])[0]
            # a touch sensor sees the contacts of its site's body: one site per sole-carrying body
            for j, (bname, R_fb, p_fb) in enumerate(r.touch_bodies(i)):
                q = np.zeros(4)
                mujoco.mju_mat2Quat(q, np.ascontiguousarray(R_fb.T @ R_foot_site).ravel())
                spec.body(bname).add_site(default=gt, name=f"{PREFIX}{side}_touch{k}_{j}",
                                          type=mujoco.mjtGeom.mjGEOM_BOX, pos=list(R_fb.T @ (p_foot - p_fb)),
                                          quat=list(q), size=[fl / 4 + pad / 2, fw / 4 + pad / 2, depth / 2 + 0.004],
                                          group=4)

    servo_joints = r.servo_joints                 # the roles in JOINT_NAMES order, then the extra joints
    held = r.held_joints
    targets = [r.joint_map[n][0] for n in servo_joints] + list(held)
    friction_terms = 0
    for theirs, label in zip(targets, [f"servo/{n}" for n in servo_joints] + [f"hold/{h}" for h in held]):
        act = spec.add_actuator(default=gt, name=PREFIX + label, target=theirs, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        friction_terms += configure(spec, spec.joint(theirs), act, r.servos[theirs])

    # the ground's part at each sole corner (its kind's actuators)
    n_drag = 0
    if ground.on_points:
        for i, (side, fname) in enumerate(zip("lr", r.feet)):
            foot = spec.body(fname)
            fl, fw = r.foot_size_of(i)            # each foot's own sole (the simulator's gate uses it)
            for k, (sx, sy) in enumerate(CORNERS):
                site = f"{PREFIX}{side}_corner{k}"
                foot.add_site(default=gt, name=site, pos=list(r.sole_points(i, [[sx * fl / 2, sy * fw / 2, 0.0]])[0]),
                              group=4)
                n_drag += ground.attach(spec, gt, site, f"{side}{k}")
    spec.nuserdata += ground.user_slots           # after the file's own (the native gate's numbers)

    # sensors, in this order
    S, O = mujoco.mjtSensor, mujoco.mjtObj
    add = spec.add_sensor
    blocks = []

    def sensor(block: str, width: int, **kw) -> None:
        add(**kw)
        if blocks and blocks[-1][0] == block:
            blocks[-1] = (block, blocks[-1][1] + width)
        else:
            blocks.append((block, width))
    sensor("quat", 4, name=PREFIX + "imu_quat", type=S.mjSENS_FRAMEQUAT, objtype=O.mjOBJ_SITE, objname=PREFIX + "imu")
    sensor("pos", 3, name=PREFIX + "imu_pos", type=S.mjSENS_FRAMEPOS, objtype=O.mjOBJ_SITE, objname=PREFIX + "imu")
    sensor("com", 3, name=PREFIX + "com", type=S.mjSENS_SUBTREECOM, objtype=O.mjOBJ_BODY, objname=r.torso)
    for side in "lr":
        sensor("sole", 3, name=f"{PREFIX}{side}_sole_pos", type=S.mjSENS_FRAMEPOS, objtype=O.mjOBJ_SITE,
               objname=f"{PREFIX}{side}_sole")
    touch_quadrant = []                     # which of the 8 quadrants each touch sensor adds to
    for i, side in enumerate("lr"):
        for k in range(4):
            for j in range(len(r.touch_bodies(i))):
                sensor("touch", 1, name=f"{PREFIX}{side}_touch{k}_{j}", type=S.mjSENS_TOUCH, objtype=O.mjOBJ_SITE,
                       objname=f"{PREFIX}{side}_touch{k}_{j}")
                touch_quadrant.append(4 * i + k)
            force = ground.point_force(f"{side}{k}")
            if force is not None:                 # the ground carries the sole without a contact: the
                # quadrant's force sensor reads its corner's support (a real sole's sensor would)
                sensor("touch", 1, name=f"{PREFIX}{side}_ground{k}", type=S.mjSENS_ACTUATORFRC,
                       objtype=O.mjOBJ_ACTUATOR, objname=force)
                touch_quadrant.append(4 * i + k)
    for side in "lr":
        for k in range(4):
            sensor("touchpos", 3, name=f"{PREFIX}{side}_touch{k}_pos", type=S.mjSENS_FRAMEPOS,
                   objtype=O.mjOBJ_SITE, objname=f"{PREFIX}{side}_touch{k}_0")
    for ours in servo_joints:
        sensor("q", 1, name=f"{PREFIX}q/{ours}", type=S.mjSENS_ACTUATORPOS, objtype=O.mjOBJ_ACTUATOR,
               objname=f"{PREFIX}servo/{ours}")
    for ours in servo_joints:
        sensor("dq", 1, name=f"{PREFIX}dq/{ours}", type=S.mjSENS_ACTUATORVEL, objtype=O.mjOBJ_ACTUATOR,
               objname=f"{PREFIX}servo/{ours}")
    for ours in servo_joints:
        sensor("tau", 1, name=f"{PREFIX}tau/{ours}", type=S.mjSENS_ACTUATORFRC, objtype=O.mjOBJ_ACTUATOR,
               objname=f"{PREFIX}servo/{ours}")
    # ground truth for the fall check (ours): the torso body's frame z axis and origin, copies of
    # MuJoCo's xmat and xpos, so a rollout run natively (``mujoco.rollout``) is judged on the same numbers;
    # a torso whose origin lies below its hips (a base frame at the floor, as an Onshape export's) is
    # judged by its centre of mass instead: its origin's height says nothing of a fall
    low_origin = fall_height_at_com(r)
    sensor("fall", 3, name=PREFIX + "torso_zaxis", type=S.mjSENS_FRAMEZAXIS, objtype=O.mjOBJ_XBODY, objname=r.torso)
    sensor("fall", 3, name=PREFIX + "torso_origin", type=S.mjSENS_FRAMEPOS,
           objtype=O.mjOBJ_BODY if low_origin else O.mjOBJ_XBODY, objname=r.torso)

    # keyframes: ctrl rebuilt from qpos (the targets that hold the pose), or dropped
    adr = {}
    i = 0
    for jt in spec.joints:
        adr[jt.name] = i
        i += {mujoco.mjtJoint.mjJNT_FREE: 7, mujoco.mjtJoint.mjJNT_BALL: 4}.get(jt.type, 1)
    for key in list(spec.keys):
        qpos = np.array(key.qpos)
        if len(qpos) not in (0, nq):
            spec.delete(key)
            continue
        if len(qpos) == 0:
            ctrl = [0.0] * len(targets)
        else:
            ctrl = [float(qpos[adr[t]]) for t in targets]
        key.ctrl = ctrl + [0.0] * n_drag
        key.act = []
    return spec, SceneLayout(servo_joints, held, n_drag, tuple(blocks), tuple(touch_quadrant), friction_terms, ground)


#: The push-recovery challenge's pendulum (RoboCup Humanoid League, technical challenges, Part A,
#: KidSize): a 1 kg bottle with up to 1 cm of foam on a rope. Ours: a 1 L PET bottle, 8 cm across
#: and 25 cm long, as a capsule; the foam as a soft contact (a 15 ms time constant).
BOTTLE_MASS = 1.0          # [kg] the 2019 rules' bottle
BOTTLE_RADIUS = 0.045      # [m] the bottle (4 cm) and its foam (<= 1 cm)
BOTTLE_LENGTH = 0.25       # [m]
FOAM_TIMECONST = 0.015     # [s]


@dataclass(frozen=True)
class Bottle:
    """The challenge's bottle: its mass [kg], the capsule's radius (foam included) and length [m];
    ``centred``: the rope is measured to its centre of mass (the 2025 rules; the 2019 bottle hangs
    from its top end, as this tool has always hung it)."""

    mass: float
    radius: float
    length: float
    centred: bool = True


#: the 2019 rules' 1 kg bottle, as the tool simulated it
BOTTLE_2019 = Bottle(BOTTLE_MASS, BOTTLE_RADIUS, BOTTLE_LENGTH, centred=False)
#: the 2025 rules' bottles (3 kg the default): water bottles of that volume, sizes ours (a capsule
#: of 3.3, 5.1 and 10.2 litres, 1 cm of foam included in the radius)
BOTTLES = {3: Bottle(3.0, 0.060, 0.33), 5: Bottle(5.0, 0.070, 0.38), 10: Bottle(10.0, 0.090, 0.46)}


def add_pendulum(spec: mujoco.MjSpec, rope: float, bottle_spec: Bottle = BOTTLE_2019) -> None:
    """The challenge's pendulum in the scene: a mocap pivot (``gt/pivot``, placed before each push)
    and the bottle hanging ``rope`` [m] below it on a ball joint (``gt/rope``), the bottle's axis
    along the rope (its centre ``rope`` below the pivot when ``centred``, else its top end). It
    touches only the robot (not the ground, its own contacts excluded)."""
    pivot = spec.worldbody.add_body(name=PREFIX + "pivot", mocap=True, pos=[0.0, 0.0, 5.0])
    bottle = pivot.add_body(name=PREFIX + "bottle", pos=[0.0, 0.0, 0.0])
    bottle.add_joint(name=PREFIX + "rope", type=mujoco.mjtJoint.mjJNT_BALL, damping=0.0)
    b = bottle_spec
    half = b.length / 2 - b.radius
    top = -rope + half if b.centred else -rope
    g = bottle.add_geom(name=PREFIX + "bottle", type=mujoco.mjtGeom.mjGEOM_CAPSULE,
                        fromto=[0, 0, top, 0, 0, top - 2 * half], size=[b.radius, 0, 0],
                        mass=b.mass, rgba=[0.9, 0.5, 0.1, 1.0])
    g.solref = [FOAM_TIMECONST, 1.0]
    g.contype = 2              # collides with the robot's geoms (contype 1), not with the ground planes
    g.conaffinity = 1
    g.friction = [0.3, 0.005, 0.0001]
