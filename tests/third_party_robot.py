"""Third-party-style robot files, written here for the tests (not copied from any collection).

A 20-DoF kid-size humanoid of ~0.5 m and ~3 kg built the way public MJCFs often are, and
unlike our built-in robot: hinge anchors away from the axis intersections (each joint sits
at its own link's origin, offset along and across the axes), a file ``<default>`` with
position-actuator settings (``ctrlrange``, ``forcerange``, ``kp``) and joint damping/armature,
a site called ``imu`` and a sensor called ``imu_quat``, a keyframe sized for its own 20
actuators, mirrored joint axes on the right leg, a torso whose CoM sits behind the hips, its
own servo numbers (kp 21, 5 N m), and feet of two boxes or of two capsules.
"""

from __future__ import annotations

from pathlib import Path

LEG = ("hip_yaw", "hip_roll", "hip_pitch", "knee", "ankle_pitch", "ankle_roll")
ARM = ("sho_pitch", "sho_roll", "elbow")


def joint_name(kind: str, side: str) -> str:
    """The file's naming: ``HipYaw_L`` and so on."""
    return "".join(w.capitalize() for w in kind.split("_")) + "_" + side.upper()


def mjcf(feet: str = "two_box", torso_com_x: float = -0.015, kp: float = 21.1, torque: float = 5.0,
         key_ctrl: int = 20, swap_lr: bool = False, yaw_offset: float = 0.0, knee_ahead: float = 0.0,
         ankle_ahead: float = 0.0, ankle_tilt_deg: float = 0.0, shoulder_yaw: bool = False) -> str:
    """The MJCF text. ``feet``: "two_box" or "capsule". Legs that are not ideal, as many teams'
    are (the numerical leg IK's robots): ``yaw_offset`` [m] the hip yaw axis that far ahead of the
    hip centre; ``knee_ahead`` and ``ankle_ahead`` [m] the knee and ankle pitch axes that far ahead
    of the hip at the zero pose (bent legs; thigh and shank keep their lengths); ``ankle_tilt_deg``
    the ankle roll axis tilted up at the front by that much. ``shoulder_yaw``: a 22-joint robot, each
    upper arm also turning about its own length (``ShoulderYaw_L``, ``ShoulderYaw_R``)."""
    import math
    thigh_z = -math.sqrt(0.11015 ** 2 - knee_ahead ** 2)
    shank_z = -math.sqrt(0.11 ** 2 - (ankle_ahead - knee_ahead) ** 2)
    tilt = math.radians(ankle_tilt_deg)
    roll_axis = f"{math.cos(tilt):.9g} 0 {math.sin(tilt):.9g}"
    def foot(s: int) -> str:
        if feet == "two_box":
            return (f'<geom class="foot" pos="0.024 {s * 0.013:.4f} -0.0265" size="0.0635 0.028 0.004"/>\n'
                    f'          <geom class="foot" pos="0.024 {s * 0.0125:.4f} -0.0265" size="0.057 0.039 0.004"/>')
        if feet == "capsule":
            return (f'<geom class="foot" type="capsule" fromto="-0.035 {s * 0.038:.4f} -0.0225 0.08 {s * 0.038:.4f} -0.0225" size="0.01"/>\n'
                    f'          <geom class="foot" type="capsule" fromto="-0.035 {s * -0.016:.4f} -0.0225 0.08 {s * -0.016:.4f} -0.0225" size="0.01"/>')
        if feet == "cleats":      # four spherical cleats on bodies welded to a foot frame turned 90 deg
            out = []
            for k, (x, y) in enumerate(((-0.03, -0.02), (-0.03, 0.04), (0.08, -0.02), (0.08, 0.04))):
                # world (x, s*y, z) -> local (x, z, -s*y) in a frame turned +90 deg about x
                out.append(f'<body name="cleat_{k}_{"l" if s > 0 else "r"}" pos="{x} -0.0225 {-s * y:.4f}">'
                           f'<inertial pos="0 0 0" mass="0.005" diaginertia="1e-7 1e-7 1e-7"/>'
                           f'<geom class="collision" type="sphere" size="0.008"/></body>')
            return "\n          ".join(out)
        raise ValueError(feet)

    turn = ' quat="0.7071068 0.7071068 0 0"' if feet == "cleats" else ""

    def leg(side: str, s: int) -> str:
        n = {k: joint_name(k, side) for k in LEG}
        return f"""
    <body name="hip_yaw_link_{side}" pos="{yaw_offset:g} {s * 0.035} 0">
      <inertial pos="-0.0016 0 -0.0077" mass="0.012" diaginertia="4e-6 4e-6 1.5e-6"/>
      <joint name="{n['hip_yaw']}" axis="0 0 -1" range="-1 1"/>
      <body name="hip_roll_link_{side}" pos="{-0.024 - yaw_offset:g} 0 -0.0285">
        <inertial pos="0.004 0 -0.012" mass="0.18" diaginertia="1.2e-4 1.1e-4 4.7e-5"/>
        <joint name="{n['hip_roll']}" axis="-1 0 0" range="-0.8 0.8"/>
        <body name="thigh_{side}" pos="0.0241 {s * 0.019} 0">
          <inertial pos="0.0006 {-s * 0.019} -0.084" mass="0.115" diaginertia="1.05e-4 9.6e-5 2.5e-5"/>
          <joint name="{n['hip_pitch']}" axis="0 {s} 0" range="-2 2"/>
          <geom class="collision" type="capsule" fromto="0 {-s * 0.019} -0.02 0 {-s * 0.019} -0.09" size="0.02"/>
          <body name="shank_{side}" pos="{knee_ahead:g} 0 {thigh_z:.9g}">
            <inertial pos="0 {-s * 0.0215} -0.055" mass="0.04" diaginertia="3.7e-5 2.8e-5 1.5e-5"/>
            <joint name="{n['knee']}" axis="0 {s} 0" range="-2.6 2.6"/>
            <body name="ankle_link_{side}" pos="{ankle_ahead - knee_ahead:g} 0 {shank_z:.9g}">
              <inertial pos="-0.02 {-s * 0.0187} 0.012" mass="0.18" diaginertia="1.2e-4 1.1e-4 4.7e-5"/>
              <joint name="{n['ankle_pitch']}" axis="0 {-s} 0" range="-1.5 1.5"/>
              <body name="foot_{side}" pos="-0.0241 {-s * 0.019} 0"{turn}>
                <inertial pos="0.024 {s * 0.0104} -0.0276" mass="0.07" diaginertia="1.2e-4 8.5e-5 4e-5"/>
                <joint name="{n['ankle_roll']}" axis="{roll_axis}" range="-0.8 0.8"/>
                {foot(s)}
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>"""

    def yaw(side: str) -> str:
        return f'\n        <joint name="{joint_name("shoulder_yaw", side)}" axis="0 1 0" range="-1.5 1.5"/>' \
            if shoulder_yaw else ""

    def arm(side: str, s: int) -> str:
        n = {k: joint_name(k, side) for k in ARM}
        return f"""
    <body name="shoulder_{side}" pos="-0.001 {s * 0.06} 0.111">
      <inertial pos="0 {s * 0.008} -0.002" mass="0.012" diaginertia="4e-6 3.6e-6 1.7e-6"/>
      <joint name="{n['sho_pitch']}" axis="0 {s} 0" range="-3.1 3.1"/>
      <body name="upper_arm_{side}" pos="0.019 {s * 0.0285} -0.01">
        <inertial pos="-0.018 {s * 0.045} 0" mass="0.178" diaginertia="2.3e-4 2.2e-4 3e-5"/>
        <joint name="{n['sho_roll']}" axis="-1 0 0" range="-2 2"/>{yaw(side)}
        <geom class="collision" type="capsule" fromto="-0.018 {s * 0.01} 0 -0.018 {s * 0.08} 0" size="0.015"/>
        <body name="forearm_{side}" pos="0 {s * 0.0904} 0">
          <inertial pos="-0.019 {s * 0.07} 0.004" mass="0.041" diaginertia="6.9e-5 6.2e-5 1.2e-5"/>
          <joint name="{n['elbow']}" axis="1 0 0" range="-2.5 2.5"/>
        </body>
      </body>
    </body>"""

    legs = leg("l", 1) + leg("r", -1)
    if swap_lr:      # the right leg's bodies named as the left and the other way round
        legs = legs.replace("_l\"", "_TMP\"").replace("_r\"", "_l\"").replace("_TMP\"", "_r\"")
    names = [joint_name("head_pan", "c"), joint_name("head_tilt", "c")]
    names += [joint_name(k, s) for s in "lr" for k in ARM] + [joint_name(k, s) for s in "lr" for k in LEG]
    actuators = "\n".join(f'    <position name="{j}_act" joint="{j}"/>' for j in names)
    arms_down = {"sho_roll": 1.25}
    qpos = ["0 0 0.3 1 0 0 0", "0 0"]
    for s, sign in (("l", 1), ("r", -1)):
        qpos.append(" ".join(f"{sign * arms_down.get(k, 0.0):g}" for k in ARM))
    qpos.append(" ".join(["0"] * 12))
    ctrl = " ".join(["0"] * key_ctrl)
    return f"""<mujoco model="third_party_kid">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="0.005"/>
  <default>
    <joint damping="1.084" armature="0.045" frictionloss="0.03"/>
    <position kp="{kp}" ctrlrange="-3.141592 3.141592" forcerange="-{torque} {torque}"/>
    <geom margin="0.001" solref="0.004 1"/>
    <site group="5" type="sphere" size="0.01"/>
    <default class="collision">
      <geom group="3"/>
      <default class="foot">
        <geom mass="0" type="box"/>
      </default>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="body_link" pos="0 0 0.3">
      <inertial pos="{torso_com_x} 0.0001 0.066" mass="1.35" diaginertia="3.4e-3 3.2e-3 3e-3"/>
      <freejoint/>
      <geom class="collision" type="box" pos="-0.01 0 0.07" size="0.045 0.06 0.06"/>
      <site name="imu" pos="0 0 0.05"/>
      <body name="head_pan_link" pos="-0.001 0 0.1365">
        <inertial pos="0.002 0 0.008" mass="0.012" diaginertia="4e-6 3.6e-6 1.7e-6"/>
        <joint name="{names[0]}" axis="0 0 1" range="-2 2"/>
        <body name="head_tilt_link" pos="0.01 0.019 0.0285">
          <inertial pos="0.002 -0.019 0.028" mass="0.136" diaginertia="1.1e-4 8.7e-5 4.4e-5"/>
          <joint name="{names[1]}" axis="0 -1 0" range="-1 1"/>
        </body>
      </body>{arm("l", 1)}{arm("r", -1)}{legs}
    </body>
  </worldbody>
  <actuator>
{actuators}
  </actuator>
  <sensor>
    <framequat name="imu_quat" objtype="site" objname="imu"/>
    <jointpos name="com" joint="{joint_name('knee', 'l')}"/>
  </sensor>
  <keyframe>
    <key name="stand" qpos="{' '.join(qpos)}" ctrl="{ctrl}"/>
  </keyframe>
</mujoco>
"""


def joint_map(legs_only: bool = False, arms_and_head: bool = True) -> dict[str, str]:
    out = {f"{s}_{k}": joint_name(k, s) for s in "lr" for k in LEG}
    if arms_and_head and not legs_only:
        out.update({"head_yaw": joint_name("head_pan", "c"), "head_pitch": joint_name("head_tilt", "c")})
        for s in "lr":
            out.update({f"{s}_shoulder_pitch": joint_name("sho_pitch", s),
                        f"{s}_shoulder_roll": joint_name("sho_roll", s), f"{s}_elbow": joint_name("elbow", s)})
    return out


def map_yaml(jmap: dict[str, str] | None = None, mjcf_name: str = "robot.xml", extra: str = "",
             feet: tuple[str, str] = ("foot_l", "foot_r")) -> str:
    jmap = joint_map() if jmap is None else jmap
    joints = "\n".join(f"  {k}: {v}" for k, v in jmap.items())
    return (f"mjcf: {mjcf_name}\ntorso: body_link\nfeet: {{left: {feet[0]}, right: {feet[1]}}}\n"
            f"joints:\n{joints}\n{extra}")


def write(tmp: Path, xml: str | None = None, yaml_text: str | None = None, subdir: str = "") -> Path:
    """Write robot.xml (in ``subdir``) and map.yaml; returns the map's path."""
    folder = tmp / subdir if subdir else tmp
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "robot.xml").write_text(mjcf() if xml is None else xml)
    mjcf_rel = f"{subdir}/robot.xml" if subdir else "robot.xml"
    (tmp / "map.yaml").write_text(map_yaml(mjcf_name=mjcf_rel) if yaml_text is None else yaml_text)
    return tmp / "map.yaml"


# --- the same robot as a ROS team would describe it: URDF -----------------------------------

def _rpy(quat_wxyz) -> str:
    from scipy.spatial.transform import Rotation
    w, x, y, z = (float(v) for v in quat_wxyz)
    import warnings
    with warnings.catch_warnings():            # a gimbal lock still gives the same rotation
        warnings.simplefilter("ignore", UserWarning)
        r = Rotation.from_quat([x, y, z, w]).as_euler("xyz")   # URDF rpy: fixed axes x, y, z
    return " ".join(f"{v:.12g}" for v in r)


def _xyz(v) -> str:
    return " ".join(f"{float(a):.12g}" for a in v)


def urdf(xml: str | None = None, *, velocity: float = 6.0, sole_link: str | None = None,
         mesh_uri: str | None = None, continuous: str | None = None, mimic: tuple[str, str] | None = None,
         imu_frame: bool = True) -> str:
    """The robot of :func:`mjcf` written as URDF (the MJCF compiled, then each body a link and each
    hinge a revolute joint at the child link's origin, with the file's range, its actuator's force
    range as ``effort`` and ``velocity`` [rad/s]; capsules become a cylinder and two spheres, URDF
    having no capsule). Options a ROS description often has: ``imu_frame`` a massless link on a fixed
    joint; ``sole_link`` a link on a fixed joint under each foot (``sole_link`` + ``_l``/``_r``)
    that carries the feet's collision geometry; ``mesh_uri`` (with ``{side}``) a mesh file for
    that sole instead of its boxes; ``continuous`` a joint made continuous (no limits); ``mimic``
    (joint, leader) a mimic joint."""
    import mujoco
    import numpy as np
    m = mujoco.MjModel.from_xml_string(mjcf() if xml is None else xml)
    G = mujoco.mjtGeom
    out = ['<?xml version="1.0"?>', '<robot name="third_party_kid">']
    act_force = {}
    for a in range(m.nu):
        act_force[int(m.actuator_trnid[a, 0])] = float(max(abs(m.actuator_forcerange[a])))

    def geoms(b: int, skip_feet: bool) -> list[str]:
        rows = []
        for g in range(m.ngeom):
            if m.geom_bodyid[g] != b:
                continue
            if skip_feet and int(m.geom_type[g]) == G.mjGEOM_BOX:
                continue
            pos, quat, size, kind = m.geom_pos[g], m.geom_quat[g], m.geom_size[g], int(m.geom_type[g])
            origin = f'<origin xyz="{_xyz(pos)}" rpy="{_rpy(quat)}"/>'
            if kind == G.mjGEOM_BOX:
                shapes = [(origin, f'<box size="{_xyz(2 * size)}"/>')]
            elif kind == G.mjGEOM_SPHERE:
                shapes = [(origin, f'<sphere radius="{size[0]:.12g}"/>')]
            elif kind in (G.mjGEOM_CYLINDER, G.mjGEOM_CAPSULE):
                shapes = [(origin, f'<cylinder radius="{size[0]:.12g}" length="{2 * size[1]:.12g}"/>')]
                if kind == G.mjGEOM_CAPSULE:
                    R = np.zeros(9)
                    mujoco.mju_quat2Mat(R, quat)
                    ax = R.reshape(3, 3)[:, 2]
                    for s in (1, -1):
                        shapes.append((f'<origin xyz="{_xyz(pos + s * size[1] * ax)}"/>',
                                       f'<sphere radius="{size[0]:.12g}"/>'))
            else:
                continue
            rows += [f'    <collision>{o}<geometry>{s}</geometry></collision>' for o, s in shapes]
        return rows

    def link(b: int, name: str, skip_feet: bool = False) -> str:
        iq = m.body_iquat[b]
        I = m.body_inertia[b]
        rows = [f'  <link name="{name}">']
        if m.body_mass[b] > 0:
            rows.append(f'    <inertial><origin xyz="{_xyz(m.body_ipos[b])}" rpy="{_rpy(iq)}"/>'
                        f'<mass value="{m.body_mass[b]:.12g}"/><inertia ixx="{I[0]:.12g}" iyy="{I[1]:.12g}" '
                        f'izz="{I[2]:.12g}" ixy="0" ixz="0" iyz="0"/></inertial>')
        rows += geoms(b, skip_feet)
        rows.append("  </link>")
        return "\n".join(rows)

    feet = {m.body(f"foot_{s}").id: s for s in "lr"} if sole_link else {}
    for b in range(1, m.nbody):
        name = m.body(b).name
        out.append(link(b, name, skip_feet=b in feet))
        if b in feet:
            s = feet[b]
            sole = f"{sole_link}_{s}"
            rows = [f'  <link name="{sole}">']
            if mesh_uri:
                rows.append(f'    <collision><origin xyz="0 0 0"/><geometry><mesh filename="'
                            f'{mesh_uri.format(side=s)}"/></geometry></collision>')
                rows.append(f'    <visual><geometry><mesh filename="package://missing_visuals/{s}.dae"/>'
                            f'</geometry></visual>')
            else:
                rows += [r for r in geoms(b, False) if "<box" in r]
            rows.append("  </link>")
            out.append("\n".join(rows))
            out.append(f'  <joint name="{sole}_fixed" type="fixed"><parent link="{name}"/><child link="{sole}"/>'
                       f'<origin xyz="0 0 0"/></joint>')
        parent = m.body_parentid[b]
        if parent == 0:
            continue
        origin = f'<origin xyz="{_xyz(m.body_pos[b])}" rpy="{_rpy(m.body_quat[b])}"/>'
        pname = m.body(parent).name
        if m.body_jntnum[b] == 0:
            out.append(f'  <joint name="{name}_fixed" type="fixed"><parent link="{pname}"/><child link="{name}"/>'
                       f'{origin}</joint>')
            continue
        j = m.body_jntadr[b]
        jn = m.joint(j).name
        lo, hi = m.jnt_range[j]
        kind = "continuous" if jn == continuous else "revolute"
        lim = (f'<limit effort="{act_force.get(j, 0.0):.12g}" velocity="{velocity:.12g}"/>' if kind == "continuous"
               else f'<limit lower="{lo:.12g}" upper="{hi:.12g}" effort="{act_force.get(j, 0.0):.12g}" '
                    f'velocity="{velocity:.12g}"/>')
        mim = f'<mimic joint="{mimic[1]}"/>' if mimic and mimic[0] == jn else ""
        out.append(f'  <joint name="{jn}" type="{kind}"><parent link="{pname}"/><child link="{name}"/>{origin}'
                   f'<axis xyz="{_xyz(m.jnt_axis[j])}"/>{lim}{mim}</joint>')
    if imu_frame:
        out.append('  <link name="imu_link"/>')
        out.append('  <joint name="imu_fixed" type="fixed"><parent link="body_link"/><child link="imu_link"/>'
                   '<origin xyz="0 0 0.05"/></joint>')
    out.append("</robot>")
    return "\n".join(out) + "\n"


def box_stl(half: tuple[float, float, float], centre: tuple[float, float, float]) -> bytes:
    """A binary STL (MuJoCo reads binary STL only) of a box (half sizes, centre) [m], for mesh
    collision tests."""
    import itertools
    import struct
    import numpy as np
    hx, hy, hz = half
    V = np.array([[sx * hx, sy * hy, sz * hz] for sx, sy, sz in itertools.product((-1, 1), repeat=3)]) + centre
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),
             (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    out = bytearray(b"box".ljust(80, b" ")) + struct.pack("<I", len(faces))
    for a, b, d in faces:
        n = np.cross(V[b] - V[a], V[d] - V[a])
        out += struct.pack("<12fH", *(n / np.linalg.norm(n)), *V[a], *V[b], *V[d], 0)
    return bytes(out)
