"""Domain randomisation: what differs between our model and a team's robot and field, per rollout.

A :class:`Randomisation` declares the distributions (a study's ``robust.randomisation:``, the
``robustness`` command's options); :func:`draw` turns it and an integer seed into one
:class:`Perturbation`, the concrete values of one rollout, which ``Simulator.rollout`` applies.
The same (randomisation, seed, namespace) gives the same perturbation and, MuJoCo being
deterministic, the same rollout bit for bit in any process. Seeds of the tuning namespace
(:data:`TUNE`) and of the evaluation namespace (:data:`EVALUATE`) come from different
``numpy.random.SeedSequence`` entropy, so an evaluation never replays a rollout used in tuning.

Defaults (all ours; each a uniform draw unless said):

* link masses x U(1 -+ 0.10) and each link's CoM moved U(-+5 mm) per axis: CAD models miss
  cables, screws and batteries by about this much;
* servos of the pd law (round one's): gain x U(1 -+ 0.20), torque limit x U(1 -+ 0.15), speed x
  U(1 -+ 0.15): Dynamixel gains and stall torque move with supply voltage (12-16 V) and temperature;
* servos of the dc-motor law (``tuner/servos/motor.py``), whose gain, torque, back-EMF and speed
  follow from these: the battery's voltage x U(1 -+ 0.10), one per walk (a 4S LiPo at 15 V: 13.5 to
  16.5 V, drained to full); per servo its torque constant kt x U(1 -+ 0.05) (unit to unit, magnet
  temperature), its winding resistance x U(1 -+ 0.15) (copper gains 0.4 %/K: a servo 40 K warm has
  16 % more) and its gearbox friction (dry and viscous, the extended terms' too) x U(1 -+ 0.30);
* backlash: a dead band of U(0, 0.01) rad per joint (MX-64 gearboxes are specified at 0.33 deg
  new and wear to about twice that; learned walks of one RoboCup team randomise up to 0.035 rad,
  a study can ask for that);
* control latency: 0-2 ticks (0-20 ms) between a command and the servo receiving it;
* IMU: tilt noise 0.5 deg and gyro noise 0.05 rad/s (standard deviations per tick), 0-2 ticks
  latency: typical of the MPU-class IMUs in kid-size robots after filtering; accelerometer noise
  0.05 m/s^2 (an MPU-6050's noise density, 400 ug/sqrt(Hz), over a 100 Hz band is 0.04);
* encoders: 0.001 rad (a 4096-tick-per-turn servo resolves 0.0015 rad) and 0.05 rad/s per tick;
  sole force sensors: 0.5 N per reading (strain gauges or FSRs under a 5 kg robot);
* sole friction x U(1 -+ 0.2); the surface's layer stiffness (time constant) x U(1 -+ 0.3),
  layer height x U(1 -+ 0.2) and blade drag x U(1 -+ 0.3): turf differs between fields;
* ground tilt: up to 2 deg in a random direction (gravity turned by that much: the same as a
  tilted floor), as RoboCup fields laid over a hall floor are not level;
* initial pose: each servo's start angle off by U(-+0.02) rad;
* pushes: off unless ``push`` > 0 [N s]: one impulse of that size, horizontal, in a random
  direction, at a random time of the walk, applied to the torso over one control tick.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from gaits.params import fields_from_mapping

from ..errors import UserError

__all__ = ["DEFAULT_PUSHES", "Randomisation", "Perturbation", "draw", "TUNE", "EVALUATE", "NONE", "randomisation_from_mapping"]

#: Push impulses [N s] of the robustness command's sweep (a 5 kg robot: 0.05-0.6 m/s).
DEFAULT_PUSHES = (0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0)

#: Seed namespaces: tuning and evaluation draw from disjoint streams.
TUNE = 0x7E57
EVALUATE = 0xE7A1

_RANGES = {"mass_scale": (0.0, 0.5, "-"), "com_shift": (0.0, 0.05, "m"), "kp_scale": (0.0, 0.8, "-"),
           "torque_scale": (0.0, 0.8, "-"), "speed_scale": (0.0, 0.8, "-"), "backlash": (0.0, 0.1, "rad"),
           "latency_ticks": (0, 5, "ticks"), "imu_noise_deg": (0.0, 5.0, "deg"),
           "gyro_noise": (0.0, 1.0, "rad/s"), "imu_latency_ticks": (0, 5, "ticks"),
           "friction_scale": (0.0, 0.8, "-"), "layer_stiffness_scale": (0.0, 0.8, "-"),
           "layer_height_scale": (0.0, 0.8, "-"), "drag_scale": (0.0, 0.8, "-"), "tilt_deg": (0.0, 10.0, "deg"),
           "initial_pose": (0.0, 0.2, "rad"), "push": (0.0, 50.0, "N s"),
           "accel_noise": (0.0, 5.0, "m/s^2"), "encoder_noise": (0.0, 0.1, "rad"),
           "voltage_scale": (0.0, 0.5, "-"), "kt_scale": (0.0, 0.5, "-"), "resistance_scale": (0.0, 0.8, "-"),
           "servo_friction_scale": (0.0, 0.9, "-"),
           "encoder_rate_noise": (0.0, 5.0, "rad/s"), "force_noise": (0.0, 20.0, "N")}
_INTEGER = ("latency_ticks", "imu_latency_ticks")


@dataclass(frozen=True)
class Randomisation:
    """The distributions of one rollout's perturbations (see the module docstring)."""

    mass_scale: float = 0.10            # [-] link mass x U(1 - a, 1 + a)
    com_shift: float = 0.005            # [m] link CoM + U(-a, a) per axis
    kp_scale: float = 0.20              # [-] servo gain x U(1 - a, 1 + a)
    torque_scale: float = 0.15          # [-] servo torque limit x U(1 - a, 1 + a)
    speed_scale: float = 0.15           # [-] servo speed limit x U(1 - a, 1 + a)
    backlash: float = 0.01              # [rad] dead band per joint, U(0, a)
    latency_ticks: int = 2              # [ticks] command latency U{0..a}
    imu_noise_deg: float = 0.5          # [deg] std of the measured tilt per tick
    gyro_noise: float = 0.05            # [rad/s] std of the measured tilt rate per tick
    imu_latency_ticks: int = 2          # [ticks] IMU latency U{0..a}
    friction_scale: float = 0.2         # [-] sole friction x U(1 - a, 1 + a)
    layer_stiffness_scale: float = 0.3  # [-] layer time constant x U(1 - a, 1 + a)
    layer_height_scale: float = 0.2     # [-] layer height x U(1 - a, 1 + a)
    drag_scale: float = 0.3             # [-] blade drag x U(1 - a, 1 + a)
    tilt_deg: float = 2.0               # [deg] ground tilt U(0, a), random direction
    initial_pose: float = 0.02          # [rad] start angle offset per servo, U(-a, a)
    push: float = 0.0                   # [N s] one horizontal push of this size (0: none)
    accel_noise: float = 0.05           # [m/s^2] std of each accelerometer axis per tick
    encoder_noise: float = 0.001        # [rad] std of each encoder angle per tick
    encoder_rate_noise: float = 0.05    # [rad/s] std of each encoder velocity per tick
    force_noise: float = 0.5            # [N] std of each sole force reading per tick
    voltage_scale: float = 0.10         # [-] dc-motor servos: battery voltage x U(1 - a, 1 + a), per walk
    kt_scale: float = 0.05              # [-] ... each servo's torque constant x U(1 - a, 1 + a)
    resistance_scale: float = 0.15      # [-] ... each servo's winding resistance x U(1 - a, 1 + a)
    servo_friction_scale: float = 0.30  # [-] ... each servo's gearbox friction x U(1 - a, 1 + a)

    def __post_init__(self) -> None:
        for name, (lo, hi, unit) in _RANGES.items():
            v = getattr(self, name)
            kind = int if name in _INTEGER else (int, float)
            if isinstance(v, bool) or not isinstance(v, kind) or not math.isfinite(v) or not lo <= v <= hi:
                what = "a whole number" if name in _INTEGER else "a number"
                raise UserError(f"randomisation.{name} = {v!r}: expected {what} in [{lo:g}, {hi:g}] {unit}")
            if name not in _INTEGER:
                object.__setattr__(self, name, float(v))

    def with_push(self, impulse: float) -> "Randomisation":
        return dataclasses.replace(self, push=float(impulse))

    def to_mapping(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


#: No perturbation at all (a deterministic rollout, but through the randomised code path).
NONE = Randomisation(**{k: 0 if k in _INTEGER else 0.0 for k in _RANGES})
#: The default randomisation's sensor noise and nothing else: the world as it is, read as a robot reads
#: it (what the identification's tests and benchmarks record their hidden robots with).
SENSOR_NOISE = ("imu_noise_deg", "gyro_noise", "accel_noise", "encoder_noise", "encoder_rate_noise", "force_noise")
SENSORS_ONLY = dataclasses.replace(NONE, **{k: getattr(Randomisation(), k) for k in SENSOR_NOISE})


def randomisation_from_mapping(doc: Any, source: str) -> Randomisation:
    """Defaults overridden by a mapping (a study's ``robust.randomisation``); errors name the field."""
    if doc is None:
        return Randomisation()
    if doc == "none":
        return NONE
    return fields_from_mapping(Randomisation, doc, source, tuple(_RANGES), UserError,
                               expected=f"{', '.join(_RANGES)} (or 'none')")


@dataclass(frozen=True)
class Perturbation:
    """The concrete perturbation of one rollout (drawn by :func:`draw`)."""

    seed: Any                    # the seed it was drawn from (int or tuple of ints)
    namespace: int
    body_mass: np.ndarray        # (nbody,) factor
    body_com: np.ndarray         # (nbody, 3) [m] shift
    kp: np.ndarray               # (n_act,) factor
    torque: np.ndarray           # (n_act,) factor
    speed: np.ndarray            # (n_servo,) factor
    backlash: np.ndarray         # (n_servo,) [rad] dead band width
    latency: int                 # [ticks]
    imu_noise: float             # [rad] std
    gyro_noise: float            # [rad/s] std
    imu_latency: int             # [ticks]
    friction: float              # factor
    layer_timeconst: float       # factor
    layer_height: float          # factor
    drag: float                  # factor
    gravity_dir: np.ndarray      # (3,) unit vector of gravity
    initial_pose: np.ndarray     # (n_servo,) [rad]
    push_impulse: float          # [N s]
    push_time: float             # [0, 1): fraction of the walk at which the push comes
    push_angle: float            # [rad] direction in the horizontal plane (0: +x, pushes forward)
    noise_seed: int              # for the per-tick sensor noise streams
    accel_noise: float = 0.0     # [m/s^2] std
    encoder_noise: float = 0.0   # [rad] std
    encoder_rate_noise: float = 0.0  # [rad/s] std
    force_noise: float = 0.0     # [N] std
    voltage: float = 1.0         # factor: the battery (dc-motor servos)
    kt: np.ndarray | None = None            # (n_act,) factor
    resistance: np.ndarray | None = None    # (n_act,) factor
    servo_friction: np.ndarray | None = None    # (n_act,) factor


def draw(r: Randomisation, seed: int | tuple[int, ...], n_body: int, n_act: int, n_servo: int,
         namespace: int = TUNE) -> Perturbation:
    """One perturbation: the same arguments give the same values in any process. ``seed`` is a
    whole number >= 0 or a tuple of them (e.g. (user seed, rollout index))."""
    parts = seed if isinstance(seed, tuple) else (seed,)
    for v in parts:
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 0:
            raise UserError(f"seed = {seed!r}: expected a whole number >= 0")
    rng = np.random.default_rng(np.random.SeedSequence([int(namespace)] + [int(v) for v in parts]))

    def scale(a: float, n: int | None = None) -> Any:
        v = rng.uniform(1 - a, 1 + a, size=n)
        return v if n is not None else float(v)
    body_mass = scale(r.mass_scale, n_body)
    body_com = rng.uniform(-r.com_shift, r.com_shift, size=(n_body, 3))
    kp = scale(r.kp_scale, n_act)
    torque = scale(r.torque_scale, n_act)
    speed = scale(r.speed_scale, n_servo)
    backlash = rng.uniform(0.0, r.backlash, size=n_servo)
    latency = int(rng.integers(0, r.latency_ticks + 1))
    imu_latency = int(rng.integers(0, r.imu_latency_ticks + 1))
    friction, timeconst, height, drag = (scale(r.friction_scale), scale(r.layer_stiffness_scale),
                                         scale(r.layer_height_scale), scale(r.drag_scale))
    tilt = math.radians(rng.uniform(0.0, r.tilt_deg))
    azimuth = rng.uniform(0.0, 2 * math.pi)
    gravity_dir = np.array([math.sin(tilt) * math.cos(azimuth), math.sin(tilt) * math.sin(azimuth), -math.cos(tilt)])
    initial = rng.uniform(-r.initial_pose, r.initial_pose, size=n_servo)
    push_time = float(rng.uniform(0.1, 0.8))
    push_angle = float(rng.uniform(0.0, 2 * math.pi))
    noise_seed = int(rng.integers(0, 2 ** 63 - 1))
    # drawn last, so that every draw before is what it was before the motor law
    voltage = scale(r.voltage_scale)
    kt, resistance, servo_friction = (scale(r.kt_scale, n_act), scale(r.resistance_scale, n_act),
                                      scale(r.servo_friction_scale, n_act))
    return Perturbation(parts[-1] if len(parts) == 1 else tuple(int(v) for v in parts), int(namespace), body_mass, body_com, kp, torque, speed, backlash, latency,
                        math.radians(r.imu_noise_deg), r.gyro_noise, imu_latency, friction, timeconst, height,
                        drag, gravity_dir, initial, r.push, push_time, push_angle, noise_seed,
                        r.accel_noise, r.encoder_noise, r.encoder_rate_noise, r.force_noise, voltage, kt,
                        resistance, servo_friction)
