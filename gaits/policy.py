"""A learned walk policy as a controller (ours): an ONNX model run at its own control period on
an observation vector built from what the robot senses, its output turned into joint targets.

Teams export the policies they train (mujoco_playground, mjlab, Isaac Lab) as ONNX with a stated
layout; a *policy file* says that layout, so any of them walks here and on the robot::

    policy:
      model: walk.onnx                # relative to this file; one input (1, N) or (N,), one output
      period: 0.02                    # [s] the policy's control period, a whole number of loop ticks
      joints: [l_hip_yaw, ..., r_ankle_roll]   # our joint names (gaits.JOINT_NAMES; a robot's joint beyond
                                      #   them by its map's extra_joints name): the order of
                                      #   joint_pos, joint_vel, last_action and of the action
      default_pose: {l_knee: 0.6, ...}  # [rad] our signs; joints not named stand at 0
      observation:                    # the terms in order, each (value - offset) * scale, clipped
        - {term: gyro, scale: 0.25}   # (3) [rad/s] body rates
        - {term: gravity}             # (3) gravity's direction in the body frame (from the IMU)
        - {term: command, scale: [2.0, 2.0, 0.25]}   # (3) vx, vy, wz
        - {term: joint_pos}           # (n) q - default_pose
        - {term: joint_vel, scale: 0.05}             # (n) [rad/s]
        - {term: last_action}         # (n) the policy's last output (after its clip)
        - {term: phase, period: 0.6}  # (2) sin, cos of 2 pi t / period
        - {term: feet_phase, period: 0.667}   # (4) cos pL, cos pR, sin pL, sin pR: two feet half a
                                      #   cycle apart, pL = 2 pi t / period, pR = pL + pi (the biped
                                      #   joysticks of mujoco_playground: Berkeley Humanoid, G1, T1)
        - {term: imu_rpy}             # (3) roll, pitch, yaw [rad]
        - {term: base_velocity}       # (3) [m/s] the trunk's velocity in its own axes, from the encoders
                                      #   and the gyro with the lower sole standing still (ours: what a
                                      #   policy trained on the simulator's velocimeter reads on a robot)
      action: {scale: 0.25, clip: 5.0}  # target = default_pose + scale * clip(output, +-clip)
      gains: {kp: 21.0, kd: 0.6}      # optional: the servos it was trained with [N m/rad, N m s/rad], a
                                      #   number or one a joint (checked joint by joint; none: said)
      commands: {vx: [-0.2, 0.4], vy: [-0.2, 0.2], wz: [-1.0, 1.0]}   # the envelope it was trained on:
                                      #   commands are clipped into it
    params: {action_scale: 0.25}      # optional: what a study may tune (action_scale, vx_max,
    ranges: {action_scale: {low: 0.15, high: 0.35}}   #   vx_min, vy_max, wz_max), with ranges

Every ``scale``, ``offset`` and ``clip`` is a number or one per element. The spec is checked against
the model's input and output sizes when it is loaded (a :class:`~gaits.params.ParamError` naming
the term). Pure numpy here; ``onnxruntime`` (the ``onnx`` extra) is imported when a model is run,
so the robot side installs it only if it runs a policy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from .control import PlanRecord, StartPose
from .leg_kinematics import rot_x, rot_y
from .params import ParamError
from .trajectory import JOINT_NAME_PATTERN, JOINT_NAMES

__all__ = ["PolicySpec", "Term", "PolicyController", "PolicyFactory", "policy_from_mapping", "gravity_in_body",
           "TERMS", "TUNABLE", "onnx_runner", "check_robot", "check_sizes", "base_velocity", "gains_unstated",
           "POLICY_FILE_KEYS", "load_policy_file"]

#: Each observation term and its length (None: one per policy joint).
TERMS = {"gyro": 3, "gravity": 3, "command": 3, "joint_pos": None, "joint_vel": None, "last_action": None,
         "phase": 2, "feet_phase": 4, "imu_rpy": 3, "base_velocity": 3}
#: The terms that advance with the gait's period (``period`` [s] required).
PHASED = ("phase", "feet_phase")
#: The readings each term needs (the controller's ``senses``).
_NEEDS = {"base_velocity": ("q", "dq", "gyro", "imu_rpy"),
          "gyro": ("gyro",), "gravity": ("imu_rpy",), "imu_rpy": ("imu_rpy",), "joint_pos": ("q",),
          "joint_vel": ("dq",)}
#: What a study may tune (``params:``), with what each means.
TUNABLE = {"action_scale": "the action's scale", "vx_max": "the forward command's top [m/s]",
           "vx_min": "the backward command's top, negative [m/s]", "vy_max": "the sideways command's top [m/s]",
           "wz_max": "the turning command's top [rad/s]"}


@dataclass(frozen=True)
class Term:
    """One observation term: (value - offset) * scale, clipped to +-clip (each a number or per element)."""

    term: str
    scale: Any = 1.0
    offset: Any = 0.0
    clip: Any = math.inf
    period: float = 0.0          # [s] ``phase`` and ``feet_phase`` only


@dataclass(frozen=True)
class PolicySpec:
    """A policy file's ``policy:`` section, checked (module docstring)."""

    model: str                                   # the ONNX file
    period: float                                # [s]
    joints: tuple[str, ...]
    default_pose: Mapping[str, float]
    observation: tuple[Term, ...]
    action_scale: Any = 1.0
    action_clip: float = math.inf
    gains: Mapping[str, float] = field(default_factory=dict)
    commands: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    def term_length(self, term: Term) -> int:
        n = TERMS[term.term]
        return len(self.joints) if n is None else n

    @property
    def observation_size(self) -> int:
        return sum(self.term_length(t) for t in self.observation)

    @property
    def senses(self) -> frozenset[str]:
        return frozenset(r for t in self.observation for r in _NEEDS.get(t.term, ()))

    def with_params(self, values: Mapping[str, float]) -> "PolicySpec":
        """The spec with a study's values (:data:`TUNABLE`) in place."""
        spec, cmd = self, dict(self.commands)
        for k, v in values.items():
            v = float(v)
            if k == "action_scale":
                spec = replace(spec, action_scale=v)
            elif k == "vx_max":
                cmd["vx"] = (cmd.get("vx", (0.0, 0.0))[0], abs(v))
            elif k == "vx_min":
                cmd["vx"] = (-abs(v), cmd.get("vx", (0.0, 0.0))[1])
            elif k in ("vy_max", "wz_max"):
                cmd[k[:2]] = (-abs(v), abs(v))
            else:
                raise ParamError(f"policy: unknown parameter {k!r} (tunable: {', '.join(TUNABLE)})")
        return replace(spec, commands=cmd)

    def tunables(self) -> dict[str, float]:
        """The values a study may tune (:data:`TUNABLE`), as the spec has them."""
        out = {}
        if np.ndim(self.action_scale) == 0:
            out["action_scale"] = float(self.action_scale)
        if "vx" in self.commands:
            out["vx_min"], out["vx_max"] = (float(x) for x in self.commands["vx"])
        for axis in ("vy", "wz"):
            if axis in self.commands:
                out[f"{axis}_max"] = float(self.commands[axis][1])
        return out


def _numbers(value: Any, n: int, what: str, source: str, positive: bool = False) -> Any:
    """A number or a list of ``n`` numbers (finite, or inf for a clip)."""
    vals = value if isinstance(value, (list, tuple)) else [value]
    for v in vals:
        if isinstance(v, bool) or not isinstance(v, (int, float)) or math.isnan(v) \
                or (not positive and not math.isfinite(v)) or (positive and v <= 0):
            raise ParamError(f"{source}: {what} = {value!r}: expected a {'positive ' if positive else 'finite '}"
                             f"number or a list of {n}")
    if isinstance(value, (list, tuple)):
        if len(value) != n:
            raise ParamError(f"{source}: {what} has {len(value)} numbers: expected 1 or {n} (the term's length)")
        return np.array(value, dtype=float)
    return float(value)


def policy_from_mapping(doc: Any, source: str) -> PolicySpec:
    """A policy file's ``policy:`` section -> :class:`PolicySpec`, every field checked (one
    :class:`ParamError` naming it). The model's path is returned as written (resolve it yourself)."""
    keys = ("model", "period", "joints", "default_pose", "observation", "action", "gains", "commands")
    if not isinstance(doc, Mapping):
        raise ParamError(f"{source}: policy: expected a mapping with {', '.join(keys)}")
    for k in doc:
        if k not in keys:
            raise ParamError(f"{source}: policy: unknown key {k!r} (allowed: {', '.join(keys)})")
    for k in ("model", "period", "joints", "observation", "action"):
        if k not in doc:
            raise ParamError(f"{source}: policy: missing {k!r}")
    if not isinstance(doc["model"], str) or not doc["model"]:
        raise ParamError(f"{source}: policy.model = {doc['model']!r}: expected the ONNX file's path")
    period = doc["period"]
    if isinstance(period, bool) or not isinstance(period, (int, float)) or not 0.001 <= period <= 1.0:
        raise ParamError(f"{source}: policy.period = {period!r}: expected [0.001, 1] s")
    joints = doc["joints"]
    if not isinstance(joints, list) or not joints:
        raise ParamError(f"{source}: policy.joints: expected a list of our joint names ({', '.join(JOINT_NAMES[:3])}, ...)")
    for j in joints:
        if not isinstance(j, str) or not JOINT_NAME_PATTERN.fullmatch(j):
            raise ParamError(f"{source}: policy.joints: {j!r} is not a joint name (our 20 roles, {', '.join(JOINT_NAMES[:3])}, "
                             f"..., or a robot's extra joint by its map's name)")
    if len(set(joints)) != len(joints):
        raise ParamError(f"{source}: policy.joints names a joint twice")
    n = len(joints)
    pose = doc.get("default_pose") or {}
    if not isinstance(pose, Mapping):
        raise ParamError(f"{source}: policy.default_pose: expected joint: angle [rad]")
    for j, v in pose.items():
        if j not in joints and j not in JOINT_NAMES:
            raise ParamError(f"{source}: policy.default_pose: {j!r} is not one of our joints nor one the policy drives")
        _numbers(v, 1, f"policy.default_pose.{j}", source)
    obs_doc = doc["observation"]
    if not isinstance(obs_doc, list) or not obs_doc:
        raise ParamError(f"{source}: policy.observation: expected a list of terms ({', '.join(TERMS)})")
    terms = []
    for i, t in enumerate(obs_doc):
        if not isinstance(t, Mapping) or "term" not in t:
            raise ParamError(f"{source}: policy.observation[{i}]: expected {{term: NAME, scale, offset, clip}}")
        name = t["term"]
        if name not in TERMS:
            raise ParamError(f"{source}: policy.observation[{i}]: unknown term {name!r} (terms: {', '.join(TERMS)})")
        extra = set(t) - {"term", "scale", "offset", "clip", "period"}
        if extra:
            raise ParamError(f"{source}: policy.observation[{i}] ({name}): unknown key {sorted(extra)[0]!r} "
                             f"(allowed: term, scale, offset, clip{', period' if name in PHASED else ''})")
        length = n if TERMS[name] is None else TERMS[name]
        where = f"policy.observation[{i}] ({name})"
        p = 0.0
        if name in PHASED:
            p = t.get("period")
            if isinstance(p, bool) or not isinstance(p, (int, float)) or not 0.05 <= p <= 10.0:
                raise ParamError(f"{source}: {where}.period = {p!r}: expected the gait's period in [0.05, 10] s")
        elif "period" in t:
            raise ParamError(f"{source}: {where}: period is the phase terms' ({', '.join(PHASED)})")
        terms.append(Term(name, _numbers(t.get("scale", 1.0), length, f"{where}.scale", source),
                          _numbers(t.get("offset", 0.0), length, f"{where}.offset", source),
                          _numbers(t.get("clip", math.inf), length, f"{where}.clip", source, positive=True),
                          float(p)))
    act = doc["action"]
    if not isinstance(act, Mapping) or set(act) - {"scale", "clip"}:
        raise ParamError(f"{source}: policy.action: expected {{scale, clip}}")
    scale = _numbers(act.get("scale", 1.0), n, "policy.action.scale", source)
    clip = _numbers(act.get("clip", math.inf), 1, "policy.action.clip", source, positive=True)
    gains = doc.get("gains") or {}
    if not isinstance(gains, Mapping) or set(gains) - {"kp", "kd"}:
        raise ParamError(f"{source}: policy.gains: expected {{kp, kd}} [N m/rad, N m s/rad], each a number or one "
                         f"a joint")
    gains = {k: _numbers(v, n, f"policy.gains.{k}", source) for k, v in gains.items()}
    cmds = doc.get("commands") or {}
    if not isinstance(cmds, Mapping) or set(cmds) - {"vx", "vy", "wz"}:
        raise ParamError(f"{source}: policy.commands: expected vx, vy, wz, each [low, high]")
    envelope = {}
    for k, v in cmds.items():
        if not isinstance(v, list) or len(v) != 2:
            raise ParamError(f"{source}: policy.commands.{k} = {v!r}: expected [low, high]")
        lo, hi = (_numbers(x, 1, f"policy.commands.{k}", source) for x in v)
        if not lo <= 0.0 <= hi:
            raise ParamError(f"{source}: policy.commands.{k} = {v!r}: expected low <= 0 <= high")
        envelope[k] = (lo, hi)
    return PolicySpec(doc["model"], float(period), tuple(joints), {k: float(v) for k, v in pose.items()},
                      tuple(terms), scale, float(clip), gains, envelope)


def gravity_in_body(rpy: np.ndarray) -> np.ndarray:
    """Gravity's direction (unit) in the body frame from the IMU's roll and pitch (yaw does not
    matter): R^T (0, 0, -1) with R = Rz(yaw) Ry(pitch) Rx(roll) (``control.rpy_from_quat``'s
    angles); upright (0, 0, -1), leaning forward +x."""
    R = rot_y(float(rpy[1])) @ rot_x(float(rpy[0]))
    return R.T @ np.array([0.0, 0.0, -1.0])


def onnx_runner(path: str | Path) -> tuple[Callable[[np.ndarray], np.ndarray], int, int]:
    """(run, input size, output size) of an ONNX model with one input and one output, on
    onnxruntime's CPU provider; the sizes from the model's last dimensions."""
    try:
        import onnxruntime as ort
    except ImportError:
        raise ParamError("a policy needs onnxruntime: pip install 'gait-tuner[onnx]' (or onnxruntime)") from None
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = 1                  # one walk, one thread: studies run walks side by side
    opts.inter_op_num_threads = 1
    try:
        session = ort.InferenceSession(str(path), opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own kinds for a bad file
        raise ParamError(f"{path}: not an ONNX model onnxruntime runs: {' '.join(str(exc).split())[:200]}") from None
    ins, outs = session.get_inputs(), session.get_outputs()
    if len(ins) != 1 or len(outs) < 1:
        raise ParamError(f"{path}: the model has {len(ins)} inputs and {len(outs)} outputs: a policy has one "
                         f"input (the observation) and its first output is the action")

    def size(shape: Sequence, what: str) -> int:
        last = shape[-1] if shape else None
        if not isinstance(last, int):
            raise ParamError(f"{path}: the model's {what} has no fixed last dimension ({shape}): export it with one")
        return last
    n_in, n_out = size(ins[0].shape, "input"), size(outs[0].shape, "output")
    name, batched = ins[0].name, len(ins[0].shape) == 2
    out_name = outs[0].name

    def run(obs: np.ndarray) -> np.ndarray:
        x = obs.astype(np.float32)[None, :] if batched else obs.astype(np.float32)
        return np.asarray(session.run([out_name], {name: x})[0], dtype=float).reshape(-1)
    return run, n_in, n_out


def check_sizes(spec: PolicySpec, n_in: int, n_out: int, source: str) -> None:
    """The spec's observation and action against the model's input and output sizes (one
    :class:`ParamError` naming the terms)."""
    if n_in != spec.observation_size:
        parts = ", ".join(f"{t.term} {spec.term_length(t)}" for t in spec.observation)
        raise ParamError(f"{source}: the observation has {spec.observation_size} numbers ({parts}) but the "
                         f"model takes {n_in}")
    if n_out != len(spec.joints):
        raise ParamError(f"{source}: the model gives {n_out} actions but policy.joints names {len(spec.joints)}")


class PolicyController:
    """A policy as a ``gaits.control.Controller`` (module docstring). ``run`` maps an observation
    (N,) to an action (n,); :func:`onnx_runner` gives one for an ONNX file. Between two of the
    policy's periods the targets hold."""

    def __init__(self, spec: PolicySpec, run: Callable[[np.ndarray], np.ndarray], robot: Any, dt: float,
                 sizes: tuple[int, int] | None = None, source: str = "policy") -> None:
        ticks = spec.period / dt
        if abs(ticks - round(ticks)) > 1e-6 or round(ticks) < 1:
            raise ParamError(f"{source}: policy.period = {spec.period:g} s is not a whole number of the loop's "
                             f"{dt:g} s ticks")
        if sizes is not None:
            check_sizes(spec, *sizes, source)
        self.spec, self.run, self.dt, self.source = spec, run, float(dt), source
        self.every = int(round(ticks))
        self.duration = None
        self.senses = spec.senses
        self.leg = getattr(robot, "leg", None)
        if self.leg is None and any(t.term == "base_velocity" for t in spec.observation):
            raise ParamError(f"{source}: observation term base_velocity needs the robot's legs (a robot file or "
                             f"map), and this robot states none")
        # the targets' order: our 20 roles, then the robot's extra joints (its map's extra_joints)
        self.names = tuple(JOINT_NAMES) + tuple(getattr(robot, "extra_joints", ()) or ())
        unknown = [j for j in spec.joints if j not in self.names]
        if unknown:
            extras = self.names[len(JOINT_NAMES):]
            raise ParamError(f"{source}: policy.joints: {unknown[0]!r} is neither one of our 20 roles nor an extra "
                             f"joint of robot {getattr(robot, 'name', '?')} (its extra joints: "
                             f"{', '.join(extras) or 'none'}; a map names them under extra_joints:)")
        self.index = np.array([self.names.index(j) for j in spec.joints])
        self.default = np.array([spec.default_pose.get(j, 0.0) for j in self.names])
        self.walk_start = 0.0
        self.reset_state()

    def reset_state(self) -> None:
        self.last_action = np.zeros(len(self.spec.joints))
        self.target = self.default.copy()
        self.ticks = 0
        self.last_observation: np.ndarray | None = None    # what the policy was last given (tests, recordings)
        self.calls = 0

    def start_pose(self) -> StartPose:
        self.reset_state()
        return StartPose(self.default.copy())

    def reset(self, m: Any) -> None:
        self.reset_state()

    def command_in_envelope(self, command: np.ndarray | None) -> np.ndarray:
        c = np.zeros(3) if command is None else np.asarray(command, dtype=float).copy()
        for i, axis in enumerate(("vx", "vy", "wz")):
            if axis in self.spec.commands:
                lo, hi = self.spec.commands[axis]
                c[i] = min(max(c[i], lo), hi)
        return c

    def observe(self, m: Any, command: np.ndarray | None) -> np.ndarray:
        """The observation vector of this tick (module docstring's terms, in the spec's order)."""
        parts = []
        for t in self.spec.observation:
            name = t.term
            if name == "gyro":
                v = np.asarray(m.gyro, dtype=float)
            elif name == "gravity":
                v = gravity_in_body(m.imu_rpy)
            elif name == "imu_rpy":
                v = np.asarray(m.imu_rpy, dtype=float)
            elif name == "command":
                v = self.command_in_envelope(command)
            elif name in ("joint_pos", "joint_vel"):
                values = m.q if name == "joint_pos" else m.dq
                names = list(m.joint_names)
                v = np.array([float(values[names.index(j)]) if j in names else 0.0 for j in self.spec.joints])
                if name == "joint_pos":
                    v = v - self.default[self.index]
            elif name == "last_action":
                v = self.last_action.copy()
            elif name == "base_velocity":
                v = base_velocity(m, self.leg)
            elif name == "phase":
                a = 2.0 * math.pi * float(m.t) / t.period
                v = np.array([math.sin(a), math.cos(a)])
            else:                                   # feet_phase: the right foot half a cycle behind
                a = 2.0 * math.pi * float(m.t) / t.period
                v = np.array([math.cos(a), math.cos(a + math.pi), math.sin(a), math.sin(a + math.pi)])
            parts.append(np.clip((v - t.offset) * t.scale, -t.clip, t.clip))
        return np.concatenate(parts)

    def step(self, m: Any, command: np.ndarray | None = None) -> np.ndarray:
        if self.ticks % self.every == 0:
            obs = self.observe(m, command)
            self.last_observation = obs
            action = np.asarray(self.run(obs), dtype=float).reshape(-1)
            if action.shape != (len(self.spec.joints),) or not np.all(np.isfinite(action)):
                raise ParamError(f"{self.source}: the policy returned {action.shape} "
                                 f"{'non-finite ' if action.size and not np.all(np.isfinite(action)) else ''}"
                                 f"actions; expected {len(self.spec.joints)} finite numbers")
            action = np.clip(action, -self.spec.action_clip, self.spec.action_clip)
            self.last_action = action
            self.target = self.default.copy()
            self.target[self.index] += self.spec.action_scale * action
            self.calls += 1
        self.ticks += 1
        return self.target.copy()

    def plan(self, n: int) -> PlanRecord:
        """A policy plans no footsteps: double support at the start pose's soles, its ZMP between them."""
        feet = np.zeros((n, 2))
        if self.leg is not None:
            W = self.leg.hip_offset_y
            left, right = feet + np.array([0.0, W]), feet + np.array([0.0, -W])
        else:
            left, right = feet, feet
        return PlanRecord("policy", np.zeros(n, dtype=int), np.zeros((n, 2)), left, right,
                          walk_start=self.walk_start, cycle_time=2 * self.spec.period,
                          meta={"policy_calls": self.calls})


def base_velocity(m: Any, leg: Any) -> np.ndarray:
    """(3,) [m/s] the trunk's velocity in its own axes from one tick's readings (ours): the sole lower
    along gravity (the IMU's roll and pitch) stands still, so the trunk moves at -(J dq + w x p), p
    that sole's point in the trunk's frame from the leg's forward kinematics, J dq its velocity from
    the leg's joint rates (a difference along dq), w the gyro."""
    from .engine.estimator import sole_in_pelvis, sole_rate
    q, dq = m.in_our_order(m.q), m.in_our_order(m.dq)
    roll, pitch = float(m.imu_rpy[0]), float(m.imu_rpy[1])
    R = rot_y(pitch) @ rot_x(roll)                  # the trunk's tilt (world from trunk, yaw left out)
    best = None
    for side, start in ((1, JOINT_NAMES.index("l_hip_yaw")), (-1, JOINT_NAMES.index("r_hip_yaw"))):
        leg_q, leg_dq = q[start:start + 6], dq[start:start + 6]
        p = sole_in_pelvis(leg_q, leg, side)[0]
        height = float((R @ p)[2])
        if best is None or height < best[0]:
            best = (height, side, p, leg_q, leg_dq)
    _, side, p, leg_q, leg_dq = best
    return -(sole_rate(leg_q, leg_dq, leg, side, p, h=1e-4) + np.cross(np.asarray(m.gyro, dtype=float), p))


_RUNNERS: dict[str, tuple] = {}


class PolicyFactory:
    """Builds a :class:`PolicyController` for a walk: ``factory(params, robot, dt)`` (the signature of
    a controller class of the user's own, ``gaits.drive.UserController``), ``params`` the study's
    values of :data:`TUNABLE`. The ONNX session is opened once per process (picklable: a study's
    workers each open their own)."""

    def __init__(self, spec: PolicySpec, model_path: str, source: str) -> None:
        self.spec, self.model_path, self.source = spec, str(model_path), source

    def runner(self) -> tuple:
        if self.model_path not in _RUNNERS:
            _RUNNERS[self.model_path] = onnx_runner(self.model_path)
        return _RUNNERS[self.model_path]

    def __call__(self, params: Mapping[str, float], robot: Any, dt: float) -> PolicyController:
        spec = self.spec.with_params(params)
        check_robot(spec, robot, self.source)
        run, n_in, n_out = self.runner()
        return PolicyController(spec, run, robot, dt, (n_in, n_out), self.source)


def check_robot(spec: PolicySpec, robot: Any, source: str) -> None:
    """The policy's joints are the robot's, and each joint's servo has the gains the policy was
    trained with (``policy.gains``: kp within 25 %, kd, the servo's derivative gain, within 25 % or
    0.05 N m s/rad), joint by joint: else one :class:`ParamError` naming the first that differs and
    what to change (a policy on other servos walks otherwise, or not at all: never silently). A
    policy that states no gains is not checked (:func:`gains_unstated` says so)."""
    jmap = getattr(robot, "joint_map", None)
    if jmap:
        missing = [j for j in spec.joints if j not in jmap]
        if missing:
            raise ParamError(f"{source}: policy.joints: {missing[0]!r} is not a joint of robot "
                             f"{getattr(robot, 'name', '?')} (its map names {', '.join(jmap)})")
    servos = getattr(robot, "servos", None)
    if not (jmap and servos):
        return
    name = getattr(robot, "name", "?")
    for key, slack in (("kp", 0.0), ("kd", 0.05)):
        if key not in spec.gains:
            continue
        trained = np.broadcast_to(np.asarray(spec.gains[key], dtype=float), (len(spec.joints),))
        for joint, want in zip(spec.joints, trained):
            servo = servos.get(jmap[joint][0])
            if servo is None:
                continue
            pieces = servo.pieces()
            have = float(pieces.kp if key == "kp" else pieces.kv)
            if abs(have - want) > 0.25 * want + slack:
                unit = "N m/rad" if key == "kp" else "N m s/rad"
                field_name = "kp" if key == "kp" else "kv"
                fields = getattr(servo, "fields", lambda: (field_name,))()
                fix = (f"give its map servo: {{{joint}: {{{field_name}: {want:g}}}}} (or its group's)"
                       if field_name in fields else
                       f"its servo law ({getattr(servo, 'law', '?')}) has no {field_name}: give its map a servo "
                       f"that has (law: pd, kp, kv)")
                raise ParamError(f"{source}: the policy was trained with {joint}'s servo at {key} {want:g} {unit} "
                                 f"(policy.gains) and robot {name}'s is at {key} {have:.3g}: {fix}, or leave "
                                 f"policy.gains out to run it on these servos")


def gains_unstated(spec: PolicySpec) -> bool:
    """The policy file states no servo gains: it runs on whatever servos the robot has, unchecked."""
    return not spec.gains


#: a policy file's top-level keys (the simulator's reader, ``tuner/controllers.py``, reads the same)
POLICY_FILE_KEYS = ("policy", "description", "params", "ranges", "time_limit")


def load_policy_file(path: str | Path, doc: Any = None) -> tuple[PolicySpec, Path]:
    """A policy file as the robot runs it (``gait-tuner-loop POLICY.yaml``): its ``policy:`` section
    checked, its ``params:`` (a study's tuned values, :data:`TUNABLE`) in place, and its model's
    path (relative to the file), which must exist. A study's ``ranges:`` and ``time_limit:`` are
    the simulator's and not read here. ``doc``: the file's document when the caller has read it.
    Every mistake is one :class:`ParamError` naming the file."""
    from .gait_file import read_yaml
    path = Path(path)
    source = str(path)
    if doc is None:
        doc = read_yaml(path, "policy")
    if not isinstance(doc, Mapping) or "policy" not in doc:
        raise ParamError(f"{source}: not a policy file (a mapping with a policy: section)")
    unknown = [k for k in doc if k not in POLICY_FILE_KEYS]
    if unknown:
        raise ParamError(f"{source}: unknown key {unknown[0]!r} in a policy file (allowed: {', '.join(POLICY_FILE_KEYS)})")
    spec = policy_from_mapping(doc["policy"], source)
    params = doc.get("params") or {}
    if not isinstance(params, Mapping):
        raise ParamError(f"{source}: params must be a mapping of name: number")
    values = {}
    for k, v in params.items():
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
            raise ParamError(f"{source}: params.{k} = {v!r}: expected a finite number")
        values[str(k)] = float(v)
    try:
        spec = spec.with_params(values)
    except ParamError as exc:
        raise ParamError(f"{source}: {exc}") from None
    model = Path(spec.model)
    model = model if model.is_absolute() else path.parent / model
    if not model.is_file():
        raise ParamError(f"{source}: policy.model: no such file {model}")
    return spec, model
