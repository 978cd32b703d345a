"""The sports-turf test methods, simulated on our surfaces: the (Advanced) Artificial Athlete drop
test and the rotational resistance test, each on the same ground the robot walks on
(its kind of ground, ``tuner/sim/ground/``: the layer's drag or the blade layer on the test foot's
points as on a sole's corners), so a team can hold our layers against what turf
makers and test houses publish.

**Drop test** (EN 14808 / FIFA Test Method 04a and 05a, the Advanced Artificial Athlete, as we
read them): a 20 kg mass falls 55 mm onto a spring of 2000 N/mm that stands on a 70 mm test
foot resting on the surface. The mass carries an accelerometer; the method computes

* the force F(t) = m a_s(t), a_s the accelerometer's specific force (gravity included), and
  **force reduction** FR = (1 - F_max / F_ref) x 100 %, F_ref = 6760 N the concrete reference
  (a 20 kg mass dropped 55 mm onto a 2 MN/m spring on a rigid floor peaks at
  m g + sqrt((m g)^2 + 2 m g h k) = 6769 N: :func:`rigid_peak_force`);
* the mass's displacement s(t), twice integrated from the impact speed sqrt(2 g h), minus the
  spring's compression F / k: the surface's deformation; its maximum is the **vertical
  deformation** [mm];
* **energy restitution** (ours, reading ASTM F3189's definition of the surface's loop): the
  work the surface gives back while its deformation shrinks over the work it took while it grew,
  both as the integral of F over the deformation, x 100 %.

The simulated impact starts with the mass touching the unloaded spring at the impact speed
(the 55 mm of free fall are not stepped) and ends when the spring is unloaded again (the mass
leaves it). Ours, where the methods leave it to the apparatus: the test foot is a flat 70 mm
disc of 0.1 kg (the real foot's base is a 500 mm sphere cap; its mass is not in our sources),
guided vertically; the accelerometer's signal is low-passed at 250 Hz (2nd-order Butterworth,
run both ways), which removes the foot's ringing on the stiff spring and keeps the mass's
bounce (the concrete reference comes out within 0.5 %: tested); the rig steps at 0.1 ms (the
robot's simulation at 2 ms; the surface's contact numbers are the same at both: none of our time
constants is near MuJoCo's 2-step floor).

**Rotational resistance** (EN 15301-1 / FIFA Test Method 06, as we read them): a studded test
disc of 150 mm, six studs on a 46 mm circle, loaded to 46 kg in all, set onto the surface from
60 mm, then turned at 12 rev/min (72 deg/s) through 45 deg or more; the peak torque [N m]. Our
studs: cylinders 13 mm across and 13 mm long with a rounded tip that makes the contact (the
stud's size is not in our sources; ours: flat cylinder ends chatter on MuJoCo's planes, and the
torque followed the time step); the layer acts on each stud's tip as on a sole corner; the turn
is a velocity servo reaching 72 deg/s in 50 ms, and the torque reported is the surface's on the
disc (its contacts' and its layer's generalised force on the turn, not the servo's, which also
accelerates the disc), averaged over 50 ms as a wrench's needle shows it.

**Scale** (why the test cannot tell all about a robot foot): the drop test presses its 70 mm
foot with 196 N at rest, ~51 kPa, and peaks near 6.8 kN; a 5 kg kid-size robot presses one 10 x 6
cm sole with ~49 N, ~8 kPa. The robot-scale figures: :func:`sole_sink` (the depth a robot's sole
settles at, at rest, under its weight), :func:`sole_resistance` (a sole held in the blades and
slid or turned) and :func:`sole_roll_stiffness` (how stiffly one sole carrying the robot is held
against rolling: below m g h a robot with still ankles topples sideways in single support).

MuJoCo's soft contact sets an *acceleration* stiffness (``solref``), so a heavier body sinks as
far as a light one: the layers' drop-test figures describe them under 20 kg, not a robot's foot;
:func:`sole_sink` and the drop test disagree for that reason, and docs/simulation.md says so.

Sources for the numbers (cited in docs/simulation.md): FIFA Quality Programme for Football Turf,
Handbook of Test Methods (October 2015 edition) and of Requirements; EN 14808, EN 14809,
EN 15301-1, EN 15330-1; ASTM F3189 (the Advanced Artificial Athlete); McGowan et al., Sports
Engineering 2023 (rotational traction testers' 72 deg/s and 30 deg/s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import mujoco
import numpy as np

from gaits.trajectory import GRAVITY

from .ground import PREFIX, kind_of
from .surfaces import Surface

__all__ = ["DropTest", "RotationTest", "SpringGround", "DropResult", "RotationResult", "drop_test",
           "rotation_test", "sole_sink", "sole_resistance", "sole_roll_stiffness", "rigid_peak_force", "BANDS",
           "WEBOTS_GRASS", "webots_ground"]


#: Published bands for football turf, (low, high): FIFA's two marks (FIFA Quality / Quality Pro,
#: formerly one and two stars). Energy restitution: no band found in the sources we could read.
BANDS = {
    "force_reduction_pct": {"FIFA Quality": (55.0, 70.0), "FIFA Quality Pro": (60.0, 70.0)},
    "vertical_deformation_mm": {"FIFA Quality": (4.0, 11.0), "FIFA Quality Pro": (4.0, 10.0)},
    "energy_restitution_pct": {},
    "rotational_torque_Nm": {"FIFA Quality": (25.0, 50.0), "FIFA Quality Pro": (30.0, 45.0)},
}


@dataclass(frozen=True)
class DropTest:
    """The Artificial Athlete's numbers (SI)."""

    mass: float = 20.0             # [kg] falling mass
    drop: float = 0.055            # [m] free fall onto the spring
    spring: float = 2.0e6          # [N/m] 2000 N/mm
    foot_diameter: float = 0.070   # [m]
    foot_mass: float = 0.1         # [kg] ours (not in our sources)
    filter_hz: float = 250.0       # [Hz] the accelerometer's low-pass (ours: 2nd order, both ways)
    reference_force: float = 6760.0  # [N] the published concrete reference
    timestep: float = 1e-4         # [s] ours
    settle: float = 0.5            # [s] the foot settles on the surface before the impact (ours)


@dataclass(frozen=True)
class RotationTest:
    """The rotational resistance test's numbers (SI)."""

    mass: float = 46.0             # [kg] disc, shaft and weights
    disc_diameter: float = 0.150   # [m]
    studs: int = 6
    stud_circle: float = 0.046     # [m] radius of the studs' circle
    stud_diameter: float = 0.013   # [m] ours
    stud_length: float = 0.013     # [m] ours
    drop: float = 0.060            # [m] set onto the surface from this height
    speed: float = math.radians(72.0)  # [rad/s] 12 rev/min
    turn: float = math.radians(60.0)   # [rad] turned this far (the method: 45 deg or more)
    timestep: float = 5e-4         # [s] ours
    settle: float = 0.5            # [s] after the drop, before the turn (ours)


@dataclass(frozen=True)
class SpringGround:
    """A ground that is a spring and damper of known rates under the test foot (one contact point,
    no layer): the methods' hand check, and the Webots grass the virtual league walks on."""

    name: str
    stiffness: float               # [N/m]
    damping: float = 0.0           # [N s/m]
    friction: float = 0.5
    description: str = ""


@dataclass
class DropResult:
    surface: str
    force_max_N: float
    force_reduction_pct: float
    vertical_deformation_mm: float
    energy_restitution_pct: float
    static_pressure_kPa: float
    t: np.ndarray = field(repr=False, default=None)
    force: np.ndarray = field(repr=False, default=None)
    deformation: np.ndarray = field(repr=False, default=None)
    foot_sink: np.ndarray = field(repr=False, default=None)   # ground truth: the foot's own travel [m]


@dataclass
class RotationResult:
    surface: str
    rotational_torque_Nm: float
    sink_mm: float


def rigid_peak_force(t: DropTest = DropTest(), spring: float | None = None) -> float:
    """Peak force [N] of the drop on a spring of rate ``spring`` (default the test's) on a rigid
    floor, massless spring and foot: energy m g (h + x) = k x^2 / 2 at the deepest point."""
    k = t.spring if spring is None else spring
    w = t.mass * GRAVITY
    return w + math.sqrt(w * w + 2.0 * w * t.drop * k)


def webots_ground(erp: float = 0.2, cfm: float = 0.03, dt: float = 0.008, friction: float = 0.5) -> SpringGround:
    """The official virtual humanoid league's grass (Webots ``ContactProperties``: friction 0.5,
    softCFM 0.03, its default softERP 0.2, 8 ms steps) as the spring and damper of one ODE contact:
    ODE's ERP = h k / (h k + c) and CFM = 1 / (h k + c) give k = ERP / (h CFM), c = (1 - ERP) / CFM."""
    return SpringGround("webots-grass", erp / (dt * cfm), (1.0 - erp) / cfm, friction,
                        f"Webots grass of the virtual humanoid league: friction {friction:g}, softCFM {cfm:g}, "
                        f"softERP {erp:g}, {dt * 1000:g} ms steps: {erp / (dt * cfm):.0f} N/m and "
                        f"{(1.0 - erp) / cfm:.1f} N s/m per contact point")


WEBOTS_GRASS = webots_ground()


def _base_spec(timestep: float) -> tuple[mujoco.MjSpec, mujoco.MjsDefault]:
    spec = mujoco.MjSpec()
    spec.option.timestep = timestep
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    return spec, spec.default


#: [s] how often the rigs update the ground's per-point part (ours; the robot's simulation: every
#: control tick, 10 ms)
GROUND_TICK = 0.002


class _Points:
    """The ground on a rig, as under the robot: its kind's geoms (``tuner/sim/ground/``), and its
    per-point part (a contact layer's drag, or the blade layer) on the given sites, each standing
    for its ``area`` of sole. Call :meth:`bind` once the rig is compiled and :meth:`tick` every 2 ms
    (the rigs' choice; the robot's simulation does it every 10 ms tick)."""

    def __init__(self, spec: mujoco.MjSpec, ground: Surface, gt, sites: list[str], areas: list[float]) -> None:
        self.ground = kind_of(ground)
        self.ground.add_geoms(spec, gt)
        self.areas = np.asarray(areas, dtype=float)
        if self.ground.on_points:
            for i, site in enumerate(sites):
                self.ground.attach(spec, gt, site, f"p{i}")

    @property
    def first(self) -> int:
        """The first of the ground's actuators (they come after the rig's own)."""
        return self.ground.first

    def bind(self, m: mujoco.MjModel) -> None:
        self.ground.bind(m, self.areas, GROUND_TICK)
        self.ground.reset()

    def tick(self, m: mujoco.MjModel, d: mujoco.MjData) -> None:
        if self.ground.python_tick:
            self.ground.tick(m, d)


def _drop_rig(ground: Surface | SpringGround, t: DropTest, with_mass: bool) -> tuple[mujoco.MjModel, _Points | None]:
    """The rig: the test foot on a vertical slide joint (``gt/foot_z``: on a spring ground its rest
    length is z = 0), and with ``with_mass`` the falling mass on a slide joint inside it
    (``gt/spring``, the spring's compression, stiffness the test's) carrying the accelerometer."""
    spec, gt = _base_spec(t.timestep)
    r = t.foot_diameter / 2
    spring_ground = isinstance(ground, SpringGround)
    foot = spec.worldbody.add_body(name=PREFIX + "foot", pos=[0, 0, 0.0 if spring_ground else 0.11])
    foot.add_joint(name=PREFIX + "foot_z", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1])
    g = foot.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[r, 0.005, 0], pos=[0, 0, 0.005],
                      mass=t.foot_mass)
    if spring_ground:
        g.contype = 0
        g.conaffinity = 0
    foot.add_site(name=PREFIX + "foot_point", pos=[0, 0, 0])
    if with_mass:
        mass = foot.add_body(name=PREFIX + "mass", pos=[0, 0, 0.05])
        spring = mass.add_joint(name=PREFIX + "spring", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1])
        spring.stiffness = [t.spring, 0.0, 0.0]
        mg = mass.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[0.05, 0.03, 0], pos=[0, 0, 0.03],
                           mass=t.mass)
        mg.contype = 0
        mg.conaffinity = 0
        mass.add_site(name=PREFIX + "accel")
        spec.add_sensor(name=PREFIX + "accel", type=mujoco.mjtSensor.mjSENS_ACCELEROMETER,
                        objtype=mujoco.mjtObj.mjOBJ_SITE, objname=PREFIX + "accel")
    points = None
    if spring_ground:                  # the ground under the foot: a spring on its slide joint
        j = spec.joint(PREFIX + "foot_z")
        j.stiffness = [ground.stiffness, 0.0, 0.0]      # MuJoCo 4: [linear, ...] terms
        j.damping = [ground.damping, 0.0, 0.0]
    else:
        points = _Points(spec, ground, gt, [PREFIX + "foot_point"], [math.pi * r * r])
    m = spec.compile()
    if points is not None:
        points.bind(m)
    return m, points


def drop_test(ground: Surface | SpringGround, t: DropTest = DropTest()) -> DropResult:
    """The drop test on ``ground`` (module docstring), every figure from the mass's accelerometer.

    The foot first settles alone (the mass off the spring, as the apparatus holds it before the
    release); then the mass touches the unloaded spring at the impact speed; the run ends when the
    spring is unloaded again."""
    tick = max(1, int(round(GROUND_TICK / t.timestep)))
    # the apparatus puts its foot on the surface: it settles without a jam (a blade layer's, which
    # a foot let fall onto it would meet)
    placed = kind_of(ground).at_rest() if isinstance(ground, Surface) else ground
    alone, pts0 = _drop_rig(placed, t, with_mass=False)
    d0 = mujoco.MjData(alone)
    for n in range(int(round(t.settle / t.timestep))):
        if n % tick == 0 and pts0 is not None:
            mujoco.mj_kinematics(alone, d0)
            pts0.tick(alone, d0)
        mujoco.mj_step(alone, d0)
    m, pts = _drop_rig(ground, t, with_mass=True)
    if pts is not None:                        # the ground under the foot as the settling left it
        pts.ground.carry_over(pts0.ground)
    d = mujoco.MjData(m)
    jf, js = m.joint(PREFIX + "foot_z").qposadr[0], m.joint(PREFIX + "spring").qposadr[0]
    vf, vs = m.joint(PREFIX + "foot_z").dofadr[0], m.joint(PREFIX + "spring").dofadr[0]
    d.qpos[jf], d.qvel[vf] = d0.qpos[0], d0.qvel[0]
    v0 = math.sqrt(2.0 * GRAVITY * t.drop)
    d.qvel[vs] = -v0 - d.qvel[vf]                 # the mass's own speed: v0 downward
    mujoco.mj_forward(m, d)
    ts, fs, zs = [0.0], [0.0], [0.0]
    z0 = float(d.qpos[jf])
    for n in range(1, int(round(3.0 / t.timestep))):        # at most 3 s (the softest ground: ~1 s)
        if (n - 1) % tick == 0 and pts is not None:
            pts.tick(m, d)
        mujoco.mj_step(m, d)
        ts.append(n * t.timestep)
        fs.append(t.mass * float(d.sensordata[2]))   # the accelerometer's specific force along z
        zs.append(z0 - float(d.qpos[jf]))
        if float(d.qpos[js]) >= 0.0 and d.qvel[vf] + d.qvel[vs] > 0.0:   # unloaded, the mass rising: it leaves
            break
    t_arr = np.array(ts)
    # the instrument's low-pass (zero phase): the test foot rings on the spring (~700 Hz with our
    # 0.1 kg foot) far above the mass's own bounce (50 Hz on concrete, slower on a surface)
    from scipy.signal import butter, filtfilt
    b, a = butter(2, t.filter_hz, fs=1.0 / t.timestep)
    f_arr = filtfilt(b, a, np.array(fs), padlen=min(len(fs) - 1, 3 * max(len(a), len(b))))
    # the method: the mass's velocity and displacement integrated from its accelerometer
    acc = f_arr / t.mass - GRAVITY                      # [m/s^2] upward positive
    vel = -v0 + np.concatenate([[0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1]) * np.diff(t_arr))])
    pos = np.concatenate([[0.0], np.cumsum(0.5 * (vel[1:] + vel[:-1]) * np.diff(t_arr))])
    deformation = -pos - f_arr / t.spring                # the surface's, downward positive
    fmax = float(f_arr.max())
    dd = np.diff(deformation)
    fm = 0.5 * (f_arr[1:] + f_arr[:-1])
    work_in = float(np.sum(np.where(dd > 0, fm * dd, 0.0)))
    work_out = float(-np.sum(np.where(dd < 0, fm * dd, 0.0)))
    area = math.pi * (t.foot_diameter / 2) ** 2
    return DropResult(ground.name, fmax, 100.0 * (1.0 - fmax / t.reference_force),
                      1000.0 * float(deformation.max()),
                      100.0 * work_out / work_in if work_in > 0 else float("nan"),
                      (t.mass + t.foot_mass) * GRAVITY / area / 1000.0, t_arr, f_arr, deformation, np.array(zs))


def rotation_test(ground: Surface | SpringGround, t: RotationTest = RotationTest()) -> RotationResult:
    """The rotational resistance test on ``ground`` (module docstring): the peak torque of the
    turning servo [N m] and how deep the studs' tips sat when the turn began [mm]. On a
    :class:`SpringGround` (one contact point: nothing for the studs to enter) the torque is
    Coulomb friction at the stud tips, friction x weight x the studs' radius, and the sink the
    spring's static deflection under the whole weight."""
    if isinstance(ground, SpringGround):      # Coulomb friction at the six stud tips, as ODE has it
        return RotationResult(ground.name, ground.friction * t.mass * GRAVITY * t.stud_circle,
                              1000.0 * t.mass * GRAVITY / ground.stiffness)
    spec, gt = _base_spec(t.timestep)
    h = ground.layer_height
    disc = spec.worldbody.add_body(name=PREFIX + "disc", pos=[0, 0, h + t.stud_length + t.drop])
    disc.add_joint(name=PREFIX + "foot_z", type=mujoco.mjtJoint.mjJNT_SLIDE, axis=[0, 0, 1])
    disc.add_joint(name=PREFIX + "turn", type=mujoco.mjtJoint.mjJNT_HINGE, axis=[0, 0, 1])
    plate = disc.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[t.disc_diameter / 2, 0.005, 0],
                          pos=[0, 0, 0.005], mass=t.mass - t.studs * 0.01)
    plate.contype = 0
    plate.conaffinity = 0
    sites = []
    for i in range(t.studs):
        a = 2 * math.pi * i / t.studs
        x, y = t.stud_circle * math.cos(a), t.stud_circle * math.sin(a)
        # the stud's shank (drawn, no contact) and its rounded tip (the contact: one point a stud)
        shank = disc.add_geom(type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[t.stud_diameter / 2, t.stud_length / 2, 0],
                              pos=[x, y, -t.stud_length / 2], mass=0.005)
        shank.contype = 0
        shank.conaffinity = 0
        disc.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[t.stud_diameter / 2, 0, 0],
                      pos=[x, y, -t.stud_length + t.stud_diameter / 2], mass=0.005)
        sites.append(f"{PREFIX}stud{i}")
        disc.add_site(name=sites[-1], pos=[x, y, -t.stud_length])
    turn = spec.add_actuator(name=PREFIX + "turn", target=PREFIX + "turn", trntype=mujoco.mjtTrn.mjTRN_JOINT)
    turn.set_to_velocity(kv=2000.0)
    pts = _Points(spec, ground, gt, sites, [math.pi * (t.disc_diameter / 2) ** 2 / t.studs] * t.studs)
    m = spec.compile()
    pts.bind(m)
    d = mujoco.MjData(m)
    dof = m.joint(PREFIX + "turn").dofadr[0]
    stud_ids = np.array([m.site(s).id for s in sites], dtype=int)
    nstep = max(1, int(round(GROUND_TICK / t.timestep)))     # the ground's tick (_Points)
    n_settle = int(round(t.settle / t.timestep))
    n_turn = int(round(t.turn / t.speed / t.timestep))
    torque = []
    sink = 0.0
    for n in range(n_settle + n_turn):
        if n % nstep == 0:
            pts.tick(m, d)
        if n == n_settle:
            sink = 1000.0 * (h - float(np.mean(d.site_xpos[stud_ids, 2])))
        d.ctrl[0] = t.speed * min(1.0, (n - n_settle) * t.timestep / 0.05) if n >= n_settle else 0.0
        mujoco.mj_step(m, d)
        if n >= n_settle:       # the surface's torque on the disc: its contacts and its drag
            torque.append(float(d.qfrc_constraint[dof] + d.qfrc_actuator[dof] - d.actuator_force[0]))
    # the peak of the torque as a wrench's needle shows it: averaged over 50 ms (ours; the
    # simulated disc hops on its studs as it slides, and the raw torque spikes with the time step)
    w = max(1, int(round(0.05 / t.timestep)))
    tq = np.abs(np.array(torque))
    avg = np.convolve(tq, np.ones(w) / w, mode="valid") if len(tq) >= w else tq
    return RotationResult(ground.name, float(avg.max()) if len(avg) else 0.0, sink)


_SLIDE, _HINGE = mujoco.mjtJoint.mjJNT_SLIDE, mujoco.mjtJoint.mjJNT_HINGE
_AXES = {"x": (_SLIDE, [1, 0, 0]), "y": (_SLIDE, [0, 1, 0]), "z": (_SLIDE, [0, 0, 1]),
         "roll": (_HINGE, [1, 0, 0]), "yaw": (_HINGE, [0, 0, 1])}


def _sole_rig(ground: Surface, joints: tuple[str, ...], mass: float, sole: tuple[float, float], z0: float,
              timestep: float, actuated: dict | None = None) -> tuple[mujoco.MjModel, mujoco.MjData, _Points]:
    """A flat sole (a box ``sole`` [m] long and wide, ``mass`` [kg]) on ``joints`` (names of
    :data:`_AXES`, ``gt/<name>``), its bottom ``z0`` [m] above the soil, its four corners standing
    each for a quarter of it, as the robot's (the layer's drag or the blades act there); with
    ``actuated``: {joint: "velocity" | "position" | "motor"} servos on those joints, in that order."""
    spec, gt = _base_spec(timestep)
    body = spec.worldbody.add_body(name=PREFIX + "sole", pos=[0, 0, z0])
    for name in joints:
        kind, axis = _AXES[name]
        j = body.add_joint(name=f"{PREFIX}{name}", type=kind, axis=axis)
        if name == "roll":
            j.damping = [1.0, 0.0, 0.0]
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=[sole[0] / 2, sole[1] / 2, 0.004], pos=[0, 0, 0.004],
                  mass=mass)
    for name, kind in (actuated or {}).items():
        act = spec.add_actuator(name=f"{PREFIX}{name}", target=f"{PREFIX}{name}", trntype=mujoco.mjtTrn.mjTRN_JOINT)
        if kind == "velocity":
            act.set_to_velocity(kv=5000.0)
        elif kind == "position":
            act.set_to_position(kp=1e5, kv=2000.0)
    sites = []
    for k, (sx, sy) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        sites.append(f"{PREFIX}corner{k}")
        body.add_site(name=sites[-1], pos=[sx * sole[0] / 2, sy * sole[1] / 2, 0.0])
    pts = _Points(spec, ground, gt, sites, [sole[0] * sole[1] / 4] * 4)
    m = spec.compile()
    pts.bind(m)
    return m, mujoco.MjData(m), pts


def _run(m: mujoco.MjModel, d: mujoco.MjData, pts: _Points, n: int, ctrl=None, after=None) -> None:
    """Step the rig ``n`` times, the ground ticking every 2 ms; ``ctrl(i)`` gives the actuators'
    controls before step i, ``after(i)`` reads after it."""
    tick = max(1, int(round(GROUND_TICK / m.opt.timestep)))
    for i in range(n):
        if i % tick == 0:
            mujoco.mj_kinematics(m, d)
            pts.tick(m, d)
        if ctrl is not None:
            k = pts.first if pts.ground.n_actuators else m.nu
            d.ctrl[:k] = ctrl(i)
        mujoco.mj_step(m, d)
        if after is not None:
            after(i)


def sole_sink(ground: Surface, *, mass: float = 4.95, sole: tuple[float, float] = (0.10, 0.06),
              timestep: float = 0.002, settle: float = 1.0, speed: float = 0.0) -> float:
    """Robot scale: the depth [mm] below the blade tips at which a flat sole of ``sole`` (length,
    width) [m] carrying ``mass`` [kg] (the built-in robot's weight on one foot) settles at rest,
    on the robot's own 2 ms step: let down from 2 mm above the tips, or with ``speed`` > 0 [m/s]
    moving down at that speed from 0.5 mm above them (a landing: a layer with a jam holds a fast
    one near the tips, ``blades.py``)."""
    h = ground.layer_height
    m, d, pts = _sole_rig(ground, ("z",), mass, sole, h + (0.0005 if speed > 0.0 else 0.002), timestep)
    d.qvel[0] = -speed
    _run(m, d, pts, int(round(settle / timestep)))
    return 1000.0 * (h - float(d.xpos[m.body(PREFIX + "sole").id, 2]))


def sole_resistance(ground: Surface, *, depth: float, motion: str = "slide", speed: float = 0.1,
                    sole: tuple[float, float] = (0.10, 0.06), timestep: float = 0.002,
                    duration: float = 0.3) -> float:
    """Robot scale: a 10 x 6 cm sole held ``depth`` [m] below the blade tips and moved through the
    layer, sideways at ``speed`` [m/s] (``motion`` "slide") or turned about its centre at ``speed``
    [rad/s] ("turn"): the mean resistance over the last half of the move, [N] or [N m]. The
    layer's drag (or its blades) act on the sole's four corners as on the robot's; the sole has no
    vertical freedom (it sits exactly at that depth) and stiff position servos hold its other
    axes, so this is the layer's share alone."""
    h = ground.layer_height
    moving = "y" if motion == "slide" else "yaw"
    joints = ("x", "y", "yaw")
    servos = {j: ("velocity" if j == moving else "position") for j in joints}
    m, d, pts = _sole_rig(ground, joints, 1.0, sole, h - depth, timestep, servos)
    target = np.zeros(len(joints))
    target[joints.index(moving)] = speed
    dof, act = m.joint(PREFIX + moving).dofadr[0], joints.index(moving)
    n = int(round(duration / timestep))
    out: list[float] = []

    def read(i: int) -> None:
        if i >= n // 2:            # the layer's force on the moving joint: contacts, drag or blades
            layer_act = float(d.qfrc_actuator[dof] - d.actuator_force[act])
            out.append(-(float(d.qfrc_constraint[dof]) + layer_act))
    _run(m, d, pts, n, ctrl=lambda i: target, after=read)
    return float(np.mean(out))


def sole_roll_stiffness(ground: Surface, *, mass: float = 4.95, torque: float = 0.5,
                        sole: tuple[float, float] = (0.10, 0.06), timestep: float = 0.002) -> float:
    """Robot scale: how stiffly the layer holds one sole against rolling [N m/rad], the sole carrying
    ``mass`` [kg] (the whole robot, as in single support) and rolled by a small ``torque`` [N m].
    A robot whose ankles hold still topples sideways on one foot when this is below m g h (its
    weight times its CoM height: 10.7 N m/rad for the built-in robot at 0.22 m)."""
    m, d, pts = _sole_rig(ground, ("z", "roll"), mass, sole, ground.layer_height + 0.001, timestep,
                          {"roll": "motor"})
    n_settle, n = int(round(1.0 / timestep)), int(round(3.0 / timestep))
    _run(m, d, pts, n, ctrl=lambda i: [torque if i >= n_settle else 0.0])
    return torque / float(d.qpos[m.joint(PREFIX + "roll").qposadr[0]])
