"""The one quaternion conversion (gaits.control.rpy_from_quat), against MuJoCo's own and itself."""

import math

import mujoco
import numpy as np

from gaits.control import rpy_from_quat


def test_rpy_matches_mujoco_for_zyx_euler_angles_and_batches_alike():
    rng = np.random.default_rng(0)
    angles = np.column_stack([rng.uniform(-1.2, 1.2, 50), rng.uniform(-1.4, 1.4, 50), rng.uniform(-3, 3, 50)])
    quats = []
    def about(axis, a):
        q = np.zeros(4)
        mujoco.mju_axisAngle2Quat(q, np.eye(3)[axis], a)
        return q
    for roll, pitch, yaw in angles:                       # R = Rz(yaw) Ry(pitch) Rx(roll)
        zy, q = np.zeros(4), np.zeros(4)
        mujoco.mju_mulQuat(zy, about(2, yaw), about(1, pitch))
        mujoco.mju_mulQuat(q, zy, about(0, roll))
        quats.append(q)
    quats = np.array(quats)
    batch = rpy_from_quat(quats)
    assert batch.shape == (50, 3) and np.allclose(batch, angles, atol=1e-12)
    for q, row in zip(quats, batch):
        assert np.array_equal(rpy_from_quat(q), row)          # one by one: the same bits
    assert np.allclose(rpy_from_quat([math.cos(0.1), 0.0, math.sin(0.1), 0.0]), [0.0, 0.2, 0.0])
