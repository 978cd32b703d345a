"""Every gait family x every shipped parameter set: finite, sane joint tables."""

import numpy as np
import pytest

from gaits import JOINT_NAMES, generate, list_baselines, load_baseline


@pytest.mark.parametrize("name", list_baselines())
@pytest.mark.parametrize("dt", [0.01, 0.002])
def test_baseline_trajectory_is_sane(name, dt):
    params = load_baseline(name).params
    traj = generate(params, dt=dt)
    n = len(traj.t)
    assert n > 100
    assert np.allclose(np.diff(traj.t), dt, atol=1e-9)
    assert traj.q_ref.shape == (n, len(JOINT_NAMES))
    for arr in (traj.q_ref, traj.p_world_com, traj.p_world_zmp_ref, traj.p_world_foot_l,
                traj.p_world_foot_r, traj.p_world_pelvis):
        assert np.all(np.isfinite(arr))
    assert np.max(np.abs(traj.q_ref)) < np.pi
    assert np.all(traj.joint("l_knee") > 0) and np.all(traj.joint("r_knee") > 0)
    assert np.min(traj.p_world_foot_l[:, 2]) >= -1e-12 and np.min(traj.p_world_foot_r[:, 2]) >= -1e-12
    assert set(np.unique(traj.support)) <= {-1, 0, 1}
    # it walks forward (or stays, for a zero step), starts and ends standing with flat, level feet
    assert traj.p_world_com[-1, 0] >= traj.p_world_com[0, 0] - 1e-9
    assert traj.support[0] == 0 and traj.support[-1] == 0
    assert abs(traj.p_world_foot_l[-1, 0] - traj.p_world_foot_r[-1, 0]) < 1e-9
    # no jumps: joint speeds stay below 15 rad/s (the EROS lift-off peaks near 9 rad/s at
    # T_mn = 3 deg per 10 ms, above a hobby servo's ~6 rad/s: the simulation makes it pay)
    assert np.max(np.abs(np.diff(traj.q_ref, axis=0))) / dt < 15.0
