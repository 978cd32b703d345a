"""The closed loop: a controller is handed only what a robot senses, and its targets drive the robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

import gaits
from gaits.control import READINGS, HoldPose, Measurement, StartPose, TablePlayer
from tuner.robots import load_robot
from tuner.sim.randomisation import NONE, draw
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES

ROBOT = load_robot("kidsize")
SIM = Simulator(ROBOT, SURFACES["rigid"])
TABLE = gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, SIM.control_period)
#: the fields of a Measurement: nothing else can reach a controller
FIELDS = ("t", "q", "dq", "imu_rpy", "gyro", "accel", "foot_force", "joint_names")


class Recorder:
    """Plays the table and keeps a copy of every measurement it is given (senses everything)."""

    def __init__(self, traj, senses=READINGS):
        self.inner = TablePlayer(traj)
        self.dt, self.duration, self.walk_start = self.inner.dt, self.inner.duration, self.inner.walk_start
        self.senses = frozenset(senses)
        self.seen: list[Measurement] = []
        self.commands: list = []

    def start_pose(self) -> StartPose:
        return self.inner.start_pose()

    def reset(self, m):
        self.inner.reset(m)

    def step(self, m, command=None):
        self.seen.append(Measurement(**{f: (np.copy(getattr(m, f)) if isinstance(getattr(m, f), np.ndarray)
                                            else getattr(m, f)) for f in FIELDS}))
        self.commands.append(command)
        return self.inner.step(m, command)

    def plan(self, n):
        return self.inner.plan(n)


def test_a_measurement_holds_sensor_readings_only():
    assert Measurement.__slots__ == FIELDS
    c = Recorder(TABLE)
    trace = SIM.run(c, duration=3.0)
    assert len(c.seen) == len(trace.t) - 1
    for i in (0, 50, 150, 290):
        m = c.seen[i]
        assert m.t == pytest.approx(i * SIM.control_period)
        np.testing.assert_allclose(m.q, trace.q[i], atol=1e-12)                    # the encoders
        np.testing.assert_allclose(m.foot_force, trace.force[i], atol=1e-9)        # the sole sensors
        assert m.imu_rpy[1] == pytest.approx(trace.pitch[i], abs=1e-12)           # the IMU's tilt
        assert m.imu_rpy[0] == pytest.approx(trace.roll[i], abs=1e-12)
        assert m.joint_names == SIM.joint_names and m.q.shape == (len(SIM.joint_names),)
    # standing before the walk (0.5-0.95 s): the accelerometer reads gravity, the gyro next to nothing
    standing = np.array([m.accel for m in c.seen[50:95]])
    assert np.linalg.norm(standing.mean(axis=0)) == pytest.approx(9.81, abs=0.05)
    assert np.abs(standing[:, :2]).max() < 0.5
    assert np.abs(np.array([m.gyro for m in c.seen[50:95]])).max() < 0.05
    # the gyro measures body rates: through the Euler-rate relation they integrate to the torso's
    # heading change, and the pitch rate follows the trace's pitch
    rpy = np.array([m.imu_rpy for m in c.seen])
    w = np.array([m.gyro for m in c.seen])
    yaw_rate = (np.sin(rpy[:, 0]) * w[:, 1] + np.cos(rpy[:, 0]) * w[:, 2]) / np.cos(rpy[:, 1])
    assert np.sum(yaw_rate) * SIM.control_period == pytest.approx(trace.yaw[-1] - trace.yaw[0], abs=1e-3)
    pitch_rate = np.cos(rpy[:, 0]) * w[:, 1] - np.sin(rpy[:, 0]) * w[:, 2]
    assert np.corrcoef(pitch_rate[:-1], np.diff(trace.pitch)[:len(pitch_rate) - 1])[0, 1] > 0.99
    # the arrays a controller gets share memory with nothing of the simulation's
    state = SIM.data.sensordata
    for f in ("q", "dq", "imu_rpy", "gyro", "accel", "foot_force"):
        v = getattr(c.seen[10], f)
        assert not np.shares_memory(v, state)


def test_noise_and_latency_reach_the_controller_as_the_randomisation_asks():
    quiet = NONE.__class__(**{**NONE.to_mapping(), "imu_noise_deg": 1.0, "imu_latency_ticks": 2,
                              "encoder_noise": 0.002, "force_noise": 1.0})
    p = draw(quiet, 4, *SIM.n_random())
    p = type(p)(**{**p.__dict__, "imu_latency": 2})
    c = Recorder(TABLE)
    trace = SIM.run(c, duration=3.0, perturb=p)
    pitch = np.array([m.imu_rpy[1] for m in c.seen])
    # two ticks late, zeros before the first reading arrives, then the tilt plus 1 deg of noise
    assert pitch[0] == 0.0 and pitch[1] == 0.0
    err = pitch[2:] - trace.pitch[:len(pitch) - 2]
    assert np.std(err) == pytest.approx(math.radians(1.0), rel=0.2)
    q_err = np.array([m.q - trace.q[i] for i, m in enumerate(c.seen)])
    assert np.std(q_err) == pytest.approx(0.002, rel=0.2)
    f_err = np.array([m.foot_force - trace.force[i] for i, m in enumerate(c.seen)])
    assert np.all(np.array([m.foot_force for m in c.seen]) >= 0.0)
    assert 0.5 < np.std(f_err) < 1.1


def test_a_controller_senses_only_what_it_asks_for():
    c = Recorder(TABLE, senses=("gyro",))
    SIM.run(c, duration=0.5)
    m = c.seen[3]
    assert m.gyro is not None and m.q is None and m.imu_rpy is None and m.foot_force is None


def test_the_controller_gets_the_command_of_its_tick():
    class Stream:
        def at(self, t):
            return np.array([0.1 if t >= 0.5 else 0.0, 0.0, 0.0])
    c = Recorder(TABLE, senses=())
    SIM.run(c, duration=1.0, commands=Stream())
    assert c.commands[49][0] == 0.0 and c.commands[50][0] == 0.1


def test_a_push_moves_the_robot_when_it_is_asked_for():
    hold = HoldPose(TABLE.q_ref[0], SIM.control_period)
    still = SIM.run(hold, duration=1.0)
    pushed = SIM.run(hold, duration=1.0, pushes=[(0.3, (1.5, 0.0, 0.0))])
    assert np.abs(pushed.p_com[25] - still.p_com[25]).max() < 1e-12          # before the push
    assert pushed.p_com[40, 0] - still.p_com[40, 0] > 0.005                    # after it
    assert pushed.meta["pushes"] == [(0.3, [1.5, 0.0, 0.0])]


def test_the_loop_refuses_a_controller_of_another_period_or_no_length():
    with pytest.raises(ValueError, match="control period"):
        SIM.run(HoldPose(TABLE.q_ref[0], 0.02, duration=1.0))
    with pytest.raises(ValueError, match="give a duration"):
        SIM.run(HoldPose(TABLE.q_ref[0], SIM.control_period))
    assert SIM.run(HoldPose(TABLE.q_ref[0], SIM.control_period), duration=0.2).completed
